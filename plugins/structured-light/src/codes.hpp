// SPDX-License-Identifier: MIT
// The projected column codes of the structured-light plugin (thesis §3.2–3.3,
// docs/techniques.md C1–C3) as ProjectedCode: a StripeCode over *code indices* plus
// the map between projector coordinates and code indices.
//
// - "gray": binary-reflected Gray code, ceil(log2 W) planes (C1), identity map.
// - "xor02" / "xor04" (§3.3.1, Eq. 3.6–3.8): the Gray code with the plane of
//   stripe width 2 (bit 0) resp. 4 (bit 1) as the *base*; every more
//   significant plane is projected as (Gray plane XOR base). Planes at or below
//   the base are projected unchanged, so no projected plane has stripes wider
//   than the base (XOR-04's bit 0 stays the width-2 Gray plane: XOR-ing it with
//   the base would make width-1 stripes). Decoding XORs each binarized plane
//   with the binarized base — done here by the lookup table itself: the
//   projected word of column c is w(c) = g(c) ^ (base(c) ? high_mask : 0), a
//   bijection, so StripeCode::decode(w) returns c directly.
// - "minsw" (§3.3.2): the 10-bit max-min-SW Gray code (min stripe width 8,
//   Goddyn & Gvozdjak 2003), 1024 code columns. Projectors wider than 1024
//   columns use *stretched code columns*: projector column x shows code column
//   k(x) = floor(x * 1024 / W); a decoded k maps back to the centre of its span
//   of projector columns. Spans are floor or ceil of W/1024 columns, so for
//   W <= 2048 the quantization error is <= 0.5 px (inside the 1-column
//   tolerance the ensemble votes with) and stripes only get wider (>= 8 px,
//   about 8*W/1024). Narrower projectors use the first W words unchanged.
//   See README "W > 1024" for the trade-off against an 11-bit extension.
// Thread-safety: immutable values.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "stripe_code.hpp"

namespace procam::sl {

struct ProjectedCode {
  std::string id;                  // "gray", "xor02", "xor04", "minsw"
  StripeCode code;                 // over code indices 0..code.length-1
  std::vector<uint32_t> index_of;  // per projector coordinate: its code index
  std::vector<float> coord_of;     // per code index: projector coordinate (span centre)
  uint32_t max_span = 1;           // most projector coordinates sharing one code index

  uint32_t length() const { return static_cast<uint32_t>(index_of.size()); }
  uint32_t bits() const { return code.bits; }
  // Value of plane p (0 = first projected) at projector coordinate x.
  bool bit(uint32_t plane, uint32_t x) const { return code.bit(plane, index_of[x]); }
};

// Code ids understood by make_projected_code, in the ensemble's vote order.
inline constexpr const char* kCodeIds[] = {"gray", "xor02", "xor04", "minsw"};

// Builds code `id` over `length` projector coordinates (1..65536). Throws
// std::invalid_argument for an unknown id or length (xor02 needs length >= 4
// and xor04 length >= 8 so that the base plane exists).
ProjectedCode make_projected_code(const std::string& id, uint32_t length);

// Longest and shortest run of equal values of plane p over projector
// coordinates [0, length), not counting the two runs touching the edges
// (they are cut by the image border). Returns {0, 0} when there are fewer
// than three runs. Used by tests and the report ("min-SW").
struct RunLengths { uint32_t min_run = 0, max_run = 0; };
RunLengths interior_runs(const ProjectedCode& code, uint32_t plane);

}  // namespace procam::sl
