// SPDX-License-Identifier: MIT
// Writes plugin outputs as files + previews and describes them for the manifest.
#include "procam/engine/results.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <sstream>

#include "procam/core/image_io.hpp"
#include "procam/engine/previews.hpp"
#include "procam/engine/rig_json.hpp"

namespace procam::engine {
namespace fs = std::filesystem;

void turbo(double t, uint8_t rgb[3]) {
  // Polynomial approximation of Google's Turbo colormap (A. Mikhailov, 2019,
  // Apache-2.0): channel = sum_k c_k t^k, k = 0..5.
  static constexpr double r[6] = {0.13572138, 4.61539260, -42.66032258, 132.13108234, -152.94239396, 59.28637943};
  static constexpr double g[6] = {0.09140261, 2.19418839, 4.84296658, -14.18503333, 4.27729857, 2.82956604};
  static constexpr double b[6] = {0.10667330, 12.64194608, -60.58204836, 110.36276771, -89.90310912, 27.34824973};
  t = std::clamp(t, 0.0, 1.0);
  const double p[6] = {1, t, t * t, t * t * t, t * t * t * t, t * t * t * t * t};
  const double* c[3] = {r, g, b};
  for (int ch = 0; ch < 3; ++ch) {
    double v = 0;
    for (int k = 0; k < 6; ++k) v += c[ch][k] * p[k];
    rgb[ch] = static_cast<uint8_t>(std::lround(std::clamp(v, 0.0, 1.0) * 255.0));
  }
}

Image colormap_preview(const Image& f) {
  Image out(f.width(), f.height(), PixelType::u8, 3);
  if (f.type() != PixelType::f32 || f.channels() != 1) return out;
  std::vector<float> finite;
  const size_t n = f.pixel_count();
  const float* src = f.ptr<float>();
  finite.reserve(n);
  for (size_t i = 0; i < n; ++i)
    if (std::isfinite(src[i])) finite.push_back(src[i]);
  if (finite.empty()) return out;
  auto pct = [&](double q) {
    auto k = static_cast<std::ptrdiff_t>(q * double(finite.size() - 1));
    std::nth_element(finite.begin(), finite.begin() + k, finite.end());
    return double(finite[static_cast<size_t>(k)]);
  };
  const double lo = pct(0.01), hi = pct(0.99);
  const double span = hi > lo ? hi - lo : 1.0;
  uint8_t* dst = out.ptr<uint8_t>();
  for (size_t i = 0; i < n; ++i) {
    if (!std::isfinite(src[i])) continue;  // stays black
    turbo((double(src[i]) - lo) / span, dst + 3 * i);
  }
  return out;
}

Status write_ply(const std::string& path, const float* pts, uint64_t count, uint32_t stride,
                 const std::string& fields, uint64_t* written) {
  std::vector<std::string> names;
  {
    std::stringstream ss(fields.empty() ? "x,y,z" : fields);
    std::string f;
    while (std::getline(ss, f, ',')) names.push_back(f);
  }
  while (names.size() < stride) names.push_back("f" + std::to_string(names.size()));
  names.resize(stride);
  std::string body;
  uint64_t kept = 0;
  body.reserve(static_cast<size_t>(count) * stride * 4);
  for (uint64_t i = 0; i < count; ++i) {
    const float* p = pts + i * stride;
    if (!std::isfinite(p[0]) || !std::isfinite(p[1]) || !std::isfinite(p[2])) continue;
    body.append(reinterpret_cast<const char*>(p), size_t{stride} * sizeof(float));
    ++kept;
  }
  std::string header = "ply\nformat binary_little_endian 1.0\ncomment procam point cloud, camera frame, mm\n";
  header += "element vertex " + std::to_string(kept) + "\n";
  for (const auto& nme : names) header += "property float " + nme + "\n";
  header += "end_header\n";
  if (written) *written = kept;
  return write_file_atomic(path, header + body);
}

namespace {
// The legend a plugin gave a class map (JSON output "<map>_legend"), if any.
nlohmann::json legend_for(const std::vector<host::Output>& outputs, const std::string& map) {
  for (const auto& o : outputs)
    if (o.kind == PROCAM_OUTPUT_JSON && o.name == map + "_legend")
      return nlohmann::json::parse(o.json, nullptr, /*allow_exceptions=*/false);
  return nullptr;
}
}  // namespace

Result<WrittenOutputs> write_outputs(const std::string& dir, const std::vector<host::Output>& outputs) {
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return Error(Code::io_error, "cannot create results folder '" + dir + "': " + ec.message());
  WrittenOutputs w;
  for (const auto& o : outputs) {
    nlohmann::json e = {{"name", o.name}, {"unit", o.unit}, {"description", o.description}};
    const std::string base = (fs::path(dir) / o.name).string();
    switch (o.kind) {
      case PROCAM_OUTPUT_IMAGE: {
        Image img = Image::copy_of(o.image);
        if (img.empty()) return Error(Code::plugin_error, "output '" + o.name + "' is not a valid image");
        e["kind"] = "image";
        e["width"] = img.width();
        e["height"] = img.height();
        e["channels"] = img.channels();
        if (img.type() == PixelType::f32) {
          e["file"] = o.name + ".exr";
          e["format"] = "exr-f32";
          PROCAM_TRY(write_image(base + ".exr", img, {{"procam:unit", o.unit}, {"procam:name", o.name}}));
          if (img.channels() == 1) {
            PROCAM_TRY(write_image(base + ".preview.png", scalar_map_preview(img, o.unit, o.name)));
            w.previews.push_back({{"of", o.name}, {"file", o.name + ".preview.png"}});
            if (o.unit == "px") {
              // Correspondence maps also as 16-bit PNG in 1/16 px fixed point
              // for tools without EXR: value = round(16 * px), 65535 = invalid.
              Image q(img.width(), img.height(), PixelType::u16);
              const float* s = img.ptr<float>();
              uint16_t* d = q.ptr<uint16_t>();
              for (size_t i = 0; i < img.pixel_count(); ++i) {
                const double v = double(s[i]) * 16.0;
                d[i] = (std::isfinite(s[i]) && v >= 0 && v < 65534.5) ? static_cast<uint16_t>(std::lround(v)) : 65535;
              }
              PROCAM_TRY(write_image(base + ".png", q));
              e["file_png16"] = o.name + ".png";
              e["png16_scale"] = 16;
              e["png16_invalid"] = 65535;
            }
          }
        } else {
          e["file"] = o.name + ".png";
          e["format"] = img.type() == PixelType::u8 ? "png-u8" : "png-u16";
          e["bit_depth"] = img.bit_depth();
          PROCAM_TRY(write_image(base + ".png", img));
          if (img.channels() == 1 && img.type() == PixelType::u8 && o.unit == "class") {
            // Raw class values (0..N) look black in a viewer: the preview is
            // coloured, with a key naming each class and its share.
            const auto classes = parse_class_legend(legend_for(outputs, o.name));
            PROCAM_TRY(write_image(base + ".preview.png", class_map_preview(img, classes, o.name)));
            w.previews.push_back({{"of", o.name}, {"file", o.name + ".preview.png"}});
          } else if (img.channels() == 1 && img.type() == PixelType::u8) {
            w.previews.push_back({{"of", o.name}, {"file", o.name + ".png"}});
          }
        }
        break;
      }
      case PROCAM_OUTPUT_POINTS: {
        uint64_t kept = 0;
        PROCAM_TRY(write_ply(base + ".ply", o.points, o.point_count, o.point_stride, o.point_fields, &kept));
        e["kind"] = "points";
        e["file"] = o.name + ".ply";
        e["format"] = "ply-binary-le";
        e["count"] = kept;
        e["fields"] = o.point_fields.empty() ? "x,y,z" : o.point_fields;
        break;
      }
      case PROCAM_OUTPUT_SCALAR:
        e["kind"] = "scalar";
        e["value"] = std::isfinite(o.scalar) ? nlohmann::json(o.scalar) : nlohmann::json(nullptr);
        break;
      case PROCAM_OUTPUT_JSON:
        e["kind"] = "json";
        try {
          e["value"] = nlohmann::json::parse(o.json);
        } catch (const std::exception&) {
          e["value"] = o.json;  // keep what the plugin said, as text
        }
        break;
      default:
        return Error(Code::plugin_error, "output '" + o.name + "' has an unknown kind");
    }
    w.outputs.push_back(std::move(e));
  }
  return w;
}

nlohmann::json list_files(const std::string& dir) {
  nlohmann::json files = nlohmann::json::array();
  std::error_code ec;
  std::vector<std::pair<std::string, uintmax_t>> v;
  for (const auto& ent : fs::directory_iterator(dir, ec)) {
    if (!ent.is_regular_file()) continue;
    std::string name = ent.path().filename().string();
    if (name.empty() || name[0] == '.') continue;  // temporaries
    v.emplace_back(name, ent.file_size(ec));
  }
  std::sort(v.begin(), v.end());
  for (auto& [n, s] : v) files.push_back({{"name", n}, {"size_bytes", s}});
  return files;
}

}  // namespace procam::engine
