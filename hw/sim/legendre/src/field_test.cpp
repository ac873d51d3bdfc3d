// SPDX-License-Identifier: MIT
// L1 operators against closed forms and independent quadrature.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "procam/legendre/field.hpp"
#include "test_util.hpp"

namespace procam::legendre {
namespace {

using testing::box2;

TEST(LegendreBasis, ValuesMatchClosedForms) {
  for (double x : {-1.0, -0.3, 0.0, 0.7, 1.0}) {
    const auto p = legendre_values(x, 5);
    EXPECT_NEAR(p[2], 0.5 * (3 * x * x - 1), 1e-15);
    EXPECT_NEAR(p[3], 0.5 * (5 * x * x * x - 3 * x), 1e-15);
    EXPECT_NEAR(p[4], (35 * std::pow(x, 4) - 30 * x * x + 3) / 8, 1e-15);
  }
}

TEST(LegendreBasis, GaussLegendreIsExactToDegree2mMinus1) {
  for (size_t m : {1u, 2u, 5u, 12u, 30u}) {
    const Quadrature q = gauss_legendre(m);
    for (size_t p = 0; p < 2 * m; ++p) {
      double s = 0;
      for (size_t i = 0; i < m; ++i) s += q.weights[i] * std::pow(q.nodes[i], static_cast<double>(p));
      const double truth = p % 2 ? 0.0 : 2.0 / static_cast<double>(p + 1);
      EXPECT_NEAR(s, truth, 1e-13) << "m=" << m << " p=" << p;
    }
  }
  EXPECT_THROW(gauss_legendre(0), std::invalid_argument);
}

// Thesis Appendix A: the closed form equals exact quadrature, and the
// sparsity pattern of the quadrature values is exactly Theorem 1's.
TEST(LegendreTripleProduct, ClosedFormAndSparsityMatchQuadrature) {
  const size_t K = 16;
  const Quadrature q = gauss_legendre(2 * K);  // exact for degree 3(K-1)
  std::vector<std::vector<double>> p(q.nodes.size());
  for (size_t n = 0; n < q.nodes.size(); ++n) p[n] = legendre_values(q.nodes[n], K);
  size_t nonzero = 0;
  for (size_t i = 0; i < K; ++i)
    for (size_t j = 0; j < K; ++j)
      for (size_t k = 0; k < K; ++k) {
        double ti = 0;
        for (size_t n = 0; n < q.nodes.size(); ++n) ti += q.weights[n] * p[n][i] * p[n][j] * p[n][k];
        const bool allowed = (i + j + k) % 2 == 0 && k <= i + j && i <= j + k && j <= i + k;
        ASSERT_EQ(triple_product_allowed(i, j, k), allowed);
        if (allowed) {
          EXPECT_GT(ti, 1e-3) << i << "," << j << "," << k;  // every allowed entry is nonzero
          ++nonzero;
        } else {
          EXPECT_LT(std::fabs(ti), 1e-13) << i << "," << j << "," << k;  // every predicted zero is zero
        }
        EXPECT_NEAR(triple_product(i, j, k), ti, 1e-13 * std::max(1.0, std::fabs(ti)));
      }
  // Result 1: nonzero count <= ceil(K^3/4 + 3K^2/8 + K/4), i.e. ~1/4.
  const double kd = static_cast<double>(K);
  EXPECT_LE(static_cast<double>(nonzero), std::ceil(kd * kd * kd / 4 + 3 * kd * kd / 8 + kd / 4));
  EXPECT_EQ(triple_product_entries(K, K, K).size(), nonzero);
}

TEST(LegendreField, DerivativeOfPolynomialIsExact) {
  // f = x^5 - 3 x^2 y^3 + 2 y on [0, 2] x [-1, 3].
  const Box b = box2(0, 2, -1, 3);
  auto f = [](double x, double y, double) { return std::pow(x, 5) - 3 * x * x * y * y * y + 2 * y; };
  const Field F = project(f, cube_shape(2, 7), b, 8);
  const Field Fx = derivative(F, 0), Fy = derivative(F, 1);
  const Field Fxy = derivative(Fx, 1);
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> ux(0, 2), uy(-1, 3);
  for (int t = 0; t < 50; ++t) {
    const double x = ux(rng), y = uy(rng);
    EXPECT_NEAR(evaluate(F, {x, y, 0}), f(x, y, 0), 1e-12 * 200);
    EXPECT_NEAR(evaluate(Fx, {x, y, 0}), 5 * std::pow(x, 4) - 6 * x * y * y * y, 1e-12 * 500);
    EXPECT_NEAR(evaluate(Fy, {x, y, 0}), -9 * x * x * y * y + 2, 1e-12 * 500);
    EXPECT_NEAR(evaluate(Fxy, {x, y, 0}), -18 * x * y * y, 1e-12 * 500);
  }
}

TEST(LegendreField, IntegralAndDerivativeRoundTrip) {
  const Box b = box2(-0.5, 1.5, 0, 1);
  auto f = [](double x, double y, double) { return std::exp(x) * std::cos(2 * y); };
  const Field F = project(f, cube_shape(2, 9), b, 20);
  // d/dx int_lo^x f = f exactly (int adds one coefficient, D removes it).
  const Field back = truncate(derivative(integral(F, 0), 0), F.n);
  for (size_t i = 0; i < F.size(); ++i) EXPECT_NEAR(back.c[i], F.c[i], 1e-12);
  EXPECT_LT(std::fabs(derivative(integral(F, 0), 0).at(9, 0)), 1e-12);
  // int_lo^x f' = f(x) - f(lo).
  const Field again = integral(derivative(F, 0), 0);
  for (double x : {-0.5, 0.1, 0.9, 1.5})
    for (double y : {0.0, 0.4, 1.0})
      EXPECT_NEAR(evaluate(again, {x, y, 0}), evaluate(F, {x, y, 0}) - evaluate(F, {-0.5, y, 0}), 1e-12);
}

// Product through TI vs pointwise multiplication on a fine grid.
TEST(LegendreField, ProductMatchesPointwiseMultiplication) {
  Box b;
  b.lo = {0, -1, 2};
  b.hi = {1, 2, 3};
  for (size_t d : {1u, 2u, 3u}) {
    const size_t n = d == 3 ? 5 : 10;
    const Field F = project([](double x, double y, double z) { return std::sin(3 * x + y) + z; }, cube_shape(d, n), b, 16);
    const Field G = project([](double x, double y, double z) { return std::exp(-x * y) * z; }, cube_shape(d, n), b, 16);
    Shape full{};
    for (size_t a = 0; a < 3; ++a) full[a] = F.n[a] + G.n[a] - 1;
    const Field H = product(F, G, full);
    const Shape grid = cube_shape(d, 33);
    const auto fv = evaluate_grid(F, grid), gv = evaluate_grid(G, grid), hv = evaluate_grid(H, grid);
    for (size_t i = 0; i < hv.size(); ++i) ASSERT_NEAR(hv[i], fv[i] * gv[i], 1e-12) << "d=" << d << " i=" << i;
    // The L2-truncated product equals the projection of the exact product.
    const Field Ht = product(F, G, F.n);
    const Field Hp = truncate(H, F.n);
    for (size_t i = 0; i < Ht.size(); ++i) ASSERT_NEAR(Ht.c[i], Hp.c[i], 1e-13);
    // The multiplication matrix M^G gives the same product (Eq. 6.10).
    const Field Hm = apply(product_matrix(G, F.n, full), F, full);
    for (size_t i = 0; i < H.size(); ++i) ASSERT_NEAR(Hm.c[i], H.c[i], 1e-13);
  }
}

// Appendix B: truncating x^n to degree n-1 gives the mini-max polynomial,
// whose maximum deviation is exactly 2^{1-n}.
TEST(LegendreTruncation, ChebyshevGivesMinimaxForMonomials) {
  for (size_t deg : {3u, 6u, 11u}) {
    const Box b;
    const Field F = project([&](double x, double, double) { return std::pow(x, static_cast<double>(deg)); },
                            cube_shape(1, deg + 1), b, deg + 2);
    const Field T = truncate(F, cube_shape(1, deg), Truncation::kChebyshev);
    double worst = 0;
    for (int i = 0; i <= 4000; ++i) {
      const double x = -1 + i / 2000.0;
      worst = std::max(worst, std::fabs(evaluate(T, {x, 0, 0}) - std::pow(x, static_cast<double>(deg))));
    }
    EXPECT_NEAR(worst, std::pow(2.0, 1.0 - static_cast<double>(deg)), 1e-12) << deg;
  }
}

TEST(LegendreTruncation, ChebyshevBeatsL2InMaxNormAndKeepsLowDegree) {
  const Box b;
  // x^31 to degree 15 (thesis Fig. 6.20).
  const Field F = project([](double x, double, double) { return std::pow(x, 31); }, cube_shape(1, 32), b, 40);
  const Field C = truncate(F, cube_shape(1, 16), Truncation::kChebyshev);
  const Field L = truncate(F, cube_shape(1, 16), Truncation::kL2);
  double ec = 0, el = 0;
  for (int i = 0; i <= 4000; ++i) {
    const double x = -1 + i / 2000.0, t = std::pow(x, 31);
    ec = std::max(ec, std::fabs(evaluate(C, {x, 0, 0}) - t));
    el = std::max(el, std::fabs(evaluate(L, {x, 0, 0}) - t));
  }
  EXPECT_LT(ec, el);
  EXPECT_LT(ec, 0.2);
  // A polynomial already of low degree passes unchanged.
  const Matrix T = chebyshev_truncation_matrix(6, 12);
  for (size_t k = 0; k < 6; ++k)
    for (size_t i = 0; i < 6; ++i) EXPECT_NEAR(T(k, i), k == i ? 1.0 : 0.0, 1e-13);
  EXPECT_THROW(chebyshev_truncation_matrix(7, 6), std::invalid_argument);
}

TEST(LegendreField, GridEvaluationAndProjection) {
  const Box b = box2(0, 4, 0, 2);
  auto f = [](double x, double y, double) { return 1 + 0.3 * x - 0.1 * x * y + 0.05 * y * y; };
  const Field F = project(f, cube_shape(2, 4), b, 6);
  const Shape g{40, 20, 1};
  const auto v = evaluate_grid(F, g);
  for (size_t y = 0; y < 20; ++y)
    for (size_t x = 0; x < 40; ++x) {
      const double px = (static_cast<double>(x) + 0.5) * 0.1, py = (static_cast<double>(y) + 0.5) * 0.1;
      ASSERT_NEAR(v[y * 40 + x], f(px, py, 0), 1e-13);
    }
  // Midpoint-rule projection: O(h^2). Error per coefficient at 40x20 cells,
  // then at twice the resolution: at least 3.5x smaller.
  const Field P = project_grid(v, g, F.n, b);
  const Shape g2{80, 40, 1};
  const Field P2 = project_grid(evaluate_grid(F, g2), g2, F.n, b);
  double e1 = 0, e2 = 0;
  for (size_t i = 0; i < F.size(); ++i) {
    e1 = std::max(e1, std::fabs(P.c[i] - F.c[i]));
    e2 = std::max(e2, std::fabs(P2.c[i] - F.c[i]));
  }
  EXPECT_LT(e1, 1e-2);
  EXPECT_LT(e2 * 3.5, e1);
  // Parseval: int f^2 over the box.
  double s = 0;
  for (double q : v) s += q * q * 0.01;
  EXPECT_NEAR(squared_norm(F), s, 1e-3 * s);
}

TEST(LegendreField, ErrorsNameTheProblem) {
  const Field a = zero_field(2, 4, Box{}), c = zero_field(2, 5, Box{});
  Field x = a;
  EXPECT_THROW(axpy(x, 1.0, c), std::invalid_argument);
  EXPECT_THROW(Field(Shape{3, 3, 3}, Box{}, 2), std::invalid_argument);
  EXPECT_THROW(Field(Shape{0, 3, 1}, Box{}, 2), std::invalid_argument);
}

}  // namespace
}  // namespace procam::legendre
