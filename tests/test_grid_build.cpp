// Grid invariants after build and update: exactly the accepted cells, thread/order independence of
// `sorted`, multiset equality of `first-empty`, update == fresh build.
#include <catch2/catch.hpp>

#include <algorithm>
#include <map>
#include <optional>

#include "gridrt/common/shared/transform.h"
#include "test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;
using reference::GridData;
using reference::GridOptions;
using reference::Insertion;

namespace {

size_t cell_index(const sh::GridParams& g, glm::uvec3 c) { return (size_t(c.z) * g.cells.y + c.y) * g.cells.x + c.x; }

// Per cell, the references the build must consider (recomputed independently of the build's
// invocations, from the scene's own transforms): the candidates.
std::vector<std::vector<uint32_t>> candidates(const Scene& scene, const sh::GridParams& g, float time) {
  std::vector<std::vector<uint32_t>> out(size_t(g.cells.x) * g.cells.y * g.cells.z);
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Mesh& mesh = scene.meshes[scene.instances[i].mesh];
    const sh::Affine m = sh::to_affine(scene.instances[i].transform_at(time));
    for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
      const glm::uvec3 idx = mesh.triangles[t];
      const glm::vec3 v0 = sh::transform_point(m, mesh.positions[idx.x]);
      const glm::vec3 v1 = sh::transform_point(m, mesh.positions[idx.y]);
      const glm::vec3 v2 = sh::transform_point(m, mesh.positions[idx.z]);
      const glm::vec3 n = sh::triangle_normal(v0, v1, v2);
      if (sh::triangle_zero_area(v0, v1, v2)) continue;
      glm::uvec3 lo, hi;
      sh::triangle_cell_range(g, v0, v1, v2, lo, hi);
      for (uint32_t z = lo.z; z <= hi.z; ++z)
        for (uint32_t y = lo.y; y <= hi.y; ++y)
          for (uint32_t x = lo.x; x <= hi.x; ++x)
            if (sh::triangle_overlaps_cell(g, v0, v1, v2, n, {x, y, z}))
              out[cell_index(g, {x, y, z})].push_back(sh::ref_pack(i, t));
    }
  }
  for (auto& c : out) std::sort(c.begin(), c.end());
  return out;
}

struct CellContent {
  std::vector<uint32_t> refs;  // slots up to the first blank, in slot order
  uint32_t status = 0;
  bool blank_tail = true;  // every slot after the first blank is blank
};

CellContent read_cell(const GridData& grid, glm::uvec3 c) {
  const sh::GridParams& g = grid.params;
  CellContent out;
  bool ended = false;
  for (uint32_t s = 0; s < g.capacity; ++s) {
    const uint32_t ref = imageLoad(grid.image, glm::ivec3(sh::cell_slot_texel(g, c, s)));
    if (ref == sh::kBlank) ended = true;
    else if (ended) out.blank_tail = false;
    else out.refs.push_back(ref);
  }
  out.status = imageLoad(grid.image, glm::ivec3(sh::cell_status_texel(g, c)));
  return out;
}

// The invariants of one image against its candidates; returns the number of saturated cells.
uint32_t check_invariants(const Scene& scene, const GridData& grid, float time) {
  const sh::GridParams& g = grid.params;
  const auto cand = candidates(scene, g, time);
  uint32_t saturated = 0;
  for (uint32_t z = 0; z < g.cells.z; ++z)
    for (uint32_t y = 0; y < g.cells.y; ++y)
      for (uint32_t x = 0; x < g.cells.x; ++x) {
        const glm::uvec3 c(x, y, z);
        const CellContent cell = read_cell(grid, c);
        const std::vector<uint32_t>& want = cand[cell_index(g, c)];
        std::vector<uint32_t> got = cell.refs;
        if (!cell.blank_tail) FAIL("cell " << hx(c) << " has a reference after a blank slot");
        if (g.insertion == sh::kInsertSorted && !std::is_sorted(got.begin(), got.end()))
          FAIL("sorted cell " << hx(c) << " is not in ascending order");
        std::sort(got.begin(), got.end());
        if (want.size() <= g.capacity) {
          // Unsaturated: exactly the candidates, no flag
          if (got != want || cell.status != 0)
            FAIL("cell " << hx(c) << ": " << got.size() << " references, " << want.size() << " candidates, status "
                         << cell.status);
        } else {
          ++saturated;
          // Saturated: full, a subset of the candidates, the right flag
          const uint32_t statics = uint32_t(std::count_if(want.begin(), want.end(),
                                                          [&](uint32_t r) { return r < g.comparison_offset; }));
          if (got.size() != g.capacity || !std::includes(want.begin(), want.end(), got.begin(), got.end()))
            FAIL("saturated cell " << hx(c) << " holds " << got.size() << " references, not a full subset of "
                                   << want.size() << " candidates");
          if (g.insertion == sh::kInsertSorted) {
            // The capacity smallest; static bit iff statics overflow, dynamic bit iff a dynamic dropped
            if (!std::equal(got.begin(), got.end(), want.begin()))
              FAIL("sorted cell " << hx(c) << " does not hold its smallest candidates");
            const uint32_t expect = (statics > g.capacity ? sh::kStatusStatic : 0u) |
                                    (want.size() > statics ? sh::kStatusDynamic : 0u);
            if (cell.status != expect) FAIL("cell " << hx(c) << " status " << cell.status << ", expected " << expect);
          } else if (cell.status == 0) {
            FAIL("saturated first-empty cell " << hx(c) << " has no status bit");
          }
        }
      }
  return saturated;
}

// Per cell: the sorted reference list and the status, as compared between first-empty images.
std::vector<std::pair<std::vector<uint32_t>, uint32_t>> multisets(const GridData& grid) {
  const sh::GridParams& g = grid.params;
  std::vector<std::pair<std::vector<uint32_t>, uint32_t>> out;
  for (uint32_t z = 0; z < g.cells.z; ++z)
    for (uint32_t y = 0; y < g.cells.y; ++y)
      for (uint32_t x = 0; x < g.cells.x; ++x) {
        CellContent c = read_cell(grid, {x, y, z});
        std::sort(c.refs.begin(), c.refs.end());
        out.emplace_back(c.refs, c.status);
      }
  return out;
}

GridData build(const Scene& scene, float time, GridOptions o) {
  GridData g;
  reference::scene_build(g, scene, time, o);
  return g;
}

}  // namespace

TEST_CASE("Every triangle is referenced in exactly the cells its test accepts", "[grid]") {
  // A capacity of 4 on a dense scene: some cells saturate
  const Scene scene = random_scene(600, 0.8f, 8.0f, 21, 80);
  using CellTest = GridOptions::CellTest;
  for (CellTest ct : {CellTest::sphere, CellTest::box})
    for (Insertion ins : {Insertion::sorted, Insertion::first_empty}) {
      GridOptions o{{.insertion = ins, .cell_test = ct}, {.capacity = 4}, {.threads = 2}};
      const GridData g = build(scene, 0.5f, o);
      CHECK(((g.params.flags & sh::kGridCellBox) != 0u) == (ct == CellTest::box));
      const uint32_t saturated = check_invariants(scene, g, 0.5f);
      INFO("saturated cells: " << saturated);
      CHECK(saturated > 0);
      CHECK(saturated < g.params.cells.x * g.params.cells.y * g.params.cells.z);
    }
}

TEST_CASE("The separating-axis cell test keeps a subset of the sphere test's references, and fewer", "[grid]") {
  const Scene scene = random_scene(400, 0.8f, 8.0f, 23, 60);
  using CellTest = GridOptions::CellTest;
  GridOptions o{{.traversal = reference::Traversal::exact, .cell_test = CellTest::sphere},
                {.resolution = glm::uvec3(12, 12, 12), .capacity = 300},
                {.threads = 2}};
  const GridData sphere = build(scene, 0.5f, o);
  o.cell_test = CellTest::automatic;  // box for the exact traversal
  const GridData box = build(scene, 0.5f, o);
  REQUIRE((box.params.flags & sh::kGridCellBox) != 0u);
  REQUIRE(box.params.cells == sphere.params.cells);
  size_t refs_sphere = 0, refs_box = 0;
  for (uint32_t z = 0; z < box.params.cells.z; ++z)
    for (uint32_t y = 0; y < box.params.cells.y; ++y)
      for (uint32_t x = 0; x < box.params.cells.x; ++x) {
        const CellContent a = read_cell(sphere, {x, y, z}), b = read_cell(box, {x, y, z});
        REQUIRE(a.status == 0u);  // nothing dropped: both hold every reference their test accepts
        REQUIRE(std::includes(a.refs.begin(), a.refs.end(), b.refs.begin(), b.refs.end()));
        refs_sphere += a.refs.size();
        refs_box += b.refs.size();
      }
  INFO("references: sphere " << refs_sphere << ", box " << refs_box);
  CHECK(refs_box < refs_sphere);
}

TEST_CASE("Sorted images are identical over thread counts and shuffled orders", "[grid]") {
  const Scene scene = random_scene(500, 0.8f, 8.0f, 22, 60);
  GridOptions o{{.insertion = Insertion::sorted}, {.capacity = 5}, {.threads = 1}};
  const GridData g1 = build(scene, 0.25f, o);
  const std::vector<uint32_t> want = g1.image.snapshot();
  for (unsigned threads : {2u, 7u})
    for (std::optional<uint64_t> seed : {std::optional<uint64_t>{}, std::optional<uint64_t>{1}, std::optional<uint64_t>{99}}) {
      o.threads = threads;
      o.shuffle_seed = seed;
      const GridData g = build(scene, 0.25f, o);
      INFO("threads " << threads << " seed " << (seed ? int64_t(*seed) : -1));
      CHECK(g.image.snapshot() == want);
      CHECK(std::memcmp(g.triangles.data(), g1.triangles.data(), g1.triangles.size() * sizeof(sh::GridTriangle)) == 0);
    }
}

TEST_CASE("First-empty images are equal as per-cell multisets where unsaturated", "[grid]") {
  const Scene scene = random_scene(500, 0.8f, 8.0f, 23, 60);
  GridOptions o{{.insertion = Insertion::first_empty}, {.capacity = 5}, {.threads = 1}};
  const GridData g1 = build(scene, 0.0f, o);
  const auto want = multisets(g1);
  bool some_order_differs = false;
  for (unsigned threads : {2u, 7u})
    for (uint64_t seed : {3u, 4u}) {
      o.threads = threads;
      o.shuffle_seed = seed;
      const GridData g = build(scene, 0.0f, o);
      check_invariants(scene, g, 0.0f);  // saturated cells: valid subsets, flagged
      const auto got = multisets(g);
      for (size_t c = 0; c < got.size(); ++c)
        if (want[c].second == 0 && got[c].second == 0 && got[c] != want[c]) FAIL("cell " << c << " differs");
      some_order_differs = some_order_differs || g.image.snapshot() != g1.image.snapshot();
    }
  CHECK(some_order_differs);  // shuffled orders do change slot order: the mode is timing-dependent
}

TEST_CASE("After animated frames, the updated image equals a fresh build at that time", "[grid]") {
  const Scene scene = random_scene(300, 0.8f, 8.0f, 24, 120);
  for (Insertion ins : {Insertion::sorted, Insertion::first_empty}) {
    GridOptions o{{.insertion = ins}, {.capacity = 5}, {.threads = 3}};
    GridData g = build(scene, 0.0f, o);
    for (float time : {0.3f, 1.1f, 2.9f, 7.5f}) {
      reference::scene_update(g, scene, time, o);
      const GridData fresh = build(scene, time, o);
      REQUIRE(std::memcmp(&fresh.params, &g.params, sizeof g.params) == 0);
      INFO("time " << time << (ins == Insertion::sorted ? " sorted" : " first-empty"));
      check_invariants(scene, g, time);
      CHECK(std::memcmp(g.triangles.data(), fresh.triangles.data(), g.triangles.size() * sizeof(sh::GridTriangle)) == 0);
      // The plane buffer: each triangle's plane as the test would make it, updated with it
      REQUIRE(g.planes.size() == g.triangles.size());
      CHECK(std::memcmp(g.planes.data(), fresh.planes.data(), g.planes.size() * sizeof(sh::GridPlane)) == 0);
      for (size_t k = 0; k < g.triangles.size(); ++k) {
        const sh::GridPlane p = sh::triangle_plane(g.triangles[k].v0, g.triangles[k].v1, g.triangles[k].v2);
        if (std::memcmp(&p, &g.planes[k], sizeof p) != 0) FAIL("triangle " << k << ": its plane is not triangle_plane's");
      }
      if (ins == Insertion::sorted) {
        CHECK(g.image.snapshot() == fresh.image.snapshot());
      } else {
        const auto a = multisets(g), b = multisets(fresh);
        for (size_t c = 0; c < a.size(); ++c)
          if (a[c].second == 0 && b[c].second == 0 && a[c] != b[c]) FAIL("cell " << c << " differs");
      }
    }
  }
}

TEST_CASE("Grid bounds cover the animation - zero-area triangles are never inserted", "[grid]") {
  Scene scene = random_scene(100, 0.8f, 8.0f, 25, 40);
  // Add a zero-area triangle to the static mesh
  Mesh& m = scene.meshes[0];
  const uint32_t b = uint32_t(m.positions.size());
  m.positions.insert(m.positions.end(), {{1, 1, 1}, {2, 2, 2}, {3, 3, 3}});
  m.triangles.push_back({b, b + 1, b + 2});
  m.materials.push_back(0);
  scene.finalize();
  GridOptions o{{}, {}, {.threads = 2}};
  reference::ReferenceGridTracer tracer(o);
  tracer.build(scene, 0.0f);
  const sh::GridParams& g = tracer.params();
  for (float time = 0.0f; time < 10.0f; time += 0.37f) {
    const Bounds bb = scene.bounds(time);
    INFO("time " << time << " bounds " << hx(bb.lo) << " " << hx(bb.hi) << " grid " << hx(g.origin) << " " << hx(g.upper));
    CHECK(glm::all(glm::greaterThan(bb.lo, g.origin)));
    CHECK(glm::all(glm::lessThan(bb.hi, g.upper)));
  }
  const reference::GridStats s = tracer.stats();
  CHECK(s.degenerate_triangles == 1);
  CHECK(s.triangles == 100 + 1 + 40);
  CHECK(s.image_bytes == uint64_t(g.cells.x) * (g.capacity + 1) * g.cells.y * g.cells.z * 4);
  uint64_t cells = 0, refs = 0;
  for (size_t k = 0; k < s.occupancy.size(); ++k) {
    cells += s.occupancy[k];
    refs += k * s.occupancy[k];
  }
  CHECK(cells == s.cell_count);
  CHECK(refs == s.references);
  CHECK(s.empty_cells == s.occupancy[0]);
  const std::string text = reference::to_text(s);
  CHECK(text.find("capacity") != std::string::npos);
  const AccelDump d = tracer.dump();
  CHECK(d.kind == "grid");
  CHECK(d.extent == sh::grid_image_extent(g));
  CHECK(d.texels.size() == size_t(d.extent.x) * d.extent.y * d.extent.z);
}

TEST_CASE("Automatic resolution respects the image limits and the overrides", "[grid]") {
  const Scene scene = random_scene(2000, 0.3f, 50.0f, 26);
  GridOptions o{{}, {.max_image_dimension = 256}};
  const sh::GridParams g = reference::choose_grid(scene, 0.0f, o);
  CHECK(g.cells.x * (g.capacity + 1) <= 256u);
  CHECK(g.cells.y <= 256u);
  CHECK(g.capacity >= 4u);
  CHECK(g.capacity <= 64u);
  CHECK(g.inv_cell_size == 1.0f / g.cell_size);
  GridOptions r{{}, {.resolution = glm::uvec3(7, 5, 3), .capacity = 9}};
  const sh::GridParams gr = reference::choose_grid(scene, 0.0f, r);
  CHECK(gr.cells == glm::uvec3(7, 5, 3));
  CHECK(gr.capacity == 9u);
  CHECK(glm::all(glm::greaterThanEqual(gr.upper, scene.bounds(0.0f).hi)));
  GridOptions too_big{{}, {.max_image_dimension = 16, .resolution = glm::uvec3(64, 5, 3)}};
  CHECK_THROWS_AS(reference::choose_grid(scene, 0.0f, too_big), Error);
}

TEST_CASE("The dirty-cell list holds every cell with dynamic references once, through updates", "[grid]") {
  const Scene scene = random_scene(300, 0.8f, 8.0f, 24, 120);
  for (Insertion ins : {Insertion::sorted, Insertion::first_empty})
    for (std::optional<uint32_t> capacity : {std::optional<uint32_t>(5), std::optional<uint32_t>()}) {
      GridOptions o{{.insertion = ins}, {.capacity = capacity}, {.threads = 3}};
      GridData g = build(scene, 0.0f, o);
      const sh::GridParams& p = g.params;
      size_t dropped_only = 0;  // listed cells whose dynamic references were all dropped (saturated)
      for (float time : {0.0f, 0.3f, 1.1f, 2.9f}) {
        if (time > 0.0f) reference::scene_update(g, scene, time, o);
        INFO("time " << time << (ins == Insertion::sorted ? " sorted" : " first-empty") << ", capacity "
                     << (capacity ? std::to_string(*capacity) : "automatic"));
        std::vector<uint32_t> list = reference::dirty_cells(g);
        std::sort(list.begin(), list.end());
        CHECK(std::adjacent_find(list.begin(), list.end()) == list.end());  // each cell once
        // The independent truth: the cells with a dynamic candidate (recomputed from the scene)
        const auto cand = candidates(scene, p, time);
        std::vector<uint32_t> want;
        for (uint32_t c = 0; c < cand.size(); ++c)
          if (!cand[c].empty() && cand[c].back() >= p.comparison_offset) want.push_back(c);
        CHECK(!want.empty());
        CHECK(list == want);
        // In the image: a listed cell holds a dynamic reference or has the dynamic saturation bit
        for (uint32_t c : list) {
          const CellContent cell = read_cell(g, sh::cell_of_linear_index(p, c));
          const bool holds = std::any_of(cell.refs.begin(), cell.refs.end(), [&](uint32_t r) { return r >= p.comparison_offset; });
          CHECK((holds || (cell.status & sh::kStatusDynamic) != 0));
          dropped_only += !holds;
        }
        // The listed bits say the same
        size_t bits = 0;
        for (uint32_t c = 0; c < sh::grid_cell_count(p); ++c) {
          const bool bit = (g.dirty.load(sh::kWorkListHeaderWords + sh::dirty_bit_item(p, c)) & sh::dirty_bit(c)) != 0;
          bits += bit;
          if (bit != std::binary_search(list.begin(), list.end(), c)) FAIL("cell " << c << ": listed bit " << bit);
        }
        CHECK(bits == list.size());
      }
      if (capacity) CHECK(dropped_only > 0);  // the saturated case is exercised
    }
}
