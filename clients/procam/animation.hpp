// SPDX-License-Identifier: MIT
// `procam sim --frames N`: the dynamic medium's frames as one animated GIF
// (docs/legendre.md), written with OpenImageIO's GIF writer (Debian's
// libopenimageio: multi-subimage GIF, "FramesPerSecond" as a rational), so
// no video encoder is linked.
//
// Contract: frames are camera frames of one size, 1 channel, U8 or U16
// (`bit_depth` significant bits, scaled to 8 bits: value * 255 / max, rounded)
// or F32 (clamped to [0, 1], * 255, NaN black); gray is written as R = G = B
// (GIF has no gray mode). OpenImageIO quantises each frame to a 256-entry
// palette: a frame with all 256 gray levels reads back within one level
// (tested), fewer levels exactly. `fps` in (0, 100]: GIF delays are
// in 1/100 s, so the delay is round(100 / fps) hundredths. The GIF loops
// forever. Frames are streamed to the file one at a time (a long sequence
// is never held in memory). Errors (no frames, a frame of another size or
// type, bad fps, a file that cannot be written) come back as a Status naming
// the problem; nothing is thrown. One writer per thread; the file is
// complete only after close() returned ok.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"

namespace procam::cli {

class AnimatedGif {
 public:
  AnimatedGif();
  ~AnimatedGif();  // closes an open file (errors then go unreported: call close())
  AnimatedGif(const AnimatedGif&) = delete;
  AnimatedGif& operator=(const AnimatedGif&) = delete;

  // Creates `path`; the first add() fixes the frame size and type.
  Status open(const std::string& path, double fps);
  Status add(const Image& frame);
  // Finishes the file; failed_precondition if no frame was added.
  Status close();
  size_t frames() const { return frames_; }

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
  size_t frames_ = 0;
};

// All of `frames` at once (open, add each, close).
Status write_animated_gif(const std::string& path, const std::vector<Image>& frames, double fps);

}  // namespace procam::cli
