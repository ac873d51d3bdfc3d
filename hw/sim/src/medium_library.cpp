// SPDX-License-Identifier: MIT
// Material library (thesis Table 4.1), Eq. 4.8 scaling and Eq. 4.9-4.10 mixtures.
#include "procam/hw/sim/medium_library.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>
#include <limits>

#include <nlohmann/json.hpp>

namespace procam::sim {
namespace detail {
extern const char* const kMaterialLibraryJson;  // medium_library_data.cpp (generated)
}

namespace {

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::string trim(std::string_view s) {
  size_t b = 0, e = s.size();
  while (b < e && std::isspace(static_cast<unsigned char>(s[b]))) ++b;
  while (e > b && std::isspace(static_cast<unsigned char>(s[e - 1]))) --e;
  return std::string(s.substr(b, e - b));
}

std::array<double, 3> rgb(const nlohmann::json& j, double null_value) {
  std::array<double, 3> v{};
  for (size_t c = 0; c < 3; ++c) v[c] = j.at(c).is_null() ? null_value : j.at(c).get<double>();
  return v;
}

// The compiled-in JSON is validated by medium_library_test; a malformed file
// is a build defect, so parsing it here may abort (it cannot be user input).
std::vector<LibraryMaterial> load_library() {
  const nlohmann::json doc = nlohmann::json::parse(detail::kMaterialLibraryJson, nullptr, false);
  std::vector<LibraryMaterial> out;
  if (doc.is_discarded() || !doc.contains("materials")) std::abort();
  for (const auto& e : doc["materials"]) {
    LibraryMaterial m;
    m.name = e.at("name").get<std::string>();
    m.thesis_name = e.at("thesis_name").get<std::string>();
    m.volume_text = e.at("volume_text").get<std::string>();
    m.volume_ml = e.at("volume_ml").is_null() ? 0.0 : e.at("volume_ml").get<double>();
    m.sigma_t_per_mm = rgb(e.at("sigma_t_per_mm"), 0.0);
    m.sigma_s_per_mm = rgb(e.at("sigma_s_per_mm"), 0.0);
    m.g = rgb(e.at("g"), std::numeric_limits<double>::quiet_NaN());
    m.check = e.at("check").get<std::string>();
    out.push_back(std::move(m));
  }
  if (out.empty()) std::abort();
  return out;
}

std::string known_names() {
  std::string s;
  for (const LibraryMaterial& m : material_library()) s += (s.empty() ? "" : ", ") + m.name;
  return s;
}

}  // namespace

Result<ColorChannel> parse_color_channel(std::string_view name) {
  const std::string n = lower(name);
  if (n == "red" || n == "r") return ColorChannel::red;
  if (n == "green" || n == "g") return ColorChannel::green;
  if (n == "blue" || n == "b") return ColorChannel::blue;
  return Error(Code::invalid_argument, "unknown colour channel '" + std::string(name) + "'",
               "use \"red\", \"green\" or \"blue\" (the sim is mono: the channel picks the table column)");
}

const std::vector<LibraryMaterial>& material_library() {
  static const std::vector<LibraryMaterial> lib = load_library();
  return lib;
}

const LibraryMaterial* find_material(std::string_view name) {
  std::string n = lower(trim(name));
  if (n == "milk") n = "lowfat milk";
  for (const LibraryMaterial& m : material_library())
    if (lower(m.name) == n || lower(m.thesis_name) == n) return &m;
  return nullptr;
}

Result<Medium> mixture_medium(const std::vector<MixturePart>& parts, double tank_litres, ColorChannel channel) {
  if (parts.empty())
    return Error(Code::invalid_argument, "mixture: no materials given", "name at least one library material");
  if (!(tank_litres > 0) || !std::isfinite(tank_litres))
    return Error(Code::invalid_argument, "tank_litres must be > 0, got " + std::to_string(tank_litres),
                 "the thesis tank holds 23 litres");
  const size_t c = static_cast<size_t>(channel);
  double sigma = 0, beta = 0, g_beta = 0;
  for (const MixturePart& p : parts) {
    const LibraryMaterial* m = find_material(p.name);
    if (m == nullptr)
      return Error(Code::invalid_argument, "unknown material '" + p.name + "'", "library names: " + known_names());
    if (!(p.volume_ml > 0) || !std::isfinite(p.volume_ml))
      return Error(Code::invalid_argument,
                   "volume_ml of '" + p.name + "' must be > 0, got " + std::to_string(p.volume_ml),
                   "the millilitres of the material poured into the tank");
    // Eq. 4.8: c2/c1 with c2 = V/(1000 T) and c1 the table row's fraction.
    const double scale = (p.volume_ml / (1000.0 * tank_litres)) / m->concentration();
    const double b = m->sigma_s_per_mm[c] * scale;
    sigma += m->sigma_t_per_mm[c] * scale;  // Eq. 4.9 (extinction alike)
    beta += b;                               // Eq. 4.9
    if (b > 0) g_beta += m->g[c] * b;        // Eq. 4.10 numerator; g undefined only where β = 0
  }
  Medium out;
  out.sigma_t_per_mm = sigma;
  out.sigma_s_per_mm = std::min(beta, sigma);  // rounding only: each part has β <= σ
  out.g = beta > 0 ? g_beta / beta : 0.0;      // Eq. 4.10
  if (sigma > 10.0)
    return Error(Code::invalid_argument,
                 "the mixture's extinction " + std::to_string(sigma) + "/mm exceeds the sim's limit 10/mm",
                 "use a smaller volume or a bigger tank");
  return out;
}

Result<Medium> material_medium(std::string_view name, double volume_ml, double tank_litres, ColorChannel channel) {
  return mixture_medium({MixturePart{std::string(name), volume_ml}}, tank_litres, channel);
}

Result<std::vector<MixturePart>> parse_mixture_spec(std::string_view spec, double total_volume_ml) {
  std::string s = trim(spec);
  std::vector<double> ratio;
  // Trailing "a:b[:c...]" ratio, separated by a space from the last name.
  const size_t sp = s.find_last_of(' ');
  if (sp != std::string::npos && s.find(':', sp) != std::string::npos) {
    std::string r = s.substr(sp + 1);
    s = trim(s.substr(0, sp));
    size_t pos = 0;
    while (pos <= r.size()) {
      const size_t colon = std::min(r.find(':', pos), r.size());
      const std::string tok = r.substr(pos, colon - pos);
      char* end = nullptr;
      const double x = std::strtod(tok.c_str(), &end);
      if (tok.empty() || end != tok.c_str() + tok.size() || !(x > 0) || !std::isfinite(x))
        return Error(Code::invalid_argument, "mixture '" + std::string(spec) + "': bad ratio '" + r + "'",
                     "write positive volume ratios like \"milk + espresso 1:3\"");
      ratio.push_back(x);
      pos = colon + 1;
    }
  }
  std::vector<MixturePart> parts;
  size_t pos = 0;
  while (pos <= s.size()) {
    const size_t plus = std::min(s.find('+', pos), s.size());
    MixturePart p;
    p.name = trim(std::string_view(s).substr(pos, plus - pos));
    if (p.name.empty())
      return Error(Code::invalid_argument, "mixture '" + std::string(spec) + "': empty material name",
                   "write names joined by '+', e.g. \"milk + espresso 1:3\"");
    parts.push_back(std::move(p));
    pos = plus + 1;
  }
  if (!ratio.empty() && ratio.size() != parts.size())
    return Error(Code::invalid_argument,
                 "mixture '" + std::string(spec) + "': " + std::to_string(parts.size()) + " materials but " +
                     std::to_string(ratio.size()) + " ratio terms",
                 "give one ratio term per material");
  if (ratio.empty()) ratio.assign(parts.size(), 1.0);
  double sum = 0;
  for (double r : ratio) sum += r;
  for (size_t i = 0; i < parts.size(); ++i) parts[i].volume_ml = total_volume_ml * ratio[i] / sum;
  return parts;
}

}  // namespace procam::sim
