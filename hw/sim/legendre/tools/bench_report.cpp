// SPDX-License-Identifier: MIT
// procam_legendre_bench_report BENCH.json OUT_DIR
// Reads procam_legendre_bench's JSON (--benchmark_out, ideally with
// --benchmark_repetitions and aggregates) and writes OUT_DIR/bench.md (the
// speed-up tables of thesis Figs. 6.10/6.11 with our medians and errors)
// and OUT_DIR/speedup.png (speed-up vs coefficient count, one line per
// grid size, 2D and 3D panels). Speed-ups use median CPU time (the machine
// is shared; wall time is listed too).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace {

struct Timing {
  double cpu_ms = NAN, real_ms = NAN, substeps = NAN, error = NAN;
};

std::string fmt(double v, int prec) {
  std::ostringstream o;
  o.setf(std::ios::fixed);
  o.precision(prec);
  o << v;
  return o.str();
}

double to_ms(double v, const std::string& unit) {
  if (unit == "ns") return v * 1e-6;
  if (unit == "us") return v * 1e-3;
  if (unit == "s") return v * 1e3;
  return v;
}

// key "Legendre/2d/4" -> timing (median aggregate if present, else the run).
std::map<std::string, Timing> load(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot read " + path + ": run procam_legendre_bench --benchmark_out=" + path);
  const nlohmann::json j = nlohmann::json::parse(in);
  std::map<std::string, Timing> out;
  std::map<std::string, bool> has_median;
  for (const auto& b : j.at("benchmarks")) {
    std::string name = b.value("run_name", b.value("name", ""));
    if (name.rfind("BM_", 0) == 0) name = name.substr(3);
    const std::string agg = b.value("aggregate_name", "");
    if (!agg.empty() && agg != "median") continue;
    if (agg.empty() && has_median[name]) continue;
    if (agg == "median") has_median[name] = true;
    Timing& t = out[name];
    const std::string unit = b.value("time_unit", "ns");
    t.cpu_ms = to_ms(b.value("cpu_time", NAN), unit);
    t.real_ms = to_ms(b.value("real_time", NAN), unit);
    if (b.contains("substeps")) t.substeps = b["substeps"].get<double>();
    if (b.contains("rel_l2_density")) t.error = b["rel_l2_density"].get<double>();
  }
  return out;
}

struct Family {
  std::string dim;
  std::vector<int> grids, ns;
};

void panel(cv::Mat& img, const cv::Rect& r, const Family& f, const std::map<std::string, Timing>& t) {
  const cv::Scalar black(0, 0, 0), grid(220, 220, 220);
  const double ymin = 0.1, ymax = 1e4;  // speed-up, log scale
  auto X = [&](size_t i) { return r.x + 40 + static_cast<int>(i * static_cast<size_t>(r.width - 80) / std::max<size_t>(1, f.ns.size() - 1)); };
  auto Y = [&](double s) {
    const double c = std::clamp(s, ymin, ymax);
    return r.y + r.height - static_cast<int>((std::log10(c) - std::log10(ymin)) / (std::log10(ymax) - std::log10(ymin)) * r.height);
  };
  for (double s : {0.1, 1.0, 10.0, 100.0, 1000.0, 10000.0}) {
    cv::line(img, {r.x, Y(s)}, {r.x + r.width, Y(s)}, s == 1.0 ? cv::Scalar(150, 150, 150) : grid);
    cv::putText(img, fmt(s, s < 1 ? 1 : 0) + "x", {r.x - 60, Y(s) + 5}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black);
  }
  cv::rectangle(img, r, black);
  for (size_t i = 0; i < f.ns.size(); ++i) {
    const int k = static_cast<int>(std::pow(f.ns[i], f.dim == "2d" ? 2 : 3));
    cv::putText(img, std::to_string(k), {X(i) - 10, r.y + r.height + 20}, cv::FONT_HERSHEY_SIMPLEX, 0.45, black);
  }
  cv::putText(img, f.dim + ": speed-up (grid CPU / Legendre CPU) vs Legendre coefficients", {r.x, r.y - 12},
              cv::FONT_HERSHEY_SIMPLEX, 0.5, black);
  const cv::Scalar palette[] = {{200, 0, 0}, {0, 140, 0}, {0, 0, 220}, {180, 0, 180}};
  for (size_t g = 0; g < f.grids.size(); ++g) {
    const cv::Scalar c = palette[g % 4];
    const auto gt = t.find("Grid/" + f.dim + "/" + std::to_string(f.grids[g]));
    if (gt == t.end()) continue;
    cv::Point prev(-1, -1);
    for (size_t i = 0; i < f.ns.size(); ++i) {
      const auto lt = t.find("Legendre/" + f.dim + "/" + std::to_string(f.ns[i]));
      if (lt == t.end()) continue;
      const cv::Point p(X(i), Y(gt->second.cpu_ms / lt->second.cpu_ms));
      cv::circle(img, p, 4, c, -1, cv::LINE_AA);
      if (prev.x >= 0) cv::line(img, prev, p, c, 2, cv::LINE_AA);
      prev = p;
    }
    const std::string label = std::to_string(f.grids[g]) + (f.dim == "2d" ? "^2" : "^3") + " grid";
    cv::putText(img, label, {r.x + r.width - 110, r.y + 20 + 18 * static_cast<int>(g)}, cv::FONT_HERSHEY_SIMPLEX, 0.45, c);
  }
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::cerr << "usage: procam_legendre_bench_report BENCH.json OUT_DIR\n";
    return 2;
  }
  try {
    const auto t = load(argv[1]);
    const std::string out = argv[2];
    const Family fams[] = {{"2d", {200, 300, 400, 500}, {4, 6, 8, 12}}, {"3d", {20, 30, 40}, {4, 5, 6}}};
    std::ofstream md(out + "/bench.md");
    md << "| benchmark | median CPU (ms) | median wall (ms) | CFL sub-steps | rel. L2 density error at T = 0.25 s |\n"
       << "|---|---|---|---|---|\n";
    for (const Family& f : fams) {
      for (int n : f.ns) {
        const std::string k = "Legendre/" + f.dim + "/" + std::to_string(n);
        if (!t.count(k)) continue;
        const Timing& x = t.at(k);
        const auto e = t.find("ErrorLegendre/" + f.dim + "/" + std::to_string(n) + "/iterations:1");
        md << "| " << k << " (" << std::pow(n, f.dim == "2d" ? 2 : 3) << " coeff.) | " << fmt(x.cpu_ms, 3) << " | "
           << fmt(x.real_ms, 3) << " | " << (std::isnan(x.substeps) ? "" : fmt(x.substeps, 0)) << " | "
           << (e == t.end() ? std::string("(reference)") : fmt(100 * e->second.error, 2) + " %") << " |\n";
      }
      for (int g : f.grids) {
        const std::string k = "Grid/" + f.dim + "/" + std::to_string(g);
        if (!t.count(k)) continue;
        const auto e = t.find("ErrorGrid/" + f.dim + "/" + std::to_string(g) + "/iterations:1");
        md << "| " << k << " | " << fmt(t.at(k).cpu_ms, 3) << " | " << fmt(t.at(k).real_ms, 3) << " | | "
           << (e == t.end() ? std::string("") : fmt(100 * e->second.error, 2) + " %") << " |\n";
      }
    }
    for (const Family& f : fams) {
      md << "\n**" << f.dim << " speed-up** (grid median CPU / Legendre median CPU)\n\n| grid \\ coefficients |";
      for (int n : f.ns) md << " " << std::pow(n, f.dim == "2d" ? 2 : 3) << " |";
      md << "\n|---|";
      for (size_t i = 0; i < f.ns.size(); ++i) md << "---|";
      md << "\n";
      for (int g : f.grids) {
        md << "| " << g << (f.dim == "2d" ? "^2" : "^3") << " |";
        for (int n : f.ns) {
          const auto gt = t.find("Grid/" + f.dim + "/" + std::to_string(g));
          const auto lt = t.find("Legendre/" + f.dim + "/" + std::to_string(n));
          md << " " << (gt == t.end() || lt == t.end() ? std::string("-") : fmt(gt->second.cpu_ms / lt->second.cpu_ms, 1) + "x")
             << " |";
        }
        md << "\n";
      }
    }
    cv::Mat img(520, 1300, CV_8UC3, cv::Scalar(255, 255, 255));
    panel(img, cv::Rect(90, 50, 520, 400), fams[0], t);
    panel(img, cv::Rect(740, 50, 520, 400), fams[1], t);
    cv::putText(img, "Legendre coefficients (K)", {520, 505}, cv::FONT_HERSHEY_SIMPLEX, 0.5, cv::Scalar(0, 0, 0));
    cv::imwrite(out + "/speedup.png", img);
    std::cout << "wrote " << out << "/bench.md and " << out << "/speedup.png\n";
  } catch (const std::exception& e) {
    std::cerr << "procam_legendre_bench_report: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
