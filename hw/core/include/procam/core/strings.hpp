// SPDX-License-Identifier: MIT
// Small string helpers shared by the daemon and the CLI (header-only).
#pragma once

#include <string>
#include <string_view>
#include <vector>

namespace procam {

// Splits "a:b::c" at `sep`, dropping empty items: {"a", "b", "c"}. Used for
// colon-separated search paths (PROCAM_PLUGIN_PATH).
inline std::vector<std::string> split_nonempty(std::string_view s, char sep = ':') {
  std::vector<std::string> out;
  size_t pos = 0;
  while (pos <= s.size()) {
    size_t e = s.find(sep, pos);
    if (e == std::string_view::npos) e = s.size();
    if (e > pos) out.emplace_back(s.substr(pos, e - pos));
    pos = e + 1;
  }
  return out;
}

}  // namespace procam
