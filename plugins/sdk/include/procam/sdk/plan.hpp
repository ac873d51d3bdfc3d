// SPDX-License-Identifier: MIT
// procam::sdk::Plan — owns the frames of one capture round (labels, pattern
// pixels, settings) and exposes them as the C procam_plan the host reads.
//
// Ownership: the Plan owns every byte the C view points to. view() pointers
// stay valid until the Plan is modified (add_frame, clear, set_note) or
// destroyed. The SDK keeps a session's current Plan untouched from the
// next_plan call that returned it until the following next_plan call or
// session_destroy — longer than the ABI's "until the next call" minimum, so a
// host may keep reading pattern i while it adds frames.
// Thread-safety: thread-bound (docs/threading.md), like the session that owns it.
#pragma once

#include <cmath>
#include <cstdint>
#include <deque>
#include <limits>
#include <span>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "procam/plugin_abi.h"

namespace procam::sdk {

// Settings with every field "unset" (keep the rig's configured value):
// exposure_us 0, gain_db -1, projector_focus_mm 0, polarisers NaN, camera 0,
// light 0 (the projector).
inline procam_frame_settings default_frame_settings() noexcept {
  procam_frame_settings s{};
  s.struct_size = sizeof(procam_frame_settings);
  s.camera_index = 0;
  s.exposure_us = 0.0;
  s.gain_db = -1.0;
  s.projector_focus_mm = 0.0;
  s.polarizer_deg = std::numeric_limits<double>::quiet_NaN();
  s.projector_polarizer_deg = std::numeric_limits<double>::quiet_NaN();
  s.light_index = 0;
  s.reserved3 = 0;
  return s;
}

class Plan {
 public:
  // Append a frame whose pattern is `width` x `height`, one channel of
  // `pixel_type`, zero-filled (black), with default_frame_settings().
  // Integer patterns use their full range (U8 255 / U16 65535 = white), F32
  // uses [0, 1]. Returns the frame's index. Throws std::invalid_argument for
  // an empty size or unknown type (a plugin bug) and std::bad_alloc.
  uint32_t add_frame(std::string label, uint32_t width, uint32_t height,
                     procam_pixel_type pixel_type = PROCAM_PIXEL_U8) {
    if (width == 0 || height == 0) throw std::invalid_argument("Plan::add_frame: empty pattern");
    Frame f;
    f.label = std::move(label);
    f.image.width = width;
    f.image.height = height;
    f.image.channels = 1;
    f.image.pixel_type = pixel_type;
    const size_t n = size_t{width} * height;
    switch (pixel_type) {
      case PROCAM_PIXEL_U8:
        f.u8.assign(n, 0);
        f.image.bit_depth = 8;
        f.image.stride_bytes = width;
        break;
      case PROCAM_PIXEL_U16:
        f.u16.assign(n, 0);
        f.image.bit_depth = 16;
        f.image.stride_bytes = size_t{width} * 2;
        break;
      case PROCAM_PIXEL_F32:
        f.f32.assign(n, 0.0f);
        f.image.bit_depth = 32;
        f.image.stride_bytes = size_t{width} * 4;
        break;
      default: throw std::invalid_argument("Plan::add_frame: unknown pixel type");
    }
    f.settings = default_frame_settings();
    frames_.push_back(std::move(f));
    dirty_ = true;
    return static_cast<uint32_t>(frames_.size() - 1);
  }

  uint32_t size() const noexcept { return static_cast<uint32_t>(frames_.size()); }
  bool empty() const noexcept { return frames_.empty(); }
  const std::string& label(uint32_t i) const { return frames_.at(i).label; }

  // Pattern pixels, row-major, width*height samples. Empty span when the
  // frame has another pixel type. Throws std::out_of_range for a bad index.
  std::span<uint8_t> pattern_u8(uint32_t i) { return frames_.at(i).u8; }
  std::span<uint16_t> pattern_u16(uint32_t i) { return frames_.at(i).u16; }
  std::span<float> pattern_f32(uint32_t i) { return frames_.at(i).f32; }
  std::span<const uint8_t> pattern_u8(uint32_t i) const { return frames_.at(i).u8; }
  const procam_image& pattern(uint32_t i) const { return frames_.at(i).image; }

  procam_frame_settings& settings(uint32_t i) { return frames_.at(i).settings; }
  const procam_frame_settings& settings(uint32_t i) const { return frames_.at(i).settings; }

  // Why this round (shown to users); empty = none (note is NULL in the view).
  void set_note(std::string note) {
    note_ = std::move(note);
    dirty_ = true;
  }
  const std::string& note() const noexcept { return note_; }

  void clear() {
    frames_.clear();
    note_.clear();
    dirty_ = true;
  }

  // The C view over this Plan's storage (see the ownership note above).
  const procam_plan* view() {
    if (dirty_) {
      c_frames_.clear();
      c_frames_.reserve(frames_.size());
      for (Frame& f : frames_) {
        f.image.data = f.u8.empty() ? (f.u16.empty() ? static_cast<const void*>(f.f32.data())
                                                     : static_cast<const void*>(f.u16.data()))
                                    : static_cast<const void*>(f.u8.data());
        procam_pattern_frame c{};
        c.label = f.label.c_str();
        c.pattern = f.image;
        c.settings = f.settings;
        c_frames_.push_back(c);
      }
      c_plan_.frame_count = static_cast<uint32_t>(c_frames_.size());
      c_plan_.frames = c_frames_.data();
      c_plan_.note = note_.empty() ? nullptr : note_.c_str();
      dirty_ = false;
    } else {
      // Settings may have been edited through settings(i) since the last view.
      for (size_t i = 0; i < frames_.size(); ++i) c_frames_[i].settings = frames_[i].settings;
    }
    return &c_plan_;
  }

 private:
  struct Frame {
    std::string label;
    std::vector<uint8_t> u8;
    std::vector<uint16_t> u16;
    std::vector<float> f32;
    procam_image image{};
    procam_frame_settings settings{};
  };
  std::deque<Frame> frames_;  // deque: frames never move once added
  std::string note_;
  std::vector<procam_pattern_frame> c_frames_;
  procam_plan c_plan_{};
  bool dirty_ = true;
};

}  // namespace procam::sdk
