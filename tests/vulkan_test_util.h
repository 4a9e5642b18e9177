// vulkan_test_util.h: what the Vulkan tests share: one validated context per test process, the
// check that the validation layer stayed silent, and hex printing of floats (Vulkan CTS style).
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>

#include <catch2/catch.hpp>

#include "vulkan/context.h"

namespace gridrt::test {

// The process-wide context of the [vulkan] tests: validation layer (and synchronization
// validation) always on. Created on first use; an Error (no device) fails the test that asked.
inline vulkan::Context& vk_context() {
  static std::unique_ptr<vulkan::Context> ctx;
  if (!ctx) {
    vulkan::ContextOptions o = vulkan::ContextOptions::from_env();
    o.validation = true;
    ctx = std::make_unique<vulkan::Context>(o);
  }
  return *ctx;
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

}  // namespace gridrt::test
