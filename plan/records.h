// records.h: what a grid tracer reports beside its hits, the same on every backend: the spill
// list as plain data and the explanation of one ray.
#pragma once

#include <string>
#include <vector>

#include "gridrt/common/shared/explain.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/tracer.h"

namespace gridrt::plan {

// The spill list as plain data: the header, the stored entries [0, min(count, capacity)) in the
// order they were appended (which differs between runs and backends: compare them as multisets,
// and the lists walked from the heads, which are in ascending reference order), and the heads.
struct SpillDump {
  bool on = false;  // kGridSpill: with spill off the count only counts, and nothing overflows
  shared::SpillHeader header{};
  std::vector<shared::SpillEntry> entries;
  std::vector<uint32_t> heads;  // four per cell (spill_head_index, spill_arrival_index); the compact
                                // layout's region heads are expanded to this form (expand_compact_heads)
  uint32_t stored() const { return header.count < header.capacity ? header.count : header.capacity; }
  uint32_t overflow() const { return on && header.count > header.capacity ? header.count - header.capacity : 0u; }
};
// The compact layout's spill heads (its header and two per region cell) as the image layout's
// four per cell of `cells` cells: the dynamic heads of the region's cells, every other head empty.
std::vector<uint32_t> expand_compact_heads(const std::vector<uint32_t>& heads, glm::uvec3 cells);
// The explanation of one ray: the events in order, and the hit.
struct ExplainRecord {
  Ray ray{};
  shared::GridParams params{};
  std::vector<shared::ExplainEvent> events;
  Hit hit{};
  uint32_t mode = shared::kTraceClosestHit;  // which hit the trace reported (kTraceAnyHit: the first)
};
std::string to_text(const ExplainRecord& record);
// A one-time warning on stderr when the spill list overflowed (references lost: holes possible);
// `warned` keeps it to once per tracer.
void warn_spill_overflow(const SpillDump& spill, const std::string& who, bool& warned);

// Hex bits of a float, e.g. "0x3f800000".
std::string hex(float f);

}  // namespace gridrt::plan
