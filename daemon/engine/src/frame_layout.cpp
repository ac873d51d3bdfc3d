// SPDX-License-Identifier: MIT
// Offline frame layouts: capture files -> plan frames (see frame_layout.hpp).
#include "procam/engine/frame_layout.hpp"

#include <fnmatch.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

namespace procam::engine {
namespace fs = std::filesystem;

namespace {

constexpr const char* kInverseSuffix = " inverse";

bool is_inverse_of(const std::string& inv, const std::string& plane) {
  return inv == plane + kInverseSuffix;
}

std::string base_name(const std::string& path) { return fs::path(path).filename().string(); }

long find_label(const std::vector<std::string>& labels, const std::string& l) {
  for (size_t i = 0; i < labels.size(); ++i)
    if (labels[i] == l) return static_cast<long>(i);
  return -1;
}

// A short list of the expected order, for error hints.
std::string expected_order(const std::vector<std::string>& labels, const std::vector<size_t>& order) {
  std::string s;
  for (size_t j = 0; j < order.size(); ++j) {
    if (j == 6 && order.size() > 8) {
      s += ", ..., " + std::to_string(order.size() - 1) + ":'" + labels[order.back()] + "'";
      break;
    }
    s += (j ? ", " : "") + std::to_string(j) + ":'" + labels[order[j]] + "'";
  }
  return s;
}

// The plan's column and row bit planes (labels "col bit N" / "row bit N",
// inverses not counted): what the rig's projector size asks for.
void count_planes(const std::vector<std::string>& labels, size_t& cols, size_t& rows) {
  cols = rows = 0;
  const std::string inv = kInverseSuffix;
  for (const auto& l : labels) {
    if (l.size() >= inv.size() && l.compare(l.size() - inv.size(), inv.size(), inv) == 0) continue;
    cols += l.rfind("col bit ", 0) == 0 ? 1u : 0u;
    rows += l.rfind("row bit ", 0) == 0 ? 1u : 0u;
  }
}

Status count_error(const std::string& layout, const std::vector<std::string>& labels,
                  const std::vector<size_t>& order, const std::vector<std::string>& files) {
  size_t cols = 0, rows = 0;
  count_planes(labels, cols, rows);
  std::string head = "layout " + layout + ": the plan needs " + std::to_string(order.size()) +
                     " files but the folder has " + std::to_string(files.size());
  // Pair layouts: each plane is a pattern/inverse pair, so the count says
  // how many planes the capture holds against the rig's projector size.
  if ((layout == "opencv-graycode" || layout == "gupta-pairs") && cols + rows > 0) {
    const size_t extra = layout == "opencv-graycode" ? 2 : 0;  // white, black
    const size_t pairs = files.size() >= extra ? (files.size() - extra) / 2 : 0;
    head += " — the rig's projector gives " + std::to_string(cols) + " column" +
            (rows > 0 ? " + " + std::to_string(rows) + " row" : std::string()) + " planes (" +
            std::to_string(cols + rows) + " pattern/inverse pairs; a projector " +
            std::to_string(cols > 0 ? (size_t{1} << (cols - 1)) + 1 : 0) + ".." +
            std::to_string(cols > 0 ? size_t{1} << cols : 0) + " columns wide has " + std::to_string(cols) +
            " column planes), the capture holds " + std::to_string(pairs) + " pairs";
  }
  std::string which;
  if (files.size() > order.size())
    which = "; file " + base_name(files[order.size()]) + " has no frame";
  else
    which = "; frame " + std::to_string(order.size() > files.size() ? order[files.size()] : 0) + " '" +
            labels[order[files.size()]] + "' (file #" + std::to_string(files.size()) + ") is missing";
  return Error(Code::invalid_argument, head + which,
               "expected file order: " + expected_order(labels, order) +
                   ". The plan's size follows the projector size of --rig (e.g. a 1024x768 projector: 10 column "
                   "and 10 row planes) and the method's parameters (rows, binarize): pass the capture's rig");
}

// Pattern (non-white/black) frames in plan order, checked to come as
// pattern, inverse, pattern, inverse, ...
Result<std::vector<size_t>> pair_order(const std::string& layout, const std::vector<std::string>& labels) {
  std::vector<size_t> order;
  for (size_t i = 0; i < labels.size(); ++i)
    if (labels[i] != "white" && labels[i] != "black") order.push_back(i);
  for (size_t j = 0; j < order.size(); j += 2) {
    if (j + 1 >= order.size() || !is_inverse_of(labels[order[j + 1]], labels[order[j]]))
      return Error(Code::invalid_argument,
                   "layout " + layout + " needs every pattern followed by its inverse, but plan frame " +
                       std::to_string(order[j]) + " '" + labels[order[j]] + "' is not followed by '" +
                       labels[order[j]] + kInverseSuffix + "'",
                   "use a method/parameters that project inverses (gray: binarize=inverse)");
  }
  return order;
}

FrameAssignment in_order(const std::vector<size_t>& order) {
  FrameAssignment a;
  a.frame_of_file = order;
  for (size_t j = 0; j < order.size(); ++j) a.files.push_back(j);
  return a;
}

void add_synthesis(FrameAssignment& a, const std::vector<std::string>& labels) {
  std::vector<bool> captured(labels.size(), false);
  for (size_t f : a.frame_of_file) captured[f] = true;
  const long w = find_label(labels, "white"), b = find_label(labels, "black");
  if (w >= 0 && !captured[static_cast<size_t>(w)]) a.white = w;
  if (b >= 0 && !captured[static_cast<size_t>(b)]) a.black = b;
  if (a.white >= 0 || a.black >= 0)
    for (size_t i = 0; i < labels.size(); ++i)
      if (captured[i] && labels[i] != "white" && labels[i] != "black") a.pair_frames.push_back(i);
}

Result<FrameAssignment> from_file(const std::string& path, const std::vector<std::string>& labels,
                                  const std::vector<std::string>& files) {
  std::ifstream in(path);
  if (!in) return Error(Code::not_found, "layout file '" + path + "' cannot be read",
                        std::string("built-in layouts: ") + kBuiltinLayouts);
  const auto doc = nlohmann::json::parse(in, nullptr, false);
  if (!doc.is_array())
    return Error(Code::invalid_argument, "layout file '" + path + "' must hold a JSON array of "
                                         "{\"file\": glob or index, \"frame\": plan label}");
  FrameAssignment a;
  std::vector<long> file_of_frame(labels.size(), -1);
  std::vector<bool> used(files.size(), false);
  for (size_t e = 0; e < doc.size(); ++e) {
    const auto& entry = doc[e];
    const std::string where = "layout file '" + path + "' entry " + std::to_string(e);
    if (!entry.is_object() || !entry.contains("file") || !entry.contains("frame") || !entry["frame"].is_string())
      return Error(Code::invalid_argument, where + ": needs \"file\" (glob or index) and \"frame\" (plan label)");
    const std::string label = entry["frame"].get<std::string>();
    const long frame = find_label(labels, label);
    if (frame < 0)
      return Error(Code::invalid_argument, where + ": the plan has no frame '" + label + "'",
                   "plan frames: " + expected_order(labels, in_order([&] {
                     std::vector<size_t> o(labels.size());
                     for (size_t i = 0; i < o.size(); ++i) o[i] = i;
                     return o;
                   }()).frame_of_file));
    long file = -1;
    if (entry["file"].is_number_integer()) {
      const auto idx = entry["file"].get<long>();
      if (idx < 0 || static_cast<size_t>(idx) >= files.size())
        return Error(Code::invalid_argument, where + ": file index " + std::to_string(idx) + " for frame '" + label +
                                                 "' is out of range (" + std::to_string(files.size()) + " files)");
      file = idx;
    } else if (entry["file"].is_string()) {
      const std::string glob = entry["file"].get<std::string>();
      for (size_t f = 0; f < files.size(); ++f)
        if (fnmatch(glob.c_str(), base_name(files[f]).c_str(), 0) == 0) {
          if (file >= 0)
            return Error(Code::invalid_argument, where + ": '" + glob + "' for frame '" + label +
                                                     "' matches both " + base_name(files[static_cast<size_t>(file)]) +
                                                     " and " + base_name(files[f]));
          file = static_cast<long>(f);
        }
      if (file < 0)
        return Error(Code::invalid_argument, where + ": no file matches '" + glob + "' for frame '" + label + "'");
    } else {
      return Error(Code::invalid_argument, where + ": \"file\" must be a glob string or an index");
    }
    const auto fu = static_cast<size_t>(file), fr = static_cast<size_t>(frame);
    if (used[fu])
      return Error(Code::invalid_argument, where + ": file " + base_name(files[fu]) + " is given to two frames");
    if (file_of_frame[fr] >= 0)
      return Error(Code::invalid_argument, where + ": frame '" + label + "' is given two files (" +
                                               base_name(files[static_cast<size_t>(file_of_frame[fr])]) + " and " +
                                               base_name(files[fu]) + ")");
    used[fu] = true;
    file_of_frame[fr] = file;
  }
  for (size_t i = 0; i < labels.size(); ++i) {
    if (file_of_frame[i] >= 0) {
      a.frame_of_file.push_back(i);
      a.files.push_back(static_cast<size_t>(file_of_frame[i]));
    } else if (labels[i] != "white" && labels[i] != "black") {
      return Error(Code::invalid_argument, "layout file '" + path + "': no file for plan frame " + std::to_string(i) +
                                               " '" + labels[i] + "'");
    }
  }
  add_synthesis(a, labels);
  if ((a.white >= 0 || a.black >= 0) && a.pair_frames.empty())
    return Error(Code::invalid_argument, "layout file '" + path + "': white/black are missing and there are no "
                                         "pattern frames to synthesize them from");
  return a;
}

}  // namespace

Result<FrameAssignment> assign_frames(const std::string& layout, const std::vector<std::string>& labels,
                                      const std::vector<std::string>& files) {
  if (layout.empty() || layout == "procam") {
    std::vector<size_t> order(labels.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = i;
    if (files.size() != order.size()) return count_error("procam", labels, order, files);
    return in_order(order);
  }
  if (layout == "opencv-graycode" || layout == "gupta-pairs") {
    auto pairs = pair_order(layout, labels);
    if (!pairs) return pairs.status();
    std::vector<size_t> order = *pairs;
    if (layout == "opencv-graycode") {
      const long w = find_label(labels, "white"), b = find_label(labels, "black");
      if (w < 0 || b < 0)
        return Error(Code::invalid_argument, "layout opencv-graycode ends with white and black, but the plan has no '" +
                                                 std::string(w < 0 ? "white" : "black") + "' frame");
      order.push_back(static_cast<size_t>(w));
      order.push_back(static_cast<size_t>(b));
    }
    if (files.size() != order.size()) return count_error(layout, labels, order, files);
    FrameAssignment a = in_order(order);
    add_synthesis(a, labels);
    return a;
  }
  std::error_code ec;
  if (!fs::is_regular_file(layout, ec))
    return Error(Code::invalid_argument, "unknown layout '" + layout + "'",
                 std::string("use one of ") + kBuiltinLayouts + " or a JSON layout file");
  return from_file(layout, labels, files);
}

}  // namespace procam::engine
