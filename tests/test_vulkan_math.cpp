// test_vulkan_math.cpp: the shared math (common/shared/{compat,transform,alpha}.h) compiled as
// GLSL and run on the device agrees bit for bit with the same functions compiled as C++, on
// thousands of random inputs including denormals, huge and tiny values (Falcor style: a kernel
// and its CPU twin; every mismatch prints its index, its inputs and both results as hex bits).
#include <algorithm>
#include <random>
#include <sstream>
#include <vector>

#include "common/shared/alpha.h"
#include "common/shared/transform.h"
#include "tests/vulkan_test_util.h"
#include "vulkan/pipeline.h"

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
  o[11] = bits(c[0] / c[3]);
  o[12] = bits(1.0f / c[1]);
  o[13] = bits(std::sqrt(std::fabs(c[2])));
  o[14] = bits(std::floor(c[4]));
  o[15] = 0;
}

const char* kResultNames[kOutStride] = {"sh_dot", "sh_cross.x", "sh_cross.y", "sh_cross.z",
                                        "transform_point.x", "transform_point.y", "transform_point.z",
                                        "interpolate_uv.x", "interpolate_uv.y", "alpha_texel_coords.x",
                                        "alpha_texel_coords.y", "a.x / b.x", "1 / a.y", "sqrt(|a.z|)",
                                        "floor(b.y)", "pad"};

bool is_denormal(float f) { return f != 0.0f && std::fpclassify(f) == FP_SUBNORMAL; }

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
  // zero): counted and reported, not failed.
  const bool preserve = ctx.info().denorm_preserve_f32;
  const bool strict = preserve || ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
  size_t mismatches = 0, flushed = 0, denormal_results = 0;
  std::ostringstream report;
  for (uint32_t i = 0; i < kCount; ++i) {
    const float* c = &in[size_t(i) * kInStride];
    uint32_t cpu[kOutStride];
    evaluate(c, cpu);
    for (uint32_t k = 0; k < kOutStride; ++k) {
      const uint32_t g = gpu[size_t(i) * kOutStride + k];
      const bool is_float = k < 9 || (k >= 11 && k < 15);
      if (is_float && is_denormal(from_bits(cpu[k]))) ++denormal_results;
      if (is_float ? same_float(g, cpu[k]) : g == cpu[k]) continue;
      const bool denormal_case =
          is_denormal(from_bits(cpu[k])) || std::any_of(c, c + 23, [](float f) { return is_denormal(f); });
      if (is_float && !strict && denormal_case) {
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
