// util.h: small utilities every layer uses: wall-clock milliseconds and seconds, a file's word made
// printable for a message, and the distance of two floats in units in the last place.
#pragma once

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <string_view>

namespace gridrt {

// A file's word for a message: printable ASCII kept, any other byte (a NUL, a control, UTF-8 or
// binary junk) and the backslash as \xNN, at most `max` bytes of `s` shown ("..." after them).
// A library's message that may quote the file's bytes (a JSON parser's "last read: '...'"): as
// printable, with line breaks and tabs kept, up to `max` bytes.
inline std::string printable_message(std::string_view s, size_t max = 4096);
inline std::string printable(std::string_view s, size_t max = 32) {
  std::string out;
  for (size_t i = 0; i < s.size() && i < max; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c >= 0x20 && c < 0x7F && c != '\\') {
      out.push_back(char(c));
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", unsigned(c));
      out += buf;
    }
  }
  if (s.size() > max) out += "...";
  return out;
}
// A name for a terminal: control bytes (a line break, an escape sequence's ESC) as \xNN, UTF-8
// and the rest kept (the same text again unchanged: it holds no control byte).
inline std::string control_escaped(std::string_view s) {
  std::string out;
  for (const char ch : s) {
    const unsigned char c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c != 0x7F) {
      out.push_back(ch);
    } else {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02X", unsigned(c));
      out += buf;
    }
  }
  return out;
}
inline std::string printable_message(std::string_view s, size_t max) {
  std::string out;
  size_t start = 0;
  for (size_t i = 0; i <= s.size() && i <= max; ++i) {  // runs between line breaks and tabs
    if (i == s.size() || i == max || s[i] == '\n' || s[i] == '\t') {
      out += printable(s.substr(start, i - start), i - start);
      if (i < s.size() && i < max) out.push_back(s[i]);
      start = i + 1;
    }
  }
  if (s.size() > max) out += "...";
  return out;
}

// Milliseconds since `t0` on the steady clock.
inline double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Seconds since `t0` on the steady clock.
inline double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

// Distance of two floats in units in the last place on the ordered line of floats (-0 and +0 meet
// at 0; across signs the steps through zero add up); UINT32_MAX where one is NaN and the bits differ.
inline uint32_t ulp_distance(float a, float b) {
  const uint32_t ua = std::bit_cast<uint32_t>(a), ub = std::bit_cast<uint32_t>(b);
  if (ua == ub) return 0;
  if (std::isnan(a) || std::isnan(b)) return UINT32_MAX;
  // Map the sign-magnitude bits onto a monotonic integer line (-0 and +0 meet at 0).
  auto ordered = [](uint32_t u) -> int64_t { return (u & 0x80000000u) ? -int64_t(u & 0x7fffffffu) : int64_t(u); };
  const int64_t d = ordered(ua) - ordered(ub);
  return uint32_t(std::min<int64_t>(d < 0 ? -d : d, UINT32_MAX));
}

}  // namespace gridrt
