// SPDX-License-Identifier: MIT
// Screen camera: XGetImage of a root-window rectangle → grey frame.
#include "procam/hw/screencam/screen_camera.hpp"

#include <X11/Xlib.h>
#include <X11/Xutil.h>
#undef Status  // Xlib's `#define Status int` would clash with procam::Status

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <ctime>

#include "procam/base/clock.hpp"

namespace procam::screencam {

struct ScreenCamera::Impl {
  Display* dpy = nullptr;
  Window root = 0;
};

Result<std::unique_ptr<ScreenCamera>> ScreenCamera::open(const ScreenCameraConfig& config) {
  std::unique_ptr<ScreenCamera> c(new ScreenCamera());
  c->impl_ = std::make_unique<Impl>();
  c->config_ = config;
  const char* env = std::getenv("DISPLAY");
  const std::string name = !config.display.empty() ? config.display : (env ? env : "");
  if (name.empty())
    return Error(Code::unavailable, "screen camera: no X display (DISPLAY is not set)", "start Xvfb (scripts/xvfb.sh) or set \"display\"");
  c->impl_->dpy = XOpenDisplay(name.c_str());
  if (!c->impl_->dpy)
    return Error(Code::unavailable, "screen camera: cannot open X display '" + name + "'", "is the X server running?");
  Display* dpy = c->impl_->dpy;
  const int scr = DefaultScreen(dpy);
  c->impl_->root = RootWindow(dpy, scr);
  const auto sw = static_cast<uint32_t>(DisplayWidth(dpy, scr)), sh = static_cast<uint32_t>(DisplayHeight(dpy, scr));
  ScreenCameraConfig& k = c->config_;
  if (k.width == 0) k.width = sw - static_cast<uint32_t>(k.x);
  if (k.height == 0) k.height = sh - static_cast<uint32_t>(k.y);
  if (k.x < 0 || k.y < 0 || static_cast<uint32_t>(k.x) + k.width > sw || static_cast<uint32_t>(k.y) + k.height > sh)
    return Error(Code::invalid_argument,
                 "screen camera: region " + std::to_string(k.width) + "x" + std::to_string(k.height) + "+" + std::to_string(k.x) +
                     "+" + std::to_string(k.y) + " is outside the " + std::to_string(sw) + "x" + std::to_string(sh) + " screen of '" +
                     name + "'");
  c->info_.backend = "screencam";
  c->info_.id = k.id;
  c->info_.width = k.width;
  c->info_.height = k.height;
  c->info_.bit_depth = 8;
  return c;
}

ScreenCamera::~ScreenCamera() {
  if (impl_ && impl_->dpy) XCloseDisplay(impl_->dpy);
}

Status ScreenCamera::configure(const hw::CameraSettings& settings) {
  if (!std::isnan(settings.polarizer_deg)) return Error(Code::failed_precondition, "screen camera: no polarizer");
  return Status::Ok();
}

Result<hw::Frame> ScreenCamera::capture(std::chrono::milliseconds) {
  const int64_t t = mono_ns();
  XImage* im = XGetImage(impl_->dpy, impl_->root, config_.x, config_.y, config_.width, config_.height, AllPlanes, ZPixmap);
  if (!im) return Error(Code::io_error, "screen camera: XGetImage failed");
  hw::Frame f;
  f.image = Image(config_.width, config_.height, PixelType::u8);
  const unsigned long gmask = im->green_mask;
  int gshift = 0;
  while (gmask && !((gmask >> gshift) & 1ul)) ++gshift;
  if (im->bits_per_pixel == 32 && im->byte_order == LSBFirst && gmask == 0xff00ul) {
    for (uint32_t y = 0; y < config_.height; ++y) {
      const auto* row = reinterpret_cast<const uint8_t*>(im->data) + size_t{y} * static_cast<size_t>(im->bytes_per_line);
      uint8_t* out = f.image.row<uint8_t>(y);
      for (uint32_t x = 0; x < config_.width; ++x) out[x] = row[size_t{x} * 4 + 1];
    }
  } else {
    for (uint32_t y = 0; y < config_.height; ++y)
      for (uint32_t x = 0; x < config_.width; ++x)
        f.image.at<uint8_t>(x, y) = static_cast<uint8_t>((XGetPixel(im, static_cast<int>(x), static_cast<int>(y)) & gmask) >> gshift);
  }
  XDestroyImage(im);
  f.frame_id = next_id_++;
  f.timestamp_ns = t;
  grab_ms_sum_ += static_cast<double>(mono_ns() - t) / 1e6;
  return f;
}

nlohmann::json ScreenCamera::stats() const {
  const uint64_t n = next_id_ - 1;
  return {{"frames", n}, {"grab_ms_mean", n ? grab_ms_sum_ / static_cast<double>(n) : 0.0}};
}

}  // namespace procam::screencam
