// ray_order_estimate: would sorting the frame's bounce rays before the trace pay? A count, on the
// CPU reference's trace of one frame's glossy bounce rays, of how evenly the rays that would share
// a GPU subgroup walk: each ray's loop trips (cells visited + references tested, the exact
// traversal's one loop: reference/trace.cpp, HitRecord::cells and ::tests), and per subgroup of 32
// lanes the trips of its longest ray, which every lane of the subgroup waits for. Nothing runs on a
// GPU, and what divergence costs beyond the trips (the lanes' different cells and triangles in
// memory) is not counted: the figures bound what an order can save on the walk's instructions.
//   gridrt_ray_order_estimate [--width W] [--height H] [--subgroup N] [--threads N] SCENE...
// Orders, each of the frame's real bounce rays once (pixels without one are left out, as a
// compacted list leaves them; "tiles" keeps them as the idle lanes the frame's trace has):
//   tiles                 the frame's trace: 8x8 pixel tiles, a subgroup 8 x (N / 8) pixels of a tile
//   rows                  pixel rows, N real rays of the rows a subgroup
//   origin, octant ...    by the Morton code of the origin's grid cell (at the grid's resolution, or
//                         divided by 2, 4 or 8), after or before the direction's octant or its cell
//                         on a cube of R x R cells a face ("dir R")
//   coherent_ray_order    what `gridrt bench --ray-order sorted` does (common/gather.h): a 32-bit key
//   16 bits: ...          keys a one-pass counting sort could take: the direction's cell, then the
//                         origin on a lattice of 2^b cells per axis over the grid
//   next frame: ...       the next frame's rays of the same pixels (new random numbers) in the tiles,
//                         by this frame's trips of their pixel (known before the trace), and sorted
//   by trips (the bound)  the rays sorted by their own trips: no order does better on trips alone
// Printed per order: the subgroups' efficiency (the rays' trips over N times each subgroup's most
// trips, summed), and the trips a lane spends per ray (N times the most, over the rays): an
// order that gathers long rays with long ones spends fewer. The ratio column is against the
// tiles (for the next frame's rows, against its own tiles).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "gridrt/common/gather.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/common/util.h"
#include "gridrt/reference/grid.h"

using namespace gridrt;

namespace {

uint64_t spread3(uint32_t v) {  // 21 bits to every third bit
  uint64_t x = v & 0x1FFFFFu;
  x = (x | x << 32) & 0x1F00000000FFFFull;
  x = (x | x << 16) & 0x1F0000FF0000FFull;
  x = (x | x << 8) & 0x100F00F00F00F00Full;
  x = (x | x << 4) & 0x10C30C30C30C30C3ull;
  x = (x | x << 2) & 0x1249249249249249ull;
  return x;
}
uint64_t morton(glm::uvec3 c) { return spread3(c.x) | spread3(c.y) << 1 | spread3(c.z) << 2; }

// The direction's cube face (0-5) and its 8x8 cell on it: 9 bits.
uint32_t dir_bin(glm::vec3 d, uint32_t res = 8) {
  const glm::vec3 a = glm::abs(d);
  int axis = a.x >= a.y && a.x >= a.z ? 0 : (a.y >= a.z ? 1 : 2);
  const float m = a[axis];
  const float u = d[(axis + 1) % 3] / m, v = d[(axis + 2) % 3] / m;
  const uint32_t face = uint32_t(axis * 2 + (d[axis] < 0.0f ? 1 : 0));
  const float h = float(res) * 0.5f;
  const uint32_t iu = std::min(res - 1u, uint32_t((u + 1.0f) * h)), iv = std::min(res - 1u, uint32_t((v + 1.0f) * h));
  return (face * res + iu) * res + iv;
}
uint32_t octant(glm::vec3 d) { return (d.x < 0.0f ? 1u : 0u) | (d.y < 0.0f ? 2u : 0u) | (d.z < 0.0f ? 4u : 0u); }

struct Tally {
  double trips = 0, lane_trips = 0;
  size_t rays = 0, groups = 0;
};

// Subgroups of consecutive entries of `order` (indices into trips; kIdle: an idle lane).
constexpr uint32_t kIdle = 0xFFFFFFFFu;
Tally tally(const std::vector<uint32_t>& order, const std::vector<uint32_t>& trips, uint32_t n) {
  Tally t;
  for (size_t g = 0; g < order.size(); g += n) {
    uint32_t most = 0, real = 0;
    double sum = 0;
    for (size_t k = g; k < std::min(order.size(), g + n); ++k) {
      if (order[k] == kIdle) continue;
      most = std::max(most, trips[order[k]]);
      sum += trips[order[k]];
      real += 1;
    }
    if (real == 0) continue;
    t.trips += sum;
    t.lane_trips += double(n) * most;
    t.rays += real;
    t.groups += 1;
  }
  return t;
}

}  // namespace

int main(int argc, char** argv) {
  uint32_t width = 1920, height = 1080, subgroup = 32, threads = 0;
  std::vector<std::string> scenes;
  CLI::App app("gridrt_ray_order_estimate: how evenly a subgroup's bounce rays walk, in the frame's order and sorted");
  app.add_option("scenes", scenes, "Scenes: builtin:NAME, a scene file or a mesh")->required();
  app.add_option("--width", width, "Image width")->check(CLI::Range(8u, 8192u));
  app.add_option("--height", height, "Image height")->check(CLI::Range(8u, 8192u));
  app.add_option("--subgroup", subgroup, "Lanes of a subgroup (8, 16, 32 or 64)")->check(CLI::IsMember({8u, 16u, 32u, 64u}));
  app.add_option("--threads", threads, "CPU threads (0: all)");
  CLI11_PARSE(app, argc, argv);
  try {
    for (const std::string& spec : scenes) {
      const Scene scene = load_scene(spec);
      reference::GridOptions o;
      o.traversal = reference::Traversal::exact;
      o.threads = threads;
      reference::ReferenceGridTracer tracer(o);
      const float time = 0.0f;
      tracer.build(scene, time);
      const shared::GridParams& g = tracer.params();
      const GatherBuffer gb = make_gather(scene, tracer, scene.frame_camera(), width, height, time);
      const std::vector<Ray> rays = bounce_rays(scene, gb, 0);
      std::vector<Hit> hits(rays.size());
      tracer.trace(rays, hits);
      std::vector<uint32_t> trips(rays.size());
      std::vector<uint32_t> real;
      for (size_t i = 0; i < rays.size(); ++i) {
        trips[i] = hits[i].cells + hits[i].tests;
        if (!is_unused(rays[i])) real.push_back(uint32_t(i));
      }
      std::printf("== %s: grid %ux%ux%u, %ux%u, %zu bounce rays, subgroup %u\n", spec.c_str(), g.cells.x, g.cells.y,
                  g.cells.z, width, height, real.size(), subgroup);
      std::printf("| order | subgroups | efficiency | trips per ray | lane trips per ray | vs tiles |\n|---|---|---|---|---|---|\n");
      double base = 0;
      auto report = [&](const char* name, const std::vector<uint32_t>& order) {
        const Tally t = tally(order, trips, subgroup);
        const double lane = t.lane_trips / double(t.rays);
        if (base == 0) base = lane;
        std::printf("| %s | %zu | %.3f | %.2f | %.2f | %.3f |\n", name, t.groups, t.trips / t.lane_trips,
                    t.trips / double(t.rays), lane, lane / base);
      };
      // tiles: the frame's trace, 8x8 tiles, subgroups of 8 x (N / 8) pixels
      std::vector<uint32_t> tiles;
      const uint32_t rows_per = std::max(1u, subgroup / 8u);
      for (uint32_t ty = 0; ty < (height + 7) / 8; ++ty)
        for (uint32_t tx = 0; tx < (width + 7) / 8; ++tx)
          for (uint32_t r0 = 0; r0 < 8; r0 += rows_per)
            for (uint32_t y = ty * 8 + r0; y < ty * 8 + r0 + rows_per; ++y)
              for (uint32_t x = tx * 8; x < tx * 8 + 8; ++x) {
                const bool inside = x < width && y < height;
                const uint32_t i = y * width + x;
                tiles.push_back(inside && !is_unused(rays[i]) ? i : kIdle);
              }
      report("tiles (the frame's)", tiles);
      report("rows (real rays only)", real);
      // Blocks of B x B pixels, each block's rays sorted by coherent_ray_order within it (the empty
      // pixels last: whole subgroups of them idle at once), a workgroup per block
      for (uint32_t B : {8u, 16u, 32u}) {
        std::vector<uint32_t> order;
        for (uint32_t by = 0; by < height; by += B)
          for (uint32_t bx = 0; bx < width; bx += B) {
            std::vector<uint32_t> idx;
            std::vector<Ray> block;
            for (uint32_t y = by; y < std::min(height, by + B); ++y)
              for (uint32_t x = bx; x < std::min(width, bx + B); ++x) {
                idx.push_back(y * width + x);
                block.push_back(rays[y * width + x]);
              }
            for (uint32_t k : coherent_ray_order(block)) order.push_back(is_unused(block[k]) ? kIdle : idx[k]);
            while (order.size() % subgroup != 0) order.push_back(kIdle);
          }
        const std::string name = "blocks of " + std::to_string(B) + "x" + std::to_string(B) + ", sorted within";
        report(name.c_str(), order);
      }
      auto cell = [&](uint32_t i) { return shared::cell_of_point(g, rays[i].org); };
      auto sorted_by = [&](auto key) {
        std::vector<std::pair<uint64_t, uint32_t>> kv;
        kv.reserve(real.size());
        for (uint32_t i : real) kv.emplace_back(key(i), i);
        std::stable_sort(kv.begin(), kv.end(), [](const auto& a, const auto& b) { return a.first < b.first; });
        std::vector<uint32_t> out;
        out.reserve(kv.size());
        for (const auto& p : kv) out.push_back(p.second);
        return out;
      };
      report("origin", sorted_by([&](uint32_t i) { return morton(cell(i)); }));
      report("octant, origin", sorted_by([&](uint32_t i) { return uint64_t(octant(rays[i].dir)) << 60 | morton(cell(i)); }));
      report("dir, origin / 4", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir)) << 54 | morton(cell(i) / 4u);
             }));
      report("origin / 4, dir", sorted_by([&](uint32_t i) {
               return morton(cell(i) / 4u) << 9 | dir_bin(rays[i].dir);
             }));
      report("octant, origin / 4, dir", sorted_by([&](uint32_t i) {
               return uint64_t(octant(rays[i].dir)) << 60 | morton(cell(i) / 4u) << 9 | dir_bin(rays[i].dir);
             }));
      report("dir 16, origin / 2", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 16)) << 54 | morton(cell(i) / 2u);
             }));
      report("dir 4, origin / 8", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 4)) << 54 | morton(cell(i) / 8u);
             }));
      report("dir 2, origin / 4", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 2)) << 54 | morton(cell(i) / 4u);
             }));
      // Keys of 16 bits (a counting sort's bins): the direction's bin, then the origin on a lattice
      // of 2^b cells per axis over the grid
      auto lattice = [&](uint32_t i, uint32_t b) {
        const glm::uvec3 c = cell(i);
        return morton(glm::uvec3((uint64_t(c.x) << b) / g.cells.x, (uint64_t(c.y) << b) / g.cells.y,
                                 (uint64_t(c.z) << b) / g.cells.z));
      };
      report("16 bits: dir 8 (9 bits), origin 2^2 a side (6)", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 8)) << 6 | lattice(i, 2);
             }));
      report("16 bits: dir 4 (7 bits), origin 2^3 a side (9)", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 4)) << 9 | lattice(i, 3);
             }));
      report("16 bits: dir 16 (11 bits), origin 2^1 a side (3)", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 16)) << 3 | lattice(i, 1);
             }));
      report("16 bits: dir 26 (13 bits), origin none", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 26));
             }));
      report("20 bits: dir 16 (11 bits), origin 2^3 a side (9)", sorted_by([&](uint32_t i) {
               return uint64_t(dir_bin(rays[i].dir, 16)) << 9 | lattice(i, 3);
             }));
      report("coherent_ray_order (bench --ray-order sorted)", [&] {
        std::vector<uint32_t> order = coherent_ray_order(rays);
        while (!order.empty() && is_unused(rays[order.back()])) order.pop_back();
        return order;
      }());
      // The next frame's rays of the same pixels (new random numbers), ordered by this frame's
      // trips of their pixel: an order known before the trace, from the last frame's records
      {
        const std::vector<Ray> next = bounce_rays(scene, gb, 1);
        std::vector<Hit> nh(next.size());
        tracer.trace(next, nh);
        std::vector<uint32_t> saved = trips;
        const double tiles_base = base;
        for (size_t i = 0; i < next.size(); ++i) trips[i] = nh[i].cells + nh[i].tests;
        base = 0;
        report("next frame: tiles", tiles);
        report("next frame: by this frame's trips", sorted_by([&](uint32_t i) { return uint64_t(saved[i]); }));
        report("next frame: by this frame's trips, then dir", sorted_by([&](uint32_t i) {
                 return uint64_t(std::min(saved[i], 1023u)) << 20 | dir_bin(next[i].dir) << 11 | (morton(cell(i) / 8u) & 0x7FF);
               }));
        report("next frame: dir, origin / 4", sorted_by([&](uint32_t i) {
                 return uint64_t(dir_bin(next[i].dir)) << 54 | morton(cell(i) / 4u);
               }));
        report("next frame: by its own trips (the bound)", sorted_by([&](uint32_t i) { return uint64_t(trips[i]); }));
        trips = saved;
        base = tiles_base;
      }
      // The bound: rays sorted by their own trips (no order does better on trips alone)
      report("by trips (the bound)", sorted_by([&](uint32_t i) { return uint64_t(trips[i]); }));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gridrt_ray_order_estimate: %s\n", e.what());
    return 1;
  }
  return 0;
}
