// SPDX-License-Identifier: MIT
// Small fixed-size geometry (header-only, usable from plugins): Vec3, Mat3 and
// rigid transforms named `b_from_a` (x_b = R * x_a + t). Units: millimetres.
#pragma once

#include <array>
#include <cmath>

namespace procam {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  constexpr Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
  constexpr Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
  constexpr Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
  constexpr Vec3 operator/(double s) const { return {x / s, y / s, z / s}; }
  constexpr Vec3 operator-() const { return {-x, -y, -z}; }
  constexpr double operator[](int i) const { return i == 0 ? x : i == 1 ? y : z; }
};
constexpr double dot(const Vec3& a, const Vec3& b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
constexpr Vec3 cross(const Vec3& a, const Vec3& b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double norm(const Vec3& a) { return std::sqrt(dot(a, a)); }
inline Vec3 normalized(const Vec3& a) {
  double n = norm(a);
  return n > 0 ? a / n : a;
}

// Row-major 3x3.
struct Mat3 {
  std::array<double, 9> m{1, 0, 0, 0, 1, 0, 0, 0, 1};
  constexpr double operator()(int r, int c) const { return m[static_cast<size_t>(r * 3 + c)]; }
  constexpr double& operator()(int r, int c) { return m[static_cast<size_t>(r * 3 + c)]; }
  constexpr Vec3 operator*(const Vec3& v) const {
    return {m[0] * v.x + m[1] * v.y + m[2] * v.z, m[3] * v.x + m[4] * v.y + m[5] * v.z,
            m[6] * v.x + m[7] * v.y + m[8] * v.z};
  }
  constexpr Mat3 operator*(const Mat3& o) const {
    Mat3 r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        r(i, j) = (*this)(i, 0) * o(0, j) + (*this)(i, 1) * o(1, j) + (*this)(i, 2) * o(2, j);
    return r;
  }
  constexpr Mat3 transposed() const {
    Mat3 r;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) r(i, j) = (*this)(j, i);
    return r;
  }
  static constexpr Mat3 identity() { return {}; }
};

// Rotation from XYZ Euler angles in degrees: R = Rz * Ry * Rx.
inline Mat3 rotation_from_euler_deg(double rx, double ry, double rz) {
  const double d = M_PI / 180.0;
  const double cx = std::cos(rx * d), sx = std::sin(rx * d);
  const double cy = std::cos(ry * d), sy = std::sin(ry * d);
  const double cz = std::cos(rz * d), sz = std::sin(rz * d);
  Mat3 Rx{{1, 0, 0, 0, cx, -sx, 0, sx, cx}};
  Mat3 Ry{{cy, 0, sy, 0, 1, 0, -sy, 0, cy}};
  Mat3 Rz{{cz, -sz, 0, sz, cz, 0, 0, 0, 1}};
  return Rz * Ry * Rx;
}

// Rigid transform b_from_a: x_b = rotation * x_a + translation_mm.
struct Rigid3 {
  Mat3 rotation;
  Vec3 translation_mm;
  constexpr Vec3 operator*(const Vec3& x) const { return rotation * x + translation_mm; }
  constexpr Rigid3 inverse() const {
    Mat3 rt = rotation.transposed();
    return {rt, -(rt * translation_mm)};
  }
  // c_from_a = c_from_b * b_from_a
  constexpr Rigid3 operator*(const Rigid3& b_from_a) const {
    return {rotation * b_from_a.rotation, rotation * b_from_a.translation_mm + translation_mm};
  }
};

}  // namespace procam
