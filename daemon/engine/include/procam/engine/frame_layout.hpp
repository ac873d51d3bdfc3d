// SPDX-License-Identifier: MIT
// Offline frame layouts: which image file of a capture folder is which frame
// of a decoder's plan (`procam decode --layout NAME|FILE`, issue 16).
//
// Layouts (files = the folder's image files sorted by name):
//  - "procam": file i is plan frame i (the plan order itself);
//  - "opencv-graycode": OpenCV structured_light::GrayCodePattern order — every
//    pattern followed by its inverse (columns, then rows), then white, then
//    black; i.e. the procam plan with white and black moved to the end. Needs
//    a plan with inverse frames (gray: binarize=inverse, rows=true for the
//    full 42-image set of a 1024x768 projector);
//  - "gupta-pairs": pattern/inverse pairs only, each pattern followed by its
//    inverse, no white or black (Gupta et al.'s released pattern sets): the
//    plan order without white and black, which are synthesized (below);
//  - a JSON layout file: an array of {"file": <glob or index>, "frame": <plan
//    label>}: "file" is a glob on the file name (*, ?, [..]; must match exactly
//    one file) or an integer index into the sorted files. Every plan frame
//    needs exactly one file, except white and black, which are synthesized
//    when absent.
// Synthesized white / black (missing from the capture): per pixel, white =
// max and black = min over every pattern/inverse frame of the round. Under
// direct light each pixel is fully lit in one of the coarsest pair and dark in
// the other, so these are its lit and unlit levels (biased outward by about
// 2 sigma of noise: the max/min of 2n noisy samples); they only set the
// contrast (validity rule 1 and confidence), never a bit.
// Errors (Code::invalid_argument) name the layout, the file and the expected
// frame, e.g. "layout opencv-graycode: file graycode_41.png should be frame 41
// 'black' but the plan has 44 frames ...".
// Thread-safety: pure functions.
#pragma once

#include <string>
#include <vector>

#include "procam/core/status.hpp"

namespace procam::engine {

// The built-in layout names, for help texts.
inline constexpr const char* kBuiltinLayouts = "procam, opencv-graycode, gupta-pairs";

struct FrameAssignment {
  std::vector<size_t> frame_of_file;   // plan frame index per used file
  std::vector<size_t> files;           // which files are used, in feeding order (indices)
  long white = -1, black = -1;         // plan frames to synthesize (-1: captured)
  std::vector<size_t> pair_frames;     // plan frames whose max/min make white/black
};

// Assigns `files` (names, sorted) to the plan frames `labels` under `layout`
// (a built-in name or a path to a JSON layout file).
Result<FrameAssignment> assign_frames(const std::string& layout,
                                      const std::vector<std::string>& labels,
                                      const std::vector<std::string>& files);

}  // namespace procam::engine
