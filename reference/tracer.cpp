// tracer.cpp: ReferenceGridTracer (the gridrt::Tracer over the reference) and grid statistics.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "gridrt/reference/grid.h"
#include "gridrt/common/util.h"
#include "gridrt/common/invocations.h"
#include "gridrt/common/safe_io.h"

namespace gridrt::reference {


ReferenceGridTracer::ReferenceGridTracer(GridOptions options) : options_(std::move(options)) {}

void ReferenceGridTracer::build_scene(const Scene& scene, float time) {
  const auto t0 = std::chrono::steady_clock::now();
  scene_ = nullptr;  // until the grid is whole (a build that throws leaves the tracer unbuilt: Tracer::build)
  try {
    scene_build(grid_, scene, time, options_);
  } catch (...) {
    grid_ = GridData{};  // as before any build: stats and dump see an empty grid, not a half-made one
    throw;
  }
  scene_ = &scene;
  build_ms_ = ms_since(t0);
  overflow_warned_ = false;
  warn_spill_overflow(spill_counts(grid_), name(), overflow_warned_);
}

void ReferenceGridTracer::update_to(float time) {
  const auto t0 = std::chrono::steady_clock::now();
  scene_update(grid_, *scene_, time, options_);
  // The spill list's forecast fell short at this time: grow it and insert again (plan::spill_growth)
  if (const uint32_t grown = plan::spill_growth(grid_.spill_header, options_, grid_.requested_flags)) {
    spill_grow(grid_, grown);
    scene_update(grid_, *scene_, time, options_);
  }
  update_ms_ = ms_since(t0);
  warn_spill_overflow(spill_counts(grid_), name(), overflow_warned_);
}


void ReferenceGridTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) {
  run_trace(rays, hits, shared::kTraceClosestHit);
}

void ReferenceGridTracer::trace_occlusion(std::span<const Ray> rays, std::span<Hit> hits) {
  run_trace(rays, hits, shared::kTraceAnyHit);
}

void ReferenceGridTracer::run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t mode) const {
  run_invocations(uint32_t(rays.size()), thread_count(options_), std::nullopt,
                  [&](uint32_t i) { hits[i] = scene_trace(grid_, rays[i], nullptr, mode); }, 64);
}

AccelDump ReferenceGridTracer::dump() const {
  AccelDump d;
  // A copy of the grid's arrays (diff, bench, sweep): checked before it is made
  const bool compact = (grid_.params.flags & shared::kGridCompact) != 0u;
  require_host_memory(4 * (compact ? uint64_t(grid_.offsets.size()) + grid_.refs.size() : uint64_t(grid_.image.size())),
                      "copies of the grid's " + std::string(compact ? "arrays" : "image"), "use a coarser grid");
  if (compact) {
    // The compact layout: the offsets (the index of occupied cells' runs), then the references (as many as the last offset
    // says: the array's one-word stand-in of a grid without any is left out), as one row
    d.kind = "grid-compact";
    d.texels = grid_.offsets;
    d.texels.insert(d.texels.end(), grid_.refs.begin(),
                    grid_.refs.begin() + std::min<size_t>(grid_.refs.size(), d.texels.back()));
    d.extent = glm::uvec3(uint32_t(d.texels.size()), 1u, 1u);
    return d;
  }
  d.kind = "grid";
  d.extent = grid_.image.extent;
  d.texels = grid_.image.snapshot();
  return d;
}

ExplainRecord ReferenceGridTracer::explain_ray(const Ray& ray, uint32_t mode) const {
  if (!built()) throw Error("reference-grid: explain before a build (or after a build that failed)");
  ExplainRecord rec;
  rec.hit = scene_trace(grid_, ray, &rec, mode);
  return rec;
}

GridStats ReferenceGridTracer::stats() const {
  GridStats s = grid_stats(grid_);
  s.build_ms = build_ms_;
  s.update_ms = update_ms_;
  return s;
}

GridStats grid_stats(const GridData& grid) {
  const shared::GridParams& g = grid.params;
  GridStats s;
  s.origin = g.origin;
  s.cell_size = g.cell_size;
  s.cells = g.cells;
  s.capacity = g.capacity;
  s.image_extent = grid.image.extent;
  s.image_bytes = uint64_t(grid.image.size()) * 4;
  s.compact = (g.flags & shared::kGridCompact) != 0u;
  s.sparse_offsets = (g.flags & shared::kGridSparseOffsets) != 0u;
  if (s.compact && grid.spill_heads.size() >= shared::kCompactHeadsHeader)
    s.region_cells = (grid.spill_heads.size() - shared::kCompactHeadsHeader) / 2;
  s.memory = grid_allocated(grid);
  s.geometry_bytes = grid.triangles.size() * sizeof(shared::GridTriangle) +
                     grid.planes.size() * sizeof(shared::GridPlane) +
                     grid.uvs.size() * sizeof(shared::GridTriangleUv) +
                     grid.instances.size() * sizeof(shared::GridInstance) +
                     grid.materials.size() * sizeof(shared::GridMaterial) + grid.texels.size() * 4;
  s.cell_count = uint64_t(g.cells.x) * g.cells.y * g.cells.z;
  s.occupancy.assign(g.capacity + 1, 0);
  s.triangles = grid.triangles.size();
  std::vector<uint32_t> per_triangle(grid.triangles.size(), 0);
  std::vector<uint64_t> walk_chain(grid.triangles.size(), 0), search_chain(grid.triangles.size(), 0);
  std::vector<uint32_t> refs;
  for (uint32_t z = 0; z < g.cells.z; ++z)
    for (uint32_t y = 0; y < g.cells.y; ++y)
      for (uint32_t x = 0; x < g.cells.x; ++x) {
        const glm::uvec3 cell(x, y, z);
        refs.clear();
        const std::vector<uint32_t> stored = cell_references(grid, cell);
        const uint32_t n = uint32_t(stored.size());
        for (uint32_t ref : stored) {
          const uint32_t k = grid.instances[shared::ref_instance(ref)].tri_offset + shared::ref_triangle(ref);
          ++per_triangle[k];
          refs.push_back(k);
        }
        if (n >= s.occupancy.size()) s.occupancy.resize(n + 1, 0);
        uint32_t log2n = 0;
        while ((1ull << log2n) < uint64_t(n) + 1) ++log2n;
        for (uint32_t k : refs) {
          walk_chain[k] += n;
          search_chain[k] += 2 * log2n;
        }
        s.walk_accesses += uint64_t(n) * (n + 1) / 2;
        s.occupancy[n] += 1;
        s.references += n;
        if (n == 0) ++s.empty_cells;
        const uint32_t status = cell_status(grid, cell);
        if (status & shared::kStatusStatic) ++s.saturated_static;
        if (status & shared::kStatusDynamic) ++s.saturated_dynamic;
      }
  const SpillDump spill = spill_counts(grid);
  s.spill_on = (g.flags & shared::kGridSpill) != 0u;
  s.spill_appended = spill.header.count;
  s.spill_static = spill.header.static_count;
  s.spill_capacity = spill.header.capacity;
  s.spill_stored = spill.stored();
  s.spill_overflow = spill.overflow();
  s.gap_fill_active = (g.flags & shared::kGridGapFill) != 0u && g.traversal == shared::kTraversalPaper;
  uint64_t sum = 0, counted = 0, range_sum = 0;
  for (size_t i = 0; i < grid.triangles.size(); ++i) {
    const shared::GridTriangle& t = grid.triangles[i];
    if (shared::triangle_zero_area(t.v0, t.v1, t.v2)) {
      ++s.degenerate_triangles;
      continue;
    }
    sum += per_triangle[i];
    ++counted;
    s.references_per_triangle_max = std::max(s.references_per_triangle_max, per_triangle[i]);
    s.walk_chain_max = std::max(s.walk_chain_max, walk_chain[i]);
    s.search_chain_max = std::max(s.search_chain_max, search_chain[i]);
    glm::uvec3 lo, hi;
    shared::triangle_cell_range(g, t.v0, t.v1, t.v2, lo, hi);
    const uint64_t range = uint64_t(hi.x - lo.x + 1) * (hi.y - lo.y + 1) * (hi.z - lo.z + 1);
    range_sum += range;
    s.range_cells_per_triangle_max = std::max(s.range_cells_per_triangle_max, range);
  }
  s.references_per_triangle_mean = counted ? double(sum) / double(counted) : 0.0;
  s.range_cells_per_triangle_mean = counted ? double(range_sum) / double(counted) : 0.0;
  return s;
}

std::string to_text(const GridStats& s) {
  std::ostringstream os;
  os << "grid: " << s.cells.x << " x " << s.cells.y << " x " << s.cells.z << " cells of "
     << s.cell_size << " units, origin (" << s.origin.x << ", " << s.origin.y << ", " << s.origin.z
     << (s.compact ? "), compact layout (largest cell count " : "), capacity ") << s.capacity << (s.compact ? ")" : "")
     << "\n";
  if (s.compact)
    os << "layout: compact: " << (s.sparse_offsets ? "sparse offsets (occupied cells only) " : "dense offsets ")
       << s.memory.offsets << " bytes, references " << s.memory.refs
       << " bytes, dynamic region " << s.region_cells << " cells (heads " << s.memory.heads
       << " bytes); geometry and tables " << s.geometry_bytes << " bytes\n";
  else
    os << "layout: image " << s.image_extent.x << " x " << s.image_extent.y << " x " << s.image_extent.z
       << " texels, " << s.image_bytes << " bytes; geometry and tables " << s.geometry_bytes << " bytes\n";
  os << "grid memory (everything the grid keeps): " << s.memory.total() << " bytes ("
     << double(s.memory.total()) / double(1 << 20) << " MiB: image " << s.memory.image << ", offsets "
     << s.memory.offsets << ", references " << s.memory.refs << ", spill list " << s.memory.spill << ", heads "
     << s.memory.heads << ", skip field " << s.memory.skip << ", dirty-cell list " << s.memory.dirty << ")\n";
  // The compact layout keeps its static references per cell and every dynamic one in the spill
  // list (no cell has slots to fill): its figures say which they count (they read as if the
  // moving instances' references were missing, "found no slot": an outside sweep's find)
  os << "cells: " << s.cell_count << (s.compact ? ", without a static reference " : ", empty ") << s.empty_cells
     << " (" << (s.cell_count ? 100.0 * double(s.empty_cells) / double(s.cell_count) : 0.0)
     << "%), saturated by static " << s.saturated_static << ", by dynamic " << s.saturated_dynamic << "\n";
  if (s.spill_on && s.compact)
    os << "spill list (the compact layout's dynamic references): " << s.spill_appended - s.spill_static
       << " dynamic references, " << s.spill_static << " static; " << s.spill_stored << " stored of "
       << s.spill_capacity << " entries, " << s.spill_overflow << " lost to overflow"
       << (s.spill_overflow ? " (WARNING: holes are possible; raise --spill-capacity)" : "") << "\n";
  else if (s.spill_on)
    os << "spill list: " << s.spill_appended << " references found no slot (" << s.spill_static << " static); "
       << s.spill_stored << " stored of " << s.spill_capacity << " entries, " << s.spill_overflow
       << " lost to overflow" << (s.spill_overflow ? " (WARNING: holes are possible; raise --spill-capacity)" : "")
       << "\n";
  else
    os << "spill list: off; " << s.spill_appended << " references found no slot (dropped)"
       << (s.gap_fill_active ? "; gap-fill on" : "") << "\n";
  os << "references: " << s.references << (s.compact ? " static (the dynamic ones in the spill list above)" : "")
     << " for " << s.triangles << " triangles (" << s.degenerate_triangles
     << " zero-area, never inserted); per triangle mean " << s.references_per_triangle_mean << ", max "
     << s.references_per_triangle_max << "\n";
  os << "build work: AABB range cells per triangle mean " << s.range_cells_per_triangle_mean << ", max "
     << s.range_cells_per_triangle_max << "; slot accesses of insertions walked from slot 0: " << s.walk_accesses
     << " in total, " << s.walk_chain_max << " along the longest invocation; galloping search loads along it: "
     << s.search_chain_max << "\n";
  os << (s.compact ? "occupancy (static references per cell: cells):" : "occupancy (references per cell: cells):");
  for (size_t k = 0; k < s.occupancy.size(); ++k)
    if (s.occupancy[k]) os << " " << k << ":" << s.occupancy[k];
  os << "\n";
  if (s.build_ms > 0.0 || s.update_ms > 0.0)
    os << "last build " << s.build_ms << " ms, last update " << s.update_ms << " ms\n";
  return os.str();
}


}  // namespace gridrt::reference
