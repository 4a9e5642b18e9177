// invocations.h: emulated shader invocations on std::threads. `count` invocations are handed out
// through a shared atomic counter, in batches; with a seed they run in a seeded shuffled order,
// so that anything depending on the order (first-empty slots, which references a saturated cell
// keeps) shows up on any thread count. Every thread runs with IEEE denormals (no FTZ/DAZ).
#pragma once

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <numeric>
#include <optional>
#include <random>
#include <thread>
#include <vector>

#include "gridrt/common/parallel.h"

#if defined(__x86_64__) || defined(__i386__)
#include <xmmintrin.h>
#endif

namespace gridrt {

// Clear FTZ (bit 15) and DAZ (bit 6) of MXCSR: the reference keeps denormals, as the shaders must
// (shaderDenormPreserveFloat32).
inline void ieee_denormals() {
#if defined(__x86_64__) || defined(__i386__)
  _mm_setcsr(_mm_getcsr() & ~(0x8000u | 0x0040u));
#endif
}

template <class Fn>
void run_invocations(uint32_t count, unsigned threads, std::optional<uint64_t> seed, Fn&& fn,
                     uint32_t batch = 64) {
  if (count == 0) return;
  std::vector<uint32_t> order;
  if (seed) {
    order.resize(count);
    std::iota(order.begin(), order.end(), 0u);
    std::mt19937_64 rng(*seed);
    std::shuffle(order.begin(), order.end(), rng);
  }
  std::atomic<uint32_t> next{0};
  auto worker = [&]() {
    ieee_denormals();
    for (;;) {
      const uint32_t first = next.fetch_add(batch, std::memory_order_relaxed);
      if (first >= count) break;
      const uint32_t last = std::min(count, first + batch);
      for (uint32_t i = first; i < last; ++i) fn(seed ? order[i] : i);
    }
  };
  run_on_threads(std::max(1u, std::min<unsigned>(threads, (count + batch - 1) / batch)), worker);
}

}  // namespace gridrt
