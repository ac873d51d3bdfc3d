// SPDX-License-Identifier: MIT
// OpenImageIO-backed image reading/writing with atomic writes.
#include "procam/core/image_io.hpp"

#include <OpenImageIO/imageio.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>

namespace procam {
namespace fs = std::filesystem;

namespace {

std::string lower_ext(const std::string& path) {
  std::string e = fs::path(path).extension().string();
  std::transform(e.begin(), e.end(), e.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return e;
}

// Temporary sibling that keeps the extension (OIIO picks the format from it).
std::string temp_sibling(const std::string& path) {
  static std::atomic<unsigned> counter{0};
  fs::path p(path);
  std::string name = "." + p.stem().string() + ".tmp" + std::to_string(::getpid()) + "_" +
                     std::to_string(counter++) + p.extension().string();
  return (p.parent_path() / name).string();
}

}  // namespace

Result<Image> read_image(const std::string& path, bool keep_channels) {
  auto in = OIIO::ImageInput::open(path);
  if (!in) {
    std::string err = OIIO::geterror();
    if (!fs::exists(path))
      return Error(Code::not_found, "image file '" + path + "' does not exist");
    return Error(Code::corrupt_data, "cannot read image '" + path + "': " + err,
                 "use PNG, TIFF, JPG, PGM or EXR files");
  }
  const OIIO::ImageSpec& spec = in->spec();
  if (spec.width <= 0 || spec.height <= 0 || spec.nchannels <= 0 || spec.width > 65536 ||
      spec.height > 65536)
    return Error(Code::corrupt_data, "image '" + path + "' has invalid dimensions");
  const auto w = static_cast<uint32_t>(spec.width), h = static_cast<uint32_t>(spec.height);
  const auto nch = static_cast<uint32_t>(spec.nchannels);

  PixelType type;
  OIIO::TypeDesc fmt;
  uint32_t bits;
  switch (spec.format.basetype) {
    case OIIO::TypeDesc::UINT8:
    case OIIO::TypeDesc::INT8:
      type = PixelType::u8; fmt = OIIO::TypeDesc::UINT8; bits = 8; break;
    case OIIO::TypeDesc::UINT16:
    case OIIO::TypeDesc::INT16:
      type = PixelType::u16; fmt = OIIO::TypeDesc::UINT16; bits = 16; break;
    default:
      type = PixelType::f32; fmt = OIIO::TypeDesc::FLOAT; bits = 32; break;
  }
  if (type != PixelType::f32) {
    int bps = spec.get_int_attribute("oiio:BitsPerSample", 0);
    // PNG has no 10/12/14-bit samples: write_image leaves the depth in a
    // text chunk, which wins over the container's 16.
    if (const int tagged = std::atoi(spec.get_string_attribute("procam:bit_depth").c_str()); tagged > 0)
      bps = tagged;
    if (bps > 0 && bps <= static_cast<int>(bits)) bits = static_cast<uint32_t>(bps);
    // OIIO scales sub-16-bit PNG/TIFF data to the full 16-bit range; keep the
    // stored values as they are by asking for the native type and trusting
    // the file's own sample range (see test read_12bit_tiff).
  }
  Image all(w, h, type, nch, bits);
  if (!in->read_image(0, 0, 0, static_cast<int>(nch), fmt, all.data()))
    return Error(Code::corrupt_data, "cannot decode image '" + path + "': " + in->geterror(),
                 "the file may be truncated or corrupt");
  in->close();
  if (keep_channels || nch == 1) return all;

  // Grey: Rec. 601 luma of the first three channels (or the first if < 3).
  Image grey(w, h, type, 1, bits);
  const size_t n = all.pixel_count();
  auto mix = [&](auto* dst, const auto* src) {
    for (size_t i = 0; i < n; ++i) {
      const auto* p = src + i * nch;
      double v = nch >= 3 ? 0.299 * double(p[0]) + 0.587 * double(p[1]) + 0.114 * double(p[2])
                          : double(p[0]);
      using T = std::remove_pointer_t<decltype(dst)>;
      if constexpr (std::is_floating_point_v<T>) dst[i] = static_cast<T>(v);
      else dst[i] = static_cast<T>(std::lround(v));
    }
  };
  if (type == PixelType::u8) mix(grey.ptr<uint8_t>(), all.ptr<uint8_t>());
  else if (type == PixelType::u16) mix(grey.ptr<uint16_t>(), all.ptr<uint16_t>());
  else mix(grey.ptr<float>(), all.ptr<float>());
  return grey;
}

Status write_image(const std::string& path, const Image& image,
                   const std::map<std::string, std::string>& attributes) {
  if (image.empty()) return Error(Code::invalid_argument, "refusing to write empty image " + path);
  const std::string ext = lower_ext(path);
  OIIO::TypeDesc fmt = image.type() == PixelType::u8    ? OIIO::TypeDesc::UINT8
                       : image.type() == PixelType::u16 ? OIIO::TypeDesc::UINT16
                                                         : OIIO::TypeDesc::FLOAT;
  if (ext == ".png" && image.type() == PixelType::f32)
    return Error(Code::invalid_argument, "PNG cannot hold float data: " + path, "write .exr");
  OIIO::ImageSpec spec(static_cast<int>(image.width()), static_cast<int>(image.height()),
                       static_cast<int>(image.channels()), fmt);
  if (image.type() != PixelType::f32 && image.bit_depth() != bytes_per_sample(image.type()) * 8) {
    spec.attribute("oiio:BitsPerSample", static_cast<int>(image.bit_depth()));
    // Kept by formats without such samples too (PNG: a tEXt chunk), so a
    // 12-bit frame reads back as 12-bit, values unchanged (read_image).
    spec.attribute("procam:bit_depth", std::to_string(image.bit_depth()));
  }
  if (ext == ".exr") spec.attribute("compression", "zip");
  for (const auto& [k, v] : attributes) spec.attribute(k, v);

  std::error_code ec;
  fs::path parent = fs::path(path).parent_path();
  if (!parent.empty()) fs::create_directories(parent, ec);
  const std::string tmp = temp_sibling(path);
  auto out = OIIO::ImageOutput::create(tmp);
  if (!out) return Error(Code::io_error, "no image writer for '" + path + "': " + OIIO::geterror());
  if (!out->open(tmp, spec)) {
    return Error(Code::io_error, "cannot create '" + path + "': " + out->geterror(),
                 "check that the folder exists and is writable");
  }
  bool ok = out->write_image(fmt, image.data());
  ok = out->close() && ok;
  if (!ok) {
    fs::remove(tmp, ec);
    return Error(Code::io_error, "writing '" + path + "' failed: " + out->geterror());
  }
  fs::rename(tmp, path, ec);
  if (ec) {
    fs::remove(tmp, ec);
    return Error(Code::io_error, "cannot move result into place at '" + path + "': " + ec.message());
  }
  return Status::Ok();
}

}  // namespace procam
