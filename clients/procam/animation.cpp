// SPDX-License-Identifier: MIT
#include "animation.hpp"

#include <OpenImageIO/imageio.h>

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace procam::cli {

namespace {

// 8-bit gray of a frame's pixel i (animation.hpp contract).
uint8_t gray8(const Image& im, size_t i) {
  double v = 0.0;
  if (im.type() == PixelType::u8) v = im.ptr<uint8_t>()[i] / im.max_value();
  else if (im.type() == PixelType::u16) v = im.ptr<uint16_t>()[i] / im.max_value();
  else v = static_cast<double>(im.ptr<float>()[i]);
  return static_cast<uint8_t>(std::lround((std::isfinite(v) ? std::clamp(v, 0.0, 1.0) : 0.0) * 255.0));
}

}  // namespace

struct AnimatedGif::Impl {
  std::string path;
  OIIO::ImageSpec spec;
  std::unique_ptr<OIIO::ImageOutput> out;
  PixelType type = PixelType::u8;
  std::vector<uint8_t> rgb;
};

AnimatedGif::AnimatedGif() = default;
AnimatedGif::~AnimatedGif() {
  if (impl_ && impl_->out && frames_ > 0) impl_->out->close();
}

Status AnimatedGif::open(const std::string& path, double fps) {
  if (!(fps > 0.0 && fps <= 100.0))
    return Error(Code::invalid_argument, "animated GIF '" + path + "': fps " + std::to_string(fps) + " out of (0, 100]",
                 "GIF frame delays are whole hundredths of a second");
  auto impl = std::make_unique<Impl>();
  impl->path = path;
  impl->out = OIIO::ImageOutput::create(path);
  if (!impl->out || !impl->out->supports("appendsubimage"))
    return Error(Code::unavailable, "animated GIF '" + path + "': no multi-frame GIF writer in OpenImageIO: " +
                                        OIIO::geterror(),
                 "install Debian's libopenimageio (it writes GIF with giflib)");
  // GIF delays are 1/100 s: FramesPerSecond = 100 / delay.
  const int delay = std::max(1, static_cast<int>(std::lround(100.0 / fps)));
  const int rate[2] = {100, delay};
  impl->spec.attribute("FramesPerSecond", OIIO::TypeRational, rate);
  impl->spec.attribute("oiio:LoopCount", 0);  // loop forever
  impl_ = std::move(impl);
  frames_ = 0;
  return {};
}

Status AnimatedGif::add(const Image& f) {
  if (!impl_ || !impl_->out) return Error(Code::failed_precondition, "animated GIF: add() before open()");
  Impl& m = *impl_;
  if (f.channels() != 1 || f.width() == 0 || f.height() == 0 ||
      (frames_ > 0 && (static_cast<int>(f.width()) != m.spec.width || static_cast<int>(f.height()) != m.spec.height ||
                       f.type() != m.type)))
    return Error(Code::invalid_argument,
                 "animated GIF '" + m.path + "': frame " + std::to_string(frames_) +
                     " is not a 1-channel image of the first frame's size and type",
                 "pass the camera's frames of one capture setting");
  if (frames_ == 0) {
    m.spec.width = m.spec.full_width = static_cast<int>(f.width());
    m.spec.height = m.spec.full_height = static_cast<int>(f.height());
    m.spec.nchannels = 3;
    m.spec.format = OIIO::TypeDesc::UINT8;
    m.spec.default_channel_names();
    m.type = f.type();
    if (!m.out->open(m.path, m.spec))
      return Error(Code::io_error, "animated GIF '" + m.path + "': cannot open: " + m.out->geterror(),
                   "check that the folder exists and is writable");
  } else if (!m.out->open(m.path, m.spec, OIIO::ImageOutput::AppendSubimage)) {
    return Error(Code::io_error, "animated GIF '" + m.path + "': frame " + std::to_string(frames_) + ": " +
                                     m.out->geterror());
  }
  const size_t n = size_t{f.width()} * f.height();
  m.rgb.resize(3 * n);
  for (size_t i = 0; i < n; ++i) m.rgb[3 * i] = m.rgb[3 * i + 1] = m.rgb[3 * i + 2] = gray8(f, i);
  if (!m.out->write_image(OIIO::TypeDesc::UINT8, m.rgb.data()))
    return Error(Code::io_error, "animated GIF '" + m.path + "': frame " + std::to_string(frames_) + ": " +
                                     m.out->geterror());
  ++frames_;
  return {};
}

Status AnimatedGif::close() {
  if (!impl_ || !impl_->out) return Error(Code::failed_precondition, "animated GIF: close() before open()");
  if (frames_ == 0) return Error(Code::failed_precondition, "animated GIF '" + impl_->path + "': no frames",
                                 "add at least one frame");
  const bool ok = impl_->out->close();
  const std::string err = ok ? std::string() : impl_->out->geterror();
  impl_->out.reset();
  if (!ok) return Error(Code::io_error, "animated GIF '" + impl_->path + "': close: " + err);
  return {};
}

Status write_animated_gif(const std::string& path, const std::vector<Image>& frames, double fps) {
  AnimatedGif gif;
  Status st = gif.open(path, fps);
  for (size_t k = 0; st.ok() && k < frames.size(); ++k) st = gif.add(frames[k]);
  return st.ok() ? gif.close() : st;
}

}  // namespace procam::cli
