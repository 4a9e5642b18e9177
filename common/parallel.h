// parallel.h: the one thread pool of the project: run a worker on several threads (the calling
// thread is one of them) and join, and a parallel loop over indices handed out through a shared
// atomic counter. The emulated shader invocations (common/invocations.h), the portal tracer and
// the Embree oracle all run on it.
#pragma once

#include <algorithm>
#include <atomic>
#include <cstddef>
#include <system_error>
#include <thread>
#include <vector>

namespace gridrt {

// `requested` threads, or (0) one per hardware thread.
inline unsigned thread_count_or_hardware(unsigned requested) {
  if (requested) return requested;
  return std::max(1u, std::thread::hardware_concurrency());
}

// work() on `threads` threads at once, the calling thread one of them; returns when all return.
// work() takes its share itself (a shared counter): where the system makes fewer threads than
// asked (its limits), those made do it all (a thread's failure ended the process in
// std::terminate with the others running: an outside sweep).
template <class Work>
void run_on_threads(unsigned threads, Work&& work) {
  std::vector<std::thread> pool;
  for (unsigned t = 1; t < threads; ++t) {
    try {
      pool.emplace_back(work);
    } catch (const std::system_error&) {
      break;
    }
  }
  work();
  for (std::thread& t : pool) t.join();
}

// f(i) for every i in [0, n), indices handed out one at a time, on up to `threads` threads
// (0: one per hardware thread).
template <class F>
void parallel_for(size_t n, unsigned threads, F&& f) {
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i; (i = next.fetch_add(1)) < n;) f(i);
  };
  run_on_threads(unsigned(std::min<size_t>(thread_count_or_hardware(threads), std::max<size_t>(n, 1))), work);
}

}  // namespace gridrt
