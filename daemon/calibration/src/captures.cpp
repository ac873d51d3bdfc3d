// SPDX-License-Identifier: MIT
// Capture folder -> calibration View (procam/calibration/captures.hpp).
#include "procam/calibration/captures.hpp"

#include <algorithm>
#include <filesystem>

#include "procam/core/image_io.hpp"
#include "procam/engine/scan_runner.hpp"

namespace procam::calibration {

Result<View> decode_capture(const host::PluginHost& host, const std::string& dir, const DecodeOptions& o) {
  if (o.projector_width == 0 || o.projector_height == 0)
    return Error(Code::invalid_argument, "calibration capture: projector size not given", "give --projector WxH");
  std::vector<std::string> files = engine::list_image_files(dir);
  // A scan folder with saved frames (frame-r<round>-<index>.png) also holds
  // the scan's output images and previews: only the frames make the white.
  if (std::filesystem::is_regular_file(std::filesystem::path(dir) / engine::recorded_frame_name(1, 0)))
    std::erase_if(files, [](const std::string& f) {
      return !std::filesystem::path(f).filename().string().starts_with("frame-r");
    });
  if (files.empty())
    return Error(Code::invalid_argument, "calibration capture " + dir + ": no image files",
                 "each capture folder holds one board pose's Gray-code frames");
  View v;
  v.name = std::filesystem::path(dir).filename().string();
  if (v.name.empty()) v.name = dir;
  // White: per-pixel maximum over every frame (header), scaled to 8 bits.
  std::vector<uint32_t> peak;
  uint32_t bits = 8;
  for (const std::string& f : files) {
    auto img = read_image((std::filesystem::path(dir) / f).string());
    if (!img.ok()) return img.status();
    if (img->type() != PixelType::u8 && img->type() != PixelType::u16)
      return Error(Code::invalid_argument, "calibration capture " + dir + "/" + f + ": 8- or 16-bit grey images only");
    if (peak.empty()) {
      v.width = img->width();
      v.height = img->height();
      peak.assign(size_t{v.width} * v.height, 0);
      bits = img->type() == PixelType::u8 ? 8u : (img->bit_depth() > 0 ? img->bit_depth() : 16u);
    } else if (img->width() != v.width || img->height() != v.height) {
      return Error(Code::invalid_argument, "calibration capture " + dir + "/" + f + " is " +
                                               std::to_string(img->width()) + "x" + std::to_string(img->height()) +
                                               " but the first frame is " + std::to_string(v.width) + "x" +
                                               std::to_string(v.height));
    }
    for (size_t i = 0; i < peak.size(); ++i) {
      const uint32_t x = img->type() == PixelType::u8 ? img->data()[i] : img->ptr<uint16_t>()[i];
      peak[i] = std::max(peak[i], x);
    }
  }
  v.white.resize(peak.size());
  const uint32_t shift = bits > 8 ? bits - 8 : 0;
  for (size_t i = 0; i < peak.size(); ++i) v.white[i] = static_cast<uint8_t>(std::min(255u, peak[i] >> shift));

  const nlohmann::json rig = {
      {"projector", {{"width", o.projector_width}, {"height", o.projector_height}}},
      {"cameras", {{{"width", v.width}, {"height", v.height}, {"bit_depth", bits}}}},
      {"threads", o.threads}};
  auto session = host.create_session(o.plugin, o.method, o.params.dump(), rig.dump());
  if (!session.ok()) return session.status();
  auto outcome = engine::run_offline(*session, dir, nullptr, engine::OfflineOptions{o.layout});
  if (!outcome.ok()) return outcome.status();
  auto outs = session->outputs();
  if (!outs.ok()) return outs.status();
  const size_t n = size_t{v.width} * v.height;
  for (const host::Output& out : *outs) {
    if (out.kind != PROCAM_OUTPUT_IMAGE || out.image.pixel_type != PROCAM_PIXEL_F32 ||
        out.image.width != v.width || out.image.height != v.height)
      continue;
    std::vector<float> map(n);
    for (uint32_t y = 0; y < v.height; ++y) {
      const auto* row = reinterpret_cast<const float*>(static_cast<const uint8_t*>(out.image.data) +
                                                       size_t{y} * out.image.stride_bytes);
      std::copy(row, row + v.width, map.begin() + static_cast<std::ptrdiff_t>(size_t{y} * v.width));
    }
    if (out.name == "proj_col_px") v.proj_col = std::move(map);
    if (out.name == "proj_row_px") v.proj_row = std::move(map);
  }
  if (v.proj_col.empty() || v.proj_row.empty())
    return Error(Code::failed_precondition,
                 "calibration capture " + dir + ": " + o.plugin + "/" + o.method +
                     " gave no proj_col_px and proj_row_px",
                 "the capture must include row planes (gray with rows=true) as well as column planes");
  return v;
}

}  // namespace procam::calibration
