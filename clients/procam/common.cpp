// SPDX-License-Identifier: MIT
// Shared CLI helpers: errors, key=value parsing, the scan summary, progress.
#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>

#include "cli.hpp"
#include "procam/core/strings.hpp"

#ifndef PROCAM_DEFAULT_PLUGIN_DIRS
#define PROCAM_DEFAULT_PLUGIN_DIRS ""
#endif

namespace procam::cli {
client::Client Args::connect() const {
  const std::string ep = has("endpoint") ? get("endpoint") : client::default_endpoint();
  long timeout_s = 10;
  try {
    if (has("timeout")) timeout_s = std::stol(get("timeout"));
  } catch (const std::exception&) {
  }
  return client::Client(ep, std::chrono::milliseconds(std::max(1L, timeout_s) * 1000));
}

int usage_error(const std::string& msg) {
  std::fprintf(stderr, "procam: %s (see procam --help)\n", msg.c_str());
  return 2;
}

int report(const Status& s) {
  std::fprintf(stderr, "procam: error: %s\n", s.message().c_str());
  if (!s.hint().empty()) std::fprintf(stderr, "        hint: %s\n", s.hint().c_str());
  std::fprintf(stderr, "        (code %s)\n", code_name(s.code()));
  return 1;
}

// "k=v": v parsed as JSON when it is JSON (numbers, true/false, arrays,
// quoted strings), otherwise taken as a plain string.
Result<nlohmann::json> kv_object(const std::vector<std::string>& items, const char* what) {
  nlohmann::json o = nlohmann::json::object();
  for (const auto& it : items) {
    auto eq = it.find('=');
    if (eq == std::string::npos || eq == 0)
      return Error(Code::invalid_argument, std::string(what) + " '" + it + "' is not key=value");
    const std::string k = it.substr(0, eq), v = it.substr(eq + 1);
    try {
      o[k] = nlohmann::json::parse(v);
    } catch (const std::exception&) {
      o[k] = v;
    }
  }
  return o;
}

Result<std::map<std::string, proto::InputRef>> input_refs(const std::vector<std::string>& items) {
  std::map<std::string, proto::InputRef> out;
  for (const auto& it : items) {
    const size_t eq = it.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == it.size())
      return Error(Code::invalid_argument, "--input '" + it + "' is not NAME=SCAN_ID[:OUTPUT]",
                   "e.g. --input depth_mm=20261123-101500-1a2b3c (output depth_mm of that scan)");
    const std::string name = it.substr(0, eq), ref = it.substr(eq + 1);
    const size_t colon = ref.find(':');
    proto::InputRef r{ref.substr(0, colon), colon == std::string::npos ? name : ref.substr(colon + 1)};
    if (r.scan_id.empty() || r.output.empty())
      return Error(Code::invalid_argument, "--input '" + it + "' is not NAME=SCAN_ID[:OUTPUT]");
    if (!out.emplace(name, std::move(r)).second)
      return Error(Code::invalid_argument, "--input '" + name + "' is given twice");
  }
  return out;
}

static std::string fmt_pct(const nlohmann::json& j, const char* k) {
  if (!j.contains(k) || !j[k].is_number()) return "n/a";
  char b[32];
  std::snprintf(b, sizeof b, "%.2f%%", j[k].get<double>() * 100.0);
  return b;
}
static std::string fmt_num(const nlohmann::json& j, const char* k, const char* unit, int prec = 2) {
  if (!j.contains(k) || !j[k].is_number()) return "n/a";
  char b[48];
  std::snprintf(b, sizeof b, "%.*f %s", prec, j[k].get<double>(), unit);
  return b;
}

// The short summary `make demo` prints: method, patterns, decode time, accuracy.
void print_summary(const nlohmann::json& m, const std::string& out_dir) {
  std::printf("\n== scan %s: %s ==\n", m.value("scan_id", "").c_str(), m.value("state", "").c_str());
  std::printf("  method        %s / %s\n", m.value("plugin", "").c_str(), m.value("method", "").c_str());
  if (m.contains("rig")) {
    const auto& st = m["rig"].value("state", nlohmann::json::object());
    std::printf("  rig           %s%s\n", m["rig"].value("name", "").c_str(),
                st.contains("scene") ? (", scene " + st["scene"].get<std::string>()).c_str() : "");
  }
  const auto& plan = m.value("plan", nlohmann::json::object());
  std::printf("  patterns      %d in %zu round(s)\n", plan.value("patterns", 0),
              plan.value("rounds", nlohmann::json::array()).size());
  for (const auto& o : m.value("outputs", nlohmann::json::array()))
    if (o.value("name", "") == "report" && o["value"].is_object()) {
      const auto& r = o["value"];
      if (r.contains("model")) std::printf("  model         %s\n", r["model"].get<std::string>().c_str());
      if (r.contains("why")) {  // first sentence; the manifest has the rest
        std::string why = r["why"].get<std::string>();
        // Sentence end = ". " before a capital letter (not "Eq. 3.5").
        for (size_t i = 0; i + 2 < why.size(); ++i)
          if (why[i] == '.' && why[i + 1] == ' ' && std::isupper(static_cast<unsigned char>(why[i + 2]))) {
            why.resize(i + 1);
            break;
          }
        std::printf("  why           %s\n", why.c_str());
      }
    }
  const auto& t = m.value("timing_ms", nlohmann::json::object());
  std::printf("  decode time   %s (capture %s, write %s)\n", fmt_num(t, "decode", "ms", 1).c_str(),
              fmt_num(t, "capture", "ms", 1).c_str(), fmt_num(t, "write", "ms", 1).c_str());
  if (m.contains("evaluation")) {
    const auto& e = m["evaluation"];
    std::printf("  accuracy vs ground truth (%d lit pixels):\n", e.value("lit_pixels", 0));
    std::printf("    within 1 projector column  %s of lit pixels\n", fmt_pct(e, "within_1col_fraction").c_str());
    std::printf("    decoded                    %s of lit pixels\n", fmt_pct(e, "decoded_fraction").c_str());
    std::printf("    gross errors (>1 column)   %s of decoded\n", fmt_pct(e, "gross_error_fraction").c_str());
    std::printf("    column RMS                 %s\n", fmt_num(e, "col_rms_px", "px", 3).c_str());
    std::printf("    depth RMS / median |err|   %s / %s\n", fmt_num(e, "depth_rms_mm", "mm", 3).c_str(),
                fmt_num(e, "depth_median_abs_mm", "mm", 3).c_str());
  }
  if (m.contains("error") && !m["error"].is_null())
    std::printf("  error         %s: %s\n", m["error"].value("code", "").c_str(),
                m["error"].value("message", "").c_str());
  if (!out_dir.empty()) {
    std::printf("  results in    %s/\n", out_dir.c_str());
    for (const auto& p : m.value("previews", nlohmann::json::array()))
      std::printf("    preview     %s\n", p.value("file", "").c_str());
  }
}

// Progress on stderr: a redrawn bar on a terminal; on a pipe or log file, one
// line per stage change and per quarter of a stage, so logs stay readable.
void progress_line(const proto::Event& ev) {
  static const bool tty = ::isatty(2) != 0;
  static std::string last_key;
  if (ev.event == "progress" && !tty) {
    const auto total = ev.body.value("total", 0), done = ev.body.value("done", 0);
    const int quarter = total > 0 ? done * 4 / total : 0;
    const std::string key = ev.body.value("stage", "") + std::to_string(ev.body.value("round", 1)) + "/" +
                            std::to_string(quarter);
    if (key == last_key) return;
    last_key = key;
    std::fprintf(stderr, "  %-8s round %d  %d/%d %s\n", ev.body.value("stage", "").c_str(),
                 ev.body.value("round", 1), done, total, ev.body.value("message", "").c_str());
    return;
  }
  if (ev.event == "state" && !tty) {
    std::fprintf(stderr, "  state: %s\n", ev.body.value("state", "").c_str());
    return;
  }
  if (ev.event == "progress") {
    const auto total = ev.body.value("total", 0), done = ev.body.value("done", 0);
    const std::string stage = ev.body.value("stage", "");
    const int width = 30;
    const int fill = total > 0 ? done * width / total : 0;
    std::fprintf(stderr, "\r  %-8s round %d [%s%s] %3d/%-3d %-28.28s", stage.c_str(), ev.body.value("round", 1),
                 std::string(static_cast<size_t>(fill), '#').c_str(),
                 std::string(static_cast<size_t>(width - fill), '.').c_str(), done, total,
                 ev.body.value("message", "").c_str());
  } else if (ev.event == "state") {
    std::fprintf(stderr, "\r  state: %-60s\n", ev.body.value("state", "").c_str());
  }
  std::fflush(stderr);
}

std::vector<std::string> split_colon(const std::string& s) { return split_nonempty(s, ':'); }

std::vector<std::string> plugin_search_dirs(const Args& a) {
  std::vector<std::string> dirs = a.list("plugins");
  if (const char* env = std::getenv("PROCAM_PLUGIN_PATH"))
    for (auto& p : split_nonempty(env)) dirs.push_back(p);
  if (dirs.empty()) dirs = split_nonempty(PROCAM_DEFAULT_PLUGIN_DIRS);
  return dirs;
}

}  // namespace procam::cli
