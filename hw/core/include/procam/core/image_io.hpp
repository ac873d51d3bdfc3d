// SPDX-License-Identifier: MIT
// Image files through OpenImageIO: read captured frames (PNG, JPG, TIFF, EXR,
// PGM...) and write results (EXR for float maps, 16-bit PNG, 8-bit PNG).
//
// Thread-safety: reentrant (each call opens its own file handles).
// Writes are atomic: a temporary file in the same folder is renamed into place,
// so a reader never sees a half-written result.
#pragma once

#include <map>
#include <string>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"

namespace procam {

// Reads the first subimage. Colour images are converted to grey (Rec. 601 luma)
// unless keep_channels. 8-bit files → u8; 9–16-bit → u16 (bit_depth from the
// file's "oiio:BitsPerSample" when present); half/float → f32.
Result<Image> read_image(const std::string& path, bool keep_channels = false);

// Writes by extension: ".exr" (float32, optional string attributes), ".png"
// (u8 or u16), ".tif"/".tiff", ".pgm". Atomic (temp + rename).
Status write_image(const std::string& path, const Image& image,
                   const std::map<std::string, std::string>& attributes = {});

}  // namespace procam
