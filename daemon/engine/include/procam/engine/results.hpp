// SPDX-License-Identifier: MIT
// Results writer: turns a plugin's outputs into files in a scan folder —
// EXR for float maps, PNG for 8/16-bit maps, PLY for point clouds, colour-mapped
// PNG previews — and describes them for the manifest (proto/PROTOCOL.md).
//
// Threads: reentrant. Errors: io_error naming the file; earlier files stay.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"
#include "procam/host/plugin_host.hpp"

namespace procam::engine {

struct WrittenOutputs {
  nlohmann::json outputs = nlohmann::json::array();   // manifest "outputs"
  nlohmann::json previews = nlohmann::json::array();  // manifest "previews"
};

// Writes every output of `outputs` into `dir` (created if needed).
Result<WrittenOutputs> write_outputs(const std::string& dir,
                                     const std::vector<host::Output>& outputs);

// PLY, binary little-endian, float properties named by `fields` (comma-separated,
// first three x,y,z). Points with a non-finite x/y/z are skipped. Atomic.
Status write_ply(const std::string& path, const float* points, uint64_t count, uint32_t stride,
                 const std::string& fields, uint64_t* written = nullptr);

// Colour-mapped 8-bit RGB preview of a float map: Turbo colormap over the
// 1st..99th percentile of finite values; NaN pixels black.
Image colormap_preview(const Image& f32);

// Turbo colormap (Mikhailov 2019, polynomial approximation); t in [0,1].
void turbo(double t, uint8_t rgb[3]);

// "manifest.json" folder listing: [{"name","size_bytes"}] of plain files.
nlohmann::json list_files(const std::string& dir);

}  // namespace procam::engine
