// records.cpp: the spill overflow warning and hex bits of floats.
#include <cstdio>
#include <cstring>

#include "gridrt/plan/records.h"

namespace gridrt::plan {

std::vector<uint32_t> expand_compact_heads(const std::vector<uint32_t>& heads, glm::uvec3 cells) {
  std::vector<uint32_t> out(4 * size_t(cells.x) * cells.y * cells.z, shared::kSpillEnd);
  if (heads.size() < shared::kCompactHeadsHeader) return out;
  const glm::uvec3 lo(heads[0], heads[1], heads[2]), hi(heads[4], heads[5], heads[6]);
  if (lo.x > hi.x || lo.y > hi.y || lo.z > hi.z) return out;
  for (uint32_t z = lo.z; z <= hi.z; ++z)
    for (uint32_t y = lo.y; y <= hi.y; ++y)
      for (uint32_t x = lo.x; x <= hi.x; ++x) {
        const glm::uvec3 c(x, y, z);
        const uint32_t r = shared::region_index(c, lo, hi);
        const size_t i = (size_t(z) * cells.y + y) * cells.x + x;
        if (shared::compact_arrival_index(r) >= heads.size()) return out;
        out[4 * i + 1] = heads[shared::compact_head_index(r)];
        out[4 * i + 3] = heads[shared::compact_arrival_index(r)];
      }
  return out;
}

void warn_spill_overflow(const SpillDump& spill, const std::string& who, bool& warned) {
  if (spill.overflow() == 0 || warned) return;
  warned = true;
  std::fprintf(stderr,
               "gridrt: warning: %s: the spill list overflowed: %u references found no slot, %u fit the list, "
               "%u were lost: rays can pass through their triangles in the cells that lost them (the image layout's "
               "saturated cells; in the compact layout, the dynamic instances' cells, none of them saturated); raise "
               "--spill-capacity\n",
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
