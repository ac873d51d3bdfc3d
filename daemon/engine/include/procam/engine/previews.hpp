// SPDX-License-Identifier: MIT
// Previews a person can read without the docs: float maps with a colour bar
// that names the range and unit, class maps with a colour key, and the
// one-page scan report (report.html) that shows them with the scan's numbers.
//
// Threads: reentrant. Errors: io_error naming the file.
#pragma once

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "procam/core/image.hpp"
#include "procam/core/status.hpp"

namespace procam::engine {

// One class of a categorical map (unit "class").
struct ClassLabel {
  int value = 0;         // pixel value 0..255
  std::string name;      // e.g. "interreflection"
  std::string meaning;   // optional longer text for the key
};

// A plugin names a class map's classes in a JSON output called
// "<map>_legend": {"classes": [{"value": 0, "name": "unlit", "meaning": "..."}]}.
// Returns the classes, or an empty list when `legend` has no usable entries
// (unknown values then show as "class N").
std::vector<ClassLabel> parse_class_legend(const nlohmann::json& legend);

// Float map (F32, 1 channel) as Turbo colours over its 1st..99th percentile,
// NaN black, with a colour bar underneath labelled with the low, middle and
// high values and `unit` ("mm", "px", or "" for a plain number) and `title`.
// The image part keeps the map's size; the bar adds rows below it.
Image scalar_map_preview(const Image& f32, const std::string& unit, const std::string& title);

// Class map (U8, 1 channel) in distinct colours, with a key to the right:
// one swatch per class that occurs or is named, its name and its share of
// the pixels.
Image class_map_preview(const Image& u8, const std::vector<ClassLabel>& classes,
                        const std::string& title);

// The distinct colour of class value `v` in class_map_preview (0 is black).
void class_color(int v, uint8_t rgb[3]);

// Writes `dir`/report.html: what was run (plugin, method, params, patterns,
// rounds, timings), the evaluation against ground truth when present, every
// scalar output, every preview image with its description, and the plugin's
// report JSON. Reads only `manifest` (the scan's manifest.json content); the
// images are referenced by file name, so the folder can be copied as a whole.
Status write_scan_report(const std::string& dir, const nlohmann::json& manifest);

}  // namespace procam::engine
