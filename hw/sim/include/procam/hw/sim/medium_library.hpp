// SPDX-License-Identifier: MIT
// The material library of thesis Table 4.1 (= Table 1 of Narasimhan et al.,
// "Acquiring Scattering Properties of Participating Media by Dilution",
// SIGGRAPH 2006): 40 media measured diluted in a 23 l tank, with σ, β, g per
// RGB channel. Data: hw/sim/data/materials/narasimhan2006.json (compiled into
// the library, so no file is looked up at run time); provenance and the
// cross-check against pbrt-v3's table: docs/materials.md.
//
// Concentration (Eq. 4.8): σ and β scale with the volume fraction c = V/T of
// the material in the tank, g does not. An entry measured with V_t ml in
// 23 l has c_t = V_t/23000; the four ocean waters were measured at natural
// concentration (c_t = 1). A tank of T litres holding V ml therefore has
//   σ = σ_t · (V/(1000·T)) / c_t,   β likewise.
// Mixtures (Eq. 4.9-4.10): coefficients add by volume, g is β-weighted:
//   β = Σ β_i,   σ = Σ σ_i,   g = Σ g_i β_i / β   (each i scaled by Eq. 4.8
// to its own volume in the tank); g = 0 where β = 0.
//
// Mono: the sim renders one channel; `channel` picks the RGB column.
//
// Threads: material_library() is built once (thread-safe static) and
// immutable; every function here is reentrant. Errors are returned, never
// thrown, and say what to change.
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

#include "procam/core/status.hpp"
#include "procam/hw/sim/scene.hpp"

namespace procam::sim {

enum class ColorChannel { red = 0, green = 1, blue = 2 };

// "red" / "green" / "blue" (also "r", "g", "b"); invalid_argument otherwise.
Result<ColorChannel> parse_color_channel(std::string_view name);

// One row of Table 4.1, units converted to 1/mm.
struct LibraryMaterial {
  std::string name;         // library name (pbrt's where it has the material), e.g. "Lowfat Milk"
  std::string thesis_name;  // as printed in the table, e.g. "Milk (lowfat)"
  std::string volume_text;  // as printed, e.g. "16ml", "5tsp"; "natural concentration"
  double volume_ml = 0;     // V_t in 23 l; 0 for natural-concentration entries
  std::array<double, 3> sigma_t_per_mm{};  // extinction σ, R G B, at the table dilution
  std::array<double, 3> sigma_s_per_mm{};  // scattering β
  std::array<double, 3> g{};               // H-G g; NaN where β = 0 (undefined)
  std::string check;                       // "agrees", "agrees_unscaled", "not_in_pbrt"
  // Volume fraction c_t of the table row: V_t/23000, or 1 (natural).
  double concentration() const { return volume_ml > 0 ? volume_ml / 23000.0 : 1.0; }
};

// The whole table, in the table's order. Never empty (the data is compiled in).
const std::vector<LibraryMaterial>& material_library();

// Case-insensitive lookup by name or thesis name ("merlot", "Wine (merlot)");
// the alias "milk" means "Lowfat Milk" (the thesis's milk). nullptr if unknown.
const LibraryMaterial* find_material(std::string_view name);

// One material of a mixture and its volume in the tank.
struct MixturePart {
  std::string name;
  double volume_ml = 0;
};

// A medium of `volume_ml` ml of `name` in a `tank_litres` litre tank (Eq. 4.8),
// column `channel`; β = 0 gives g = 0. invalid_argument for an unknown name
// (the message lists the names), volume_ml <= 0 or tank_litres <= 0, or a
// result outside the scene limits (σ > 10/mm).
Result<Medium> material_medium(std::string_view name, double volume_ml, double tank_litres, ColorChannel channel);

// Eq. 4.9-4.10 over `parts` (each with its own volume in the tank).
Result<Medium> mixture_medium(const std::vector<MixturePart>& parts, double tank_litres, ColorChannel channel);

// A mixture spelled as text: "milk + espresso 1:3" = parts in volume ratio
// 1:3 (no ratio: equal parts), `total_volume_ml` ml of the mixture in the tank.
// A single name is that material. invalid_argument on a malformed spec.
Result<std::vector<MixturePart>> parse_mixture_spec(std::string_view spec, double total_volume_ml);

}  // namespace procam::sim
