#include "vdrig/core/sh_basis.hpp"

#include <array>

#include "vdrig/core/result.hpp"

namespace vdrig {
namespace {

// Coefficients of the normalised recurrence, precomputed for l, m < kMaxShBands.
struct Recurrence {
  std::array<double, kMaxShBands> diag{};
  std::array<std::array<double, kMaxShBands>, kMaxShBands> a{};
  std::array<std::array<double, kMaxShBands>, kMaxShBands> b{};

  Recurrence() {
    diag[0] = 1.0 / std::sqrt(4.0 * kPi);
    for (int m = 1; m < kMaxShBands; ++m) diag[m] = -std::sqrt((2.0 * m + 1.0) / (2.0 * m)) * diag[m - 1];
    for (int m = 0; m < kMaxShBands; ++m) {
      for (int l = m + 1; l < kMaxShBands; ++l) {
        const double l2 = double(l) * l, m2 = double(m) * m, lm1 = l - 1.0;
        a[l][m] = std::sqrt((4.0 * l2 - 1.0) / (l2 - m2));
        b[l][m] = std::sqrt((lm1 * lm1 - m2) / (4.0 * lm1 * lm1 - 1.0));  // 0 for l = m + 1
      }
    }
  }
};

const Recurrence& recurrence() {
  static const Recurrence r;
  return r;
}

void check_lm(int l, int m) {
  VDRIG_CHECK(m >= 0 && m < l && l < kMaxShBands, "sh recurrence: need 0 <= m < l < kMaxShBands");
}

}  // namespace

double sh_recurrence_diag(int m) {
  VDRIG_CHECK(m >= 0 && m < kMaxShBands, "sh recurrence: m out of range");
  return recurrence().diag[m];
}

double sh_recurrence_a(int l, int m) {
  check_lm(l, m);
  return recurrence().a[l][m];
}

double sh_recurrence_b(int l, int m) {
  check_lm(l, m);
  return recurrence().b[l][m];
}

void sh_basis(int bands, const Vec3d& dir, double* out) {
  VDRIG_CHECK(bands >= 1 && bands <= kMaxShBands, "sh_basis: bands out of range");
  const Recurrence& r = recurrence();
  const double x = dir.x(), y = dir.y(), z = dir.z();
  constexpr double kSqrt2 = 1.41421356237309504880;
  double re = 1.0, im = 0.0;  // (x + i y)^m = sin^m(zenith) (cos, sin)(m azimuth)
  for (int m = 0; m < bands; ++m) {
    // Q_l^m for l = m .. bands - 1 by the upward recurrence in l.
    double q_prev2 = 0.0;
    double q_prev = r.diag[m];
    for (int l = m; l < bands; ++l) {
      double q = q_prev;
      if (l > m) {
        q = r.a[l][m] * (z * q_prev - r.b[l][m] * q_prev2);
        q_prev2 = q_prev;
        q_prev = q;
      }
      if (m == 0) {
        out[sh_index(l, 0)] = q;
      } else {
        out[sh_index(l, m)] = kSqrt2 * q * re;
        out[sh_index(l, -m)] = kSqrt2 * q * im;
      }
    }
    const double re_next = re * x - im * y;
    im = re * y + im * x;
    re = re_next;
  }
}

}  // namespace vdrig
