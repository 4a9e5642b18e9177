// Correctly rounded division and square root (common/shared/rounding.h) against the C++ host's
// double precision: for binary32 operands, a / b and sqrt(a) computed in binary64 and rounded to
// binary32 are the correctly rounded binary32 results (double rounding is innocuous when the
// wider format has at least 2p + 2 bits: 53 >= 2 * 24 + 2; Figueroa 1995), subnormal results
// included (binary64 holds every binary32 subnormal as a normal). The first approximation is
// perturbed by k ulps, as a device whose `/` or `sqrt` is off by k ulps would hand it over.
#include <catch2/catch.hpp>

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <string>

#include "gridrt/common/shared/rounding.h"

namespace sh = gridrt::shared;

namespace {

uint32_t bits(float f) { return std::bit_cast<uint32_t>(f); }
float from_bits(uint32_t u) { return std::bit_cast<float>(u); }
bool same(float a, float b) { return bits(a) == bits(b) || (std::isnan(a) && std::isnan(b)); }
std::string hex(float f) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "0x%08x (%a)", bits(f), double(f));
  return buf;
}
// x moved by k units in the last place (its bit pattern plus k; x positive and normal).
float nudge(float x, int k) { return from_bits(uint32_t(int64_t(bits(x)) + k)); }
float div_ref(float a, float b) { return float(double(a) / double(b)); }
float sqrt_ref(float a) { return float(std::sqrt(double(a))); }

// Random floats by kind: any bit pattern, near one, subnormal or zero, powers of two, small
// integers (exact quotients, halfway points), the extremes of the range.
struct Floats {
  std::mt19937 rng{20240917u};
  float operator()() {
    const uint32_t u = rng(), s = u & 0x80000000u;
    switch (rng() % 7u) {
      case 0: return from_bits(u);
      case 1: return from_bits(s | ((120u + rng() % 16u) << 23) | (u & 0x7FFFFFu));
      case 2: return from_bits(s | (u & 0x7FFFFFu) >> (rng() % 24u));
      case 3: return from_bits(s | ((rng() % 254u + 1u) << 23));
      case 4: return float(int(rng() % 4096u) - 2048);
      case 5: return from_bits(s | ((rng() % 2u ? 253u : 1u) + rng() % 2u) << 23 | (u & 0x7FFFFFu));
      default: return from_bits(s | (u & 0x7F800000u) | (rng() % 8u));  // short significands
    }
  }
};

}  // namespace

TEST_CASE("Correctly rounded division: special and edge cases", "[unit][rounding]") {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  const float denorm_min = std::numeric_limits<float>::denorm_min(), fmax = std::numeric_limits<float>::max();
  const float cases[] = {0.0f, -0.0f, 1.0f, -1.0f, 3.0f, 7.0f, 0.1f, inf, -inf, nan, denorm_min, -denorm_min,
                         fmax, -fmax, std::numeric_limits<float>::min(), 0x1p-127f, 0x1.fffffep-127f, 0x1p127f,
                         0x1p-126f, 1.5f, 0x1.000002p0f, 0x1.fffffep0f, 3e38f, 1e-38f};
  for (float a : cases)
    for (float b : cases) {
      INFO(hex(a) << " / " << hex(b));
      CHECK(same(sh::sh_div(a, b), div_ref(a, b)));
      CHECK(same(sh::sh_rcp(b), div_ref(1.0f, b)));
    }
  for (float a : cases) {
    INFO("sqrt " << hex(a));
    CHECK(same(sh::sh_sqrt(a), sqrt_ref(a)));
  }
  CHECK(bits(sh::sh_div(-0.0f, 5.0f)) == 0x80000000u);
  CHECK(bits(sh::sh_sqrt(-0.0f)) == 0x80000000u);
  CHECK(sh::sh_div(1.0f, 3e38f) == div_ref(1.0f, 3e38f));  // a subnormal quotient (NVIDIA's / gives 0)
  CHECK(sh::sh_div(1.0f, 3e38f) != 0.0f);
  // Halfway: the exact quotient lies between two floats; ties to even, in both directions
  CHECK(sh::sh_div(0x1.000003p0f, 2.0f) == 0x1.000004p-1f);
  CHECK(sh::sh_div(0x1.000001p-125f, 0x1p24f) == div_ref(0x1.000001p-125f, 0x1p24f));
}

TEST_CASE("Correctly rounded division: random operands, first approximation off by up to 4 ulps",
          "[unit][rounding]") {
  Floats rnd;
  size_t wrong = 0, halfway = 0, subnormal = 0, exact = 0, n = 0;
  const int kCases = 400000;
  for (int i = 0; i < kCases; ++i) {
    const float a = rnd(), b = rnd();
    const float want = div_ref(a, b);
    if (std::fpclassify(want) == FP_SUBNORMAL) ++subnormal;
    if (std::isfinite(want) && double(want) * double(b) == double(a)) ++exact;
    const double q = double(a) / double(b);
    if (std::isfinite(want) && q != double(want)) {
      const float other = std::nextafter(want, q > double(want) ? INFINITY : -INFINITY);
      if ((double(want) + double(other)) / 2.0 == q) ++halfway;
    }
    // The device's approximation of the significands' quotient, off by k ulps
    const float e = div_ref(sh::sh_significand(a), sh::sh_significand(b));
    for (int k = -4; k <= 4; ++k) {
      const float got = sh::sh_div_correct(a, b, nudge(e, k));
      ++n;
      if (!same(got, want) && wrong++ < 10) FAIL_CHECK(hex(a) << " / " << hex(b) << ", k = " << k << ": " << hex(got) << ", want " << hex(want));
    }
    if (!same(sh::sh_div(a, b), want) && wrong++ < 10) FAIL_CHECK(hex(a) << " / " << hex(b));
  }
  INFO(n << " quotients, " << exact << " exact, " << halfway << " halfway, " << subnormal << " subnormal");
  CHECK(wrong == 0);
  CHECK(exact > 1000);
  CHECK(halfway > 100);
  CHECK(subnormal > 1000);
}

TEST_CASE("Correctly rounded division: first approximation off by up to 64 ulps, or garbage",
          "[unit][rounding]") {
  Floats rnd;
  size_t wrong = 0;
  for (int i = 0; i < 20000; ++i) {
    const float a = rnd(), b = rnd(), want = div_ref(a, b);
    const float e = div_ref(sh::sh_significand(a), sh::sh_significand(b));
    for (int k : {-64, -33, -17, -8, 5, 9, 16, 40, 64})
      if (!same(sh::sh_div_correct(a, b, nudge(e, k)), want)) ++wrong;
    // Deterministic (no UB) for any first approximation
    const float garbage[] = {std::numeric_limits<float>::quiet_NaN(), -1.0f, 0.0f, 1e30f, 3.9f};
    for (float g : garbage) (void)sh::sh_div_correct(a, b, g);
  }
  CHECK(wrong == 0);
}

TEST_CASE("Correctly rounded square root: edge cases and random operands, approximation off by up to 4 ulps",
          "[unit][rounding]") {
  // Every significand near 1, 2 and 4 and every binade's first few values
  size_t wrong = 0;
  for (uint32_t e = 0; e < 255u; ++e)
    for (uint32_t m : {0u, 1u, 2u, 3u, 0x7FFFFFu, 0x7FFFFEu, 0x400000u, 0x3FFFFFu}) {
      const float a = from_bits(e << 23 | m);
      if (!same(sh::sh_sqrt(a), sqrt_ref(a)) && wrong++ < 10) FAIL_CHECK("sqrt " << hex(a));
    }
  // Perfect squares (exact roots)
  for (uint32_t s = 1; s < 4096u; ++s) {
    const float a = float(s * s) * 0x1p-40f;
    if (sh::sh_sqrt(a) != float(s) * 0x1p-20f && wrong++ < 10) FAIL_CHECK("sqrt " << hex(a));
  }
  Floats rnd;
  for (int i = 0; i < 400000; ++i) {
    const float a = std::fabs(rnd()), want = sqrt_ref(a);
    const float e = sqrt_ref(sh::sh_sqrt_significand(a));
    for (int k = -4; k <= 4; ++k) {
      const float got = sh::sh_sqrt_correct(a, nudge(e, k));
      if (!same(got, want) && wrong++ < 10) FAIL_CHECK("sqrt " << hex(a) << ", k = " << k << ": " << hex(got) << ", want " << hex(want));
    }
    for (int k : {-16, -9, 11, 16})
      if (!same(sh::sh_sqrt_correct(a, nudge(e, k)), want) && wrong++ < 10) FAIL_CHECK("sqrt " << hex(a) << ", k = " << k);
    if (!same(sh::sh_sqrt(-a), std::sqrt(-a)) && wrong++ < 10) FAIL_CHECK("sqrt " << hex(-a));
  }
  CHECK(wrong == 0);
}
