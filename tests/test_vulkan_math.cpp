// test_vulkan_math.cpp: the shared math (common/shared/{compat,transform,alpha}.h) compiled as
// GLSL and run on the device agrees bit for bit with the same functions compiled as C++, on
// thousands of random inputs including denormals, huge and tiny values (Falcor style: a kernel
// and its CPU twin; every mismatch prints its index, its inputs and both results as hex bits).
#include <algorithm>
#include <random>
#include <sstream>
#include <vector>

#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
#endif

#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/rounding.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/shared/transform.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/pipeline.h"

using namespace gridrt;
using namespace gridrt::test;
namespace sh = gridrt::shared;

namespace {

constexpr uint32_t kInStride = 28;   // as test_shared_math.comp
constexpr uint32_t kOutStride = 16;

// Random floats by kind: ordinary, huge, tiny normal, denormal, signed zero, small integers,
// near one. `finite_only` keeps to values whose products with [0, 4096] stay finite.
class FloatSource {
 public:
  explicit FloatSource(uint32_t seed) : rng_(seed) {}

  float any(int kind) {
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    const float sign = (rng_() & 1u) ? -1.0f : 1.0f;
    switch (kind) {
      case 0: return std::uniform_real_distribution<float>(-10.0f, 10.0f)(rng_);
      case 1: return sign * std::pow(10.0f, 30.0f + 8.5f * u01(rng_));   // 1e30 .. 3e38
      case 2: return sign * std::pow(10.0f, -37.9f + 7.9f * u01(rng_));  // 1.2e-38 .. 1e-30
      case 3: return from_bits((rng_() & 0x007FFFFFu) | 1u) * sign;      // denormal
      case 4: return sign * 0.0f;
      case 5: return float(int(rng_() % 9u) - 4);
      default: return 1.0f + sign * std::ldexp(float(rng_() % 64u), -23);
    }
  }
  int kind() { return int(rng_() % 7u); }
  // Mostly one kind for a whole group of inputs (so that e.g. all-denormal cases occur), else mixed.
  float next(int group_kind) { return (rng_() % 4u) ? any(group_kind) : any(kind()); }
  uint32_t size() { return 1u + rng_() % 4096u; }

 private:
  std::mt19937 rng_;
};

std::vector<float> make_inputs(uint32_t count, uint32_t seed) {
  FloatSource src(seed);
  std::vector<float> in(size_t(count) * kInStride, 0.0f);
  for (uint32_t i = 0; i < count; ++i) {
    float* c = &in[size_t(i) * kInStride];
    const int k = src.kind();
    for (int j = 0; j < 23; ++j) c[j] = src.next(k);
    // alpha_texel_coords: uv finite and width, height in [1, 4096] (as uint bits).
    c[23] = src.next(k);
    c[24] = src.next(k);
    c[25] = from_bits(src.size());
    c[26] = from_bits(src.size());
  }
  return in;
}

// The C++ twin of test_shared_math.comp.
void evaluate(const float* c, uint32_t* o) {
  const glm::vec3 a(c[0], c[1], c[2]), b(c[3], c[4], c[5]);
  o[0] = bits(sh::sh_dot(a, b));
  const glm::vec3 x = sh::sh_cross(a, b);
  o[1] = bits(x.x), o[2] = bits(x.y), o[3] = bits(x.z);
  const sh::Affine m{glm::vec4(c[0], c[1], c[2], c[3]), glm::vec4(c[4], c[5], c[6], c[7]),
                     glm::vec4(c[8], c[9], c[10], c[11])};
  const glm::vec3 p = sh::transform_point(m, glm::vec3(c[12], c[13], c[14]));
  o[4] = bits(p.x), o[5] = bits(p.y), o[6] = bits(p.z);
  const glm::vec2 uv = sh::interpolate_uv(glm::vec2(c[15], c[16]), glm::vec2(c[17], c[18]), glm::vec2(c[19], c[20]),
                                          c[21], c[22]);
  o[7] = bits(uv.x), o[8] = bits(uv.y);
  const glm::uvec2 t = sh::alpha_texel_coords(glm::vec2(c[23], c[24]), bits(c[25]), bits(c[26]));
  o[9] = t.x, o[10] = t.y;
  o[11] = bits(sh::sh_div(c[0], c[3]));
  o[12] = bits(sh::sh_rcp(c[1]));
  o[13] = bits(sh::sh_sqrt(std::fabs(c[2])));
  o[14] = bits(std::floor(c[4]));
  o[15] = 0;
}

const char* kResultNames[kOutStride] = {"sh_dot", "sh_cross.x", "sh_cross.y", "sh_cross.z",
                                        "transform_point.x", "transform_point.y", "transform_point.z",
                                        "interpolate_uv.x", "interpolate_uv.y", "alpha_texel_coords.x",
                                        "alpha_texel_coords.y", "sh_div(a.x, b.x)", "sh_rcp(a.y)", "sh_sqrt(|a.z|)",
                                        "floor(b.y)", "pad"};

bool is_denormal(float f) { return f != 0.0f && std::fpclassify(f) == FP_SUBNORMAL; }

// evaluate() as a device that flushes denormals computes it: FTZ and DAZ set (x86), so that a
// denormal input, intermediate or result becomes zero. Elsewhere the same as evaluate().
void evaluate_flushing(const float* c, uint32_t* o) {
#if defined(__x86_64__) || defined(__i386__)
  const unsigned saved = _mm_getcsr();
  _mm_setcsr(saved | 0x8040u);
  evaluate(c, o);
  _mm_setcsr(saved);
#else
  evaluate(c, o);
#endif
}

}  // namespace

TEST_CASE("Shared math: the GLSL build agrees with the C++ build bit for bit", "[vulkan][diff][math]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  constexpr uint32_t kCount = 20000;
  const std::vector<float> in = make_inputs(kCount, 12345u);

  vulkan::Buffer in_buf = ctx.create_buffer(in.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  vulkan::Buffer out_buf = ctx.create_buffer(size_t(kCount) * kOutStride * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  ctx.upload(in_buf, std::span<const float>(in));
  vulkan::Descriptors set(ctx, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER},
                          VK_SHADER_STAGE_COMPUTE_BIT);
  set.bind(0, in_buf);
  set.bind(1, out_buf);
  vulkan::Pipeline pipe(ctx, "test_shared_math.comp", set.layout(), sizeof(uint32_t));
  ctx.submit([&](VkCommandBuffer cb) {
    pipe.bind(cb, set.set());
    pipe.push(cb, kCount);
    vulkan::vkCmdDispatch(cb, vulkan::groups(kCount, 64), 1, 1);
  });
  const std::vector<uint32_t> gpu = ctx.download<uint32_t>(out_buf, size_t(kCount) * kOutStride);

  // Denormals are held to the bit where the device promises to keep them
  // (shaderDenormPreserveFloat32) and on lavapipe, which keeps them without promising it
  // (docs/VULKAN.md). Elsewhere a case with a denormal input or result may differ (flush to
  // zero; the C++ twin run with FTZ/DAZ tells an intermediate denormal): counted and reported,
  // not failed. Everything else to the bit on every device: + - * are correctly rounded, and
  // sh_div, sh_rcp and sh_sqrt (rounding.h) are by construction.
  const bool preserve = ctx.info().denorm_preserve_f32;
  const bool strict = preserve || bit_exact_device(ctx);
  size_t mismatches = 0, flushed = 0, denormal_results = 0;
  std::ostringstream report;
  for (uint32_t i = 0; i < kCount; ++i) {
    const float* c = &in[size_t(i) * kInStride];
    uint32_t cpu[kOutStride], cpu_ftz[kOutStride];
    evaluate(c, cpu);
    evaluate_flushing(c, cpu_ftz);
    for (uint32_t k = 0; k < kOutStride; ++k) {
      const uint32_t g = gpu[size_t(i) * kOutStride + k];
      const bool is_float = k < 9 || (k >= 11 && k < 15);
      if (is_float && is_denormal(from_bits(cpu[k]))) ++denormal_results;
      if (is_float ? same_float(g, cpu[k]) : g == cpu[k]) continue;
      const bool denormal_case =
          g == cpu_ftz[k] || (is_float && (is_denormal(from_bits(cpu[k])) ||
                                           std::any_of(c, c + 23, [](float f) { return is_denormal(f); })));
      if (!strict && denormal_case) {
        ++flushed;
        continue;
      }
      if (++mismatches <= 8) {
        report << "case " << i << ", " << kResultNames[k] << ": gpu " << (is_float ? hex(from_bits(g)) : hex(g))
               << ", cpu " << (is_float ? hex(from_bits(cpu[k])) : hex(cpu[k])) << "\n  inputs:";
        for (uint32_t j = 0; j < kInStride; ++j) report << (j % 4 ? " " : "\n    ") << hex(c[j]);
        report << "\n";
      }
    }
  }
  INFO(report.str());
  INFO("denormal results on the CPU: " << denormal_results << ", flushed on the device: " << flushed
                                       << " (shaderDenormPreserveFloat32 = " << preserve << ")");
  CHECK(denormal_results > 100);  // the inputs do exercise denormals
  CHECK(mismatches == 0);
  if (!strict && flushed) WARN(flushed << " results differ in cases with denormals (no shaderDenormPreserveFloat32)");
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Shared math: `precise` survives into SPIR-V as NoContraction, no Fma", "[vulkan][unit][math]") {
  for (const char* name : {"test_shared_math.comp", "test_raster.vert"}) {
    const vulkan::SpirvFacts f = vulkan::inspect_spirv(vulkan::shader_spirv(name));
    INFO(name);
    CHECK(f.no_contraction > 0);
    CHECK(f.fma == 0);
  }
}

namespace {

constexpr uint32_t kGridInStride = 20;  // as test_grid_math.comp
constexpr uint32_t kGridOutStride = 24;
const char* kGridMathNames[kGridOutStride] = {
    "dot(dir, dir)", "sh_sqrt", "sh_div(cell_size, len)", "cell_size / len (the built-in, for comparison)", "clip t0", "clip t1",
    "clipped | meets << 1", "rs.seg_t", "rs.t_start", "rs.t_end", "rs.t_lo", "moller_trumbore code", "det",
    "u*|det|", "v*|det|", "t*|det|", "t_lo*|det|", "t_hi*|det|", "moller_trumbore_t", "cramer u", "cramer v",
    "1/dir.x", "1/dir.y", "1/dir.z"};
bool grid_math_is_float(uint32_t k) { return k != 6 && k != 11; }

void grid_math_cpu(const sh::GridParams& g, const float* c, uint32_t* o) {
  const glm::vec3 org(c[0], c[1], c[2]), dir(c[4], c[5], c[6]), v0(c[8], c[9], c[10]), v1(c[11], c[12], c[13]),
      v2(c[14], c[15], c[16]);
  const float tmin = c[3], tmax = c[7];
  const float dd = sh::sh_dot(dir, dir);
  const float len = sh::sh_sqrt(dd);
  o[0] = bits(dd), o[1] = bits(len), o[2] = bits(sh::sh_div(g.cell_size, len)), o[3] = bits(g.cell_size / len);
  float t0, t1;
  const bool clipped = sh::clip_to_grid(g, org, dir, t0, t1);
  sh::RaySetup rs;
  const bool meets = sh::ray_setup(g, org, dir, tmin, tmax, rs);
  o[4] = bits(t0), o[5] = bits(t1), o[6] = (clipped ? 1u : 0u) | (meets ? 2u : 0u);
  o[7] = bits(rs.seg_t), o[8] = bits(rs.t_start), o[9] = bits(rs.t_end), o[10] = bits(rs.t_lo);
  sh::TriangleTest r;
  const uint32_t code = sh::moller_trumbore(org, dir, v0, v1, v2, tmin, tmax, sh::sh_infinity(), r);
  o[11] = code, o[12] = bits(r.det), o[13] = bits(r.u_det), o[14] = bits(r.v_det), o[15] = bits(r.t_det);
  o[16] = bits(r.lo_det), o[17] = bits(r.hi_det);
  const float t = code == sh::kTestAccepted ? sh::moller_trumbore_t(r) : 0.0f;
  o[18] = bits(t);
  const glm::vec2 bc = sh::cramer_barycentrics(v0, v1, v2, sh::point_at(org, dir, t));
  o[19] = bits(bc.x), o[20] = bits(bc.y);
  const glm::vec3 inv = sh::dda_inverse_direction(dir);
  o[21] = bits(inv.x), o[22] = bits(inv.y), o[23] = bits(inv.z);
}


}  // namespace

TEST_CASE("Shared grid math: ray setup, Moller-Trumbore, Cramer, DDA inverse, GLSL == C++", "[vulkan][diff][math]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  // A grid like the tests' (10^3 cells over [-3.3, 15.4]^3) and rays aimed at random triangles
  sh::GridParams g{};
  g.origin = glm::vec3(-3.30897141f);
  g.cell_size = 1.86734235f;
  g.inv_cell_size = 1.0f / g.cell_size;
  g.cells = glm::uvec3(10u);
  g.upper = g.origin + glm::vec3(g.cells) * g.cell_size;
  g.self_hit_offset = 0.0f;
  constexpr uint32_t kCount = 20000;
  std::mt19937 rng(99);
  std::uniform_real_distribution<float> p(-2.0f, 14.0f), e(-1.5f, 1.5f), w(0.0f, 1.0f), s(0.05f, 3.0f);
  std::vector<float> in(size_t(kCount) * kGridInStride, 0.0f);
  for (uint32_t i = 0; i < kCount; ++i) {
    float* c = &in[size_t(i) * kGridInStride];
    const glm::vec3 v0(p(rng), p(rng), p(rng)), v1 = v0 + glm::vec3(e(rng), e(rng), e(rng)),
                    v2 = v0 + glm::vec3(e(rng), e(rng), e(rng));
    float a = w(rng), b = w(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    const glm::vec3 target = v0 + a * (v1 - v0) + b * (v2 - v0), org(p(rng), p(rng), p(rng));
    const glm::vec3 dir = (target - org) * s(rng);
    const float vals[17] = {org.x, org.y, org.z, 0.0f, dir.x, dir.y, dir.z, (i % 4) ? INFINITY : 0.7f,
                            v0.x, v0.y, v0.z, v1.x, v1.y, v1.z, v2.x, v2.y, v2.z};
    std::copy(vals, vals + 17, c);
  }
  vulkan::Buffer params = ctx.create_buffer(sizeof g, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  vulkan::Buffer in_buf = ctx.create_buffer(in.size() * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  vulkan::Buffer out_buf = ctx.create_buffer(size_t(kCount) * kGridOutStride * 4, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  ctx.upload(params, &g, sizeof g);
  ctx.upload(in_buf, std::span<const float>(in));
  vulkan::Descriptors set(ctx, {VK_DESCRIPTOR_TYPE_STORAGE_BUFFER, VK_DESCRIPTOR_TYPE_STORAGE_BUFFER,
                                VK_DESCRIPTOR_TYPE_STORAGE_BUFFER}, VK_SHADER_STAGE_COMPUTE_BIT);
  set.bind(0, params);
  set.bind(1, in_buf);
  set.bind(2, out_buf);
  vulkan::Pipeline pipe(ctx, "test_grid_math.comp", set.layout(), sizeof(uint32_t));
  ctx.submit([&](VkCommandBuffer cb) {
    pipe.bind(cb, set.set());
    pipe.push(cb, kCount);
    vulkan::vkCmdDispatch(cb, vulkan::groups(kCount, 64), 1, 1);
  });
  const std::vector<uint32_t> gpu = ctx.download<uint32_t>(out_buf, size_t(kCount) * kGridOutStride);

  // Per value: how many differ, the largest distance in ulps, the first case
  std::vector<size_t> differ(kGridOutStride, 0), first(kGridOutStride, 0);
  std::vector<uint64_t> worst(kGridOutStride, 0);
  size_t accepted = 0;
  for (uint32_t i = 0; i < kCount; ++i) {
    uint32_t cpu[kGridOutStride];
    grid_math_cpu(g, &in[size_t(i) * kGridInStride], cpu);
    accepted += cpu[11] == sh::kTestAccepted;
    for (uint32_t k = 0; k < kGridOutStride; ++k) {
      const uint32_t v = gpu[size_t(i) * kGridOutStride + k];
      if (grid_math_is_float(k) ? same_float(v, cpu[k]) : v == cpu[k]) continue;
      if (differ[k]++ == 0) first[k] = i;
      worst[k] = std::max<uint64_t>(worst[k], grid_math_is_float(k) ? ulp_distance(v, cpu[k]) : ~uint64_t(0));
    }
  }
  std::ostringstream table;
  size_t total = 0;
  for (uint32_t k = 0; k < kGridOutStride; ++k) {
    total += differ[k];
    if (!differ[k]) continue;
    const uint32_t i = uint32_t(first[k]);
    uint32_t cpu[kGridOutStride];
    grid_math_cpu(g, &in[size_t(i) * kGridInStride], cpu);
    table << kGridMathNames[k] << ": " << differ[k] << " of " << kCount << " differ, at most " << worst[k]
          << " ulps; first case " << i << ": gpu " << hex(from_bits(gpu[size_t(i) * kGridOutStride + k])) << " cpu "
          << hex(from_bits(cpu[k])) << "\n";
  }
  INFO(ctx.info().name << ": " << (table.str().empty() ? "every value identical\n" : table.str()));
  CHECK(accepted > kCount / 4);
  // Every value to the bit on every device (division and square root by rounding.h), except the
  // built-in `/` kept for comparison: to the bit on lavapipe, within kDivisionUlps elsewhere.
  if (!bit_exact_device(ctx) && differ[3])
    WARN("the built-in cell_size / len on " << ctx.info().name << ": " << differ[3] << " of " << kCount
                                            << " differ from the correctly rounded quotient, by at most " << worst[3] << " ulps");
  CHECK(total - differ[3] == 0);
  CHECK(worst[3] <= (bit_exact_device(ctx) ? 0u : kDivisionUlps));
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
