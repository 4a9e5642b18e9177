// records.cpp: the spill overflow warning and hex bits of floats.
#include <cstdio>
#include <cstring>

#include "gridrt/plan/records.h"

namespace gridrt::plan {

void warn_spill_overflow(const SpillDump& spill, const std::string& who, bool& warned) {
  if (spill.overflow() == 0 || warned) return;
  warned = true;
  std::fprintf(stderr,
               "gridrt: warning: %s: the spill list overflowed: %u references found no slot, %u fit the list, "
               "%u were lost (holes are possible in saturated cells); raise --spill-capacity\n",
               who.c_str(), spill.header.count, spill.header.capacity, spill.overflow());
}

std::string hex(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", u);
  return buf;
}

}  // namespace gridrt::plan
