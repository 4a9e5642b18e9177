// vulkan_test_util.h: what the Vulkan tests share: one validated context per test process, the
// check that the validation layer stayed silent, and hex printing of floats (Vulkan CTS style).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>

#include <catch2/catch.hpp>

#include "gridrt/common/util.h"
#include "gridrt/vulkan/context.h"

namespace gridrt::test {

// The process-wide context of the [vulkan] tests: validation layer (and synchronization
// validation) always on. Created on first use; an Error (no device) fails the test that asked.
// Destroyed by an atexit handler registered after the driver's own (so it runs before them):
// a function-local static would be destroyed after the driver tore itself down (a crash at exit
// seen with the NVIDIA driver).
inline vulkan::Context& vk_context() {
  static vulkan::Context* ctx = nullptr;
  if (!ctx) {
    vulkan::ContextOptions o = vulkan::ContextOptions::from_env();
    o.validation = true;
    ctx = new vulkan::Context(o);
    std::atexit([] {
      delete ctx;
      ctx = nullptr;
    });
  }
  return *ctx;
}

// Whether this device is held to the reference bit for bit in everything, denormals included:
// lavapipe (docs/VULKAN.md).
inline bool bit_exact_device(const vulkan::Context& ctx) {
  return ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE;
}

// Whether this device's hit records and explain events are held to the bit: lavapipe, and NVIDIA,
// whose + - * are correctly rounded and which, with division and square root taken from
// common/shared/rounding.h, agreed on every one of 4,665,600 hit records of the real scenes
// (docs/VULKAN.md); it flushes denormals, which the grid's values do not reach. Elsewhere the
// tests hold discrete results and reported floats to the tolerances of docs/VULKAN.md.
inline bool bit_exact_hits_device(const vulkan::Context& ctx) {
  return bit_exact_device(ctx) || ctx.info().driver_id == VK_DRIVER_ID_NVIDIA_PROPRIETARY;
}

// Fails the test with every validation message received since the last clear_messages().
#define GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx)                                    \
  do {                                                                              \
    const auto gridrt_msgs_ = (ctx).messages();                                     \
    for (const auto& m_ : gridrt_msgs_) UNSCOPED_INFO("validation: " << m_);         \
    REQUIRE(gridrt_msgs_.empty());                                                  \
  } while (0)

inline uint32_t bits(float f) { return std::bit_cast<uint32_t>(f); }
inline float from_bits(uint32_t u) { return std::bit_cast<float>(u); }

// "0x3f800000 (1)" : bits first, then the value.
inline std::string hex(float f) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "0x%08x (%.9g)", bits(f), double(f));
  return buf;
}
inline std::string hex(uint32_t u) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "0x%08x", u);
  return buf;
}

// Bit-identical, or both NaN (NaN payloads are not specified by Vulkan; see docs/VULKAN.md).
inline bool same_float(uint32_t a, uint32_t b) {
  return a == b || (std::isnan(from_bits(a)) && std::isnan(from_bits(b)));
}

// Distance in units in the last place of two floats given by their bits (common/util.h).
inline uint64_t ulp_distance(uint32_t a, uint32_t b) { return gridrt::ulp_distance(from_bits(a), from_bits(b)); }

// Vulkan's precision of the built-in division and square root (2.5 ulp in the Vulkan
// specification; 3 measured on NVIDIA H200, docs/VULKAN.md). The shared math uses rounding.h's
// correctly rounded ones instead; this bounds the built-ins where a test shows them, and what
// follows from a division on a device not held to the bit.
inline constexpr uint64_t kDivisionUlps = 3;

}  // namespace gridrt::test
