// SPDX-License-Identifier: MIT
// Shared helpers of the procam::legendre tests.
#pragma once

#include "procam/legendre/field.hpp"

namespace procam::legendre::testing {

// A 2D box [x0, x1] x [y0, y1] (z unused).
inline Box box2(double x0, double x1, double y0, double y1) {
  Box b;
  b.lo = {x0, y0, 0.0};
  b.hi = {x1, y1, 1.0};
  return b;
}

}  // namespace procam::legendre::testing
