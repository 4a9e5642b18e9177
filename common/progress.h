// progress.h: a progress line for long work. Silent for work that ends within a second; then one
// line on stderr, rewritten in place on a terminal, at most every second elsewhere (CI logs). A
// total of 0: work of unknown length, counted in steps (no share, no estimate of the rest).
#pragma once

#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string>

#include <unistd.h>

namespace gridrt {

class Progress {
 public:
  // `timer`: work with nothing to count (a wait on the device): the line gives the seconds only.
  Progress(std::string label, uint64_t total, bool timer = false)
      : label_(std::move(label)), total_(total), start_(Clock::now()), last_(start_),
        tty_(isatty(fileno(stderr)) != 0), timer_(timer) {}
  ~Progress() { finish(); }
  Progress(const Progress&) = delete;
  Progress& operator=(const Progress&) = delete;

  // Thread safe; cheap when no line is due.
  void advance(uint64_t n = 1) {
    const uint64_t done = done_.fetch_add(n, std::memory_order_relaxed) + n;
    const auto now = Clock::now();
    if (now - last_tick_.load(std::memory_order_relaxed) < std::chrono::milliseconds(tty_ ? 100 : 1000)) return;
    std::lock_guard lock(mutex_);
    if (now - start_ < std::chrono::seconds(1) || now - last_ < std::chrono::milliseconds(tty_ ? 100 : 1000)) return;
    last_ = now;
    last_tick_.store(now, std::memory_order_relaxed);
    print(done, now, false);
  }

  void finish() {
    std::lock_guard lock(mutex_);
    if (finished_) return;
    finished_ = true;
    const auto now = Clock::now();
    if (now - start_ >= std::chrono::seconds(1)) print(done_.load(), now, true);
  }

 private:
  using Clock = std::chrono::steady_clock;
  void print(uint64_t done, Clock::time_point now, bool final) {
    const double secs = std::chrono::duration<double>(now - start_).count();
    const double frac = total_ ? double(done > total_ ? total_ : done) / double(total_) : 0.0;
    if (final)
      std::fprintf(stderr, "%s%s: done in %.1f s%s\n", tty_ ? "\r" : "", label_.c_str(), secs, tty_ ? "\033[K" : "");
    else if (timer_)
      std::fprintf(stderr, "%s%s: %.0f s so far%s", tty_ ? "\r" : "", label_.c_str(), secs, tty_ ? "\033[K" : "\n");
    else if (total_ == 0)
      std::fprintf(stderr, "%s%s: %llu so far (%.1f s)%s", tty_ ? "\r" : "", label_.c_str(),
                   (unsigned long long)done, secs, tty_ ? "\033[K" : "\n");
    else {
      const double eta = frac > 0.0 ? secs / frac - secs : 0.0;
      std::fprintf(stderr, "%s%s: %5.1f%% (%.1f s, ~%.0f s left)%s", tty_ ? "\r" : "", label_.c_str(),
                   100.0 * frac, secs, eta, tty_ ? "\033[K" : "\n");
    }
    std::fflush(stderr);
  }

  std::string label_;
  uint64_t total_;
  std::atomic<uint64_t> done_{0};
  Clock::time_point start_, last_;
  std::atomic<Clock::time_point> last_tick_{Clock::time_point{}};
  std::mutex mutex_;
  bool tty_;
  bool timer_;
  bool finished_ = false;
};

}  // namespace gridrt
