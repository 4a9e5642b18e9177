// test_grid_covered.cpp: covered cells in the exact traversal (docs/SPEC.md "Covered cells"):
//  - a cell's cover bits say exactly which face neighbours' static runs hold every reference of its
//    own (non-empty) run, against the cells' reference lists compared as sets, with dense and
//    sparse offsets;
//  - with covered cells skipped, every hit record (closest and any hit) equals the one with every
//    cell's run tested in every field but `tests`, and no ray takes more tests, on every ray of a
//    batch (random, axis-parallel and lattice-diagonal rays, finite and infinite tmax), through
//    animated updates; and the skipped runs are reported in the ray's events.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstring>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using reference::GridOptions;
using reference::ReferenceGridTracer;
namespace sh = gridrt::shared;

namespace {

GridOptions covered_options(bool covered, glm::uvec3 res) {
  GridOptions o;
  o.threads = 2;
  o.traversal = reference::Traversal::exact;
  o.skip_covered = covered;
  o.resolution = res;
  return o;
}


// A cell's cover bits, from its skip byte (an occupied cell's: its distance is 0).
uint32_t cover_bits(const reference::GridData& grid, uint32_t i) {
  const uint32_t b = (grid.skip[sh::skip_distance_word(i)] >> sh::skip_distance_shift(i)) & 0xFFu;
  if (b >= sh::kSkipCoverTag) REQUIRE(sh::skip_byte_distance(b) == 0u);
  return sh::skip_byte_cover(b);
}

}  // namespace

TEST_CASE("Covered cells: the cover bits are the face neighbours whose runs hold the cell's", "[grid][covered]") {
  using Offsets = GridOptions::Offsets;
  for (const auto& [name, res, offsets] :
       {std::tuple{"random", glm::uvec3(40, 36, 44), Offsets::dense}, std::tuple{"random", glm::uvec3(23, 19, 31), Offsets::sparse},
        std::tuple{"atrium", glm::uvec3(48, 20, 30), Offsets::sparse}, std::tuple{"cornell", glm::uvec3(9, 9, 9), Offsets::dense}}) {
    INFO(name << " " << gridtest::hx(res));
    const std::string n = name;
    const Scene scene = n == "random" ? gridtest::random_scene(300, 0.6f, 10.0f, 5, 20) : make_builtin(n);
    GridOptions o = covered_options(true, res);
    o.offsets = offsets;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    const reference::GridData& grid = ref.data();
    const sh::GridParams& g = grid.params;
    REQUIRE((g.flags & sh::kGridSkipCovered) != 0u);
    REQUIRE((g.flags & sh::kGridCompact) != 0u);
    REQUIRE(((g.flags & sh::kGridSparseOffsets) != 0u) == (offsets == Offsets::sparse));
    REQUIRE(grid.skip.size() == sh::skip_words(g));
    size_t set = 0, occupied = 0;
    for (uint32_t i = 0; i < sh::grid_cell_count(g); ++i) {
      const glm::ivec3 c(sh::cell_of_linear_index(g, i));
      std::vector<uint32_t> own = reference::cell_references(grid, glm::uvec3(c));
      std::sort(own.begin(), own.end());
      occupied += !own.empty();
      uint32_t want = 0u;
      for (uint32_t f = 0; f < 6u; ++f) {
        glm::ivec3 m = c;
        m[f / 2] += f % 2 ? 1 : -1;
        if (own.empty() || glm::any(glm::lessThan(m, glm::ivec3(0))) ||
            glm::any(glm::greaterThanEqual(m, glm::ivec3(g.cells))))
          continue;
        std::vector<uint32_t> other = reference::cell_references(grid, glm::uvec3(m));
        std::sort(other.begin(), other.end());
        if (std::includes(other.begin(), other.end(), own.begin(), own.end())) want |= 1u << f;
      }
      INFO("cell " << i << " (" << c.x << ", " << c.y << ", " << c.z << ") with " << own.size() << " references");
      REQUIRE(cover_bits(grid, i) == want);
      set += want != 0u;
    }
    WARN(name << ": " << set << " of " << occupied << " occupied cells covered from some face");
    CHECK(set > 0);
  }
}

TEST_CASE("Covered cells: every hit record equals the one testing every run but `tests`, never more tests",
          "[grid][covered]") {
  for (const char* name : {"random", "atrium"}) {
    INFO(name);
    const bool random = std::string(name) == "random";
    const Scene scene = random ? gridtest::random_scene(200, 0.6f, 10.0f, 21, 40) : make_builtin(name);
    const glm::uvec3 res(40, 36, 44);
    ReferenceGridTracer all(covered_options(false, res)), covered(covered_options(true, res));
    all.build(scene, 0.0f);
    covered.build(scene, 0.0f);
    REQUIRE(all.params().cells == covered.params().cells);
    REQUIRE((all.params().flags & sh::kGridSkipCovered) == 0u);
    REQUIRE((covered.params().flags & sh::kGridSkipCovered) != 0u);
    for (float time : {0.0f, 0.7f, 2.2f}) {
      INFO("time " << time);
      if (time > 0.0f) {
        all.update(time);
        covered.update(time);
      }
      const std::vector<Ray> rays = gridtest::walk_rays(all.params(), 60 + uint32_t(time * 10));
      for (const bool any : {false, true}) {
        INFO((any ? "any hit" : "closest hit"));
        std::vector<Hit> want(rays.size()), got(rays.size());
        if (any) {
          all.trace_any(rays, want);
          covered.trace_any(rays, got);
        } else {
          all.trace(rays, want);
          covered.trace(rays, got);
        }
        uint64_t tests_all = 0, tests_covered = 0, hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
          INFO("ray " << i << " " << gridtest::hx(rays[i]) << "\nall     " << gridtest::hx(want[i]) << "\ncovered "
                      << gridtest::hx(got[i]));
          Hit a = want[i], b = got[i];
          REQUIRE(b.tests <= a.tests);
          tests_all += a.tests;
          tests_covered += b.tests;
          hits += !is_miss(a);
          a.tests = b.tests = 0;
          REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);
        }
        WARN(name << " time " << time << (any ? " any hit" : " closest") << ": tests per ray "
                  << double(tests_all) / rays.size() << " all, " << double(tests_covered) / rays.size()
                  << " covered skipped; " << hits << " hits of " << rays.size());
        CHECK(hits > rays.size() / 50);
        CHECK(tests_covered < tests_all);
      }
    }
    // The events: a covered cell reads none of its run, and says so
    size_t covered_events = 0;
    for (const Ray& r : gridtest::walk_rays(covered.params(), 7)) {
      const reference::ExplainRecord rec = covered.explain_ray(r);
      for (size_t k = 0; k < rec.events.size(); ++k) {
        if (rec.events[k].kind != sh::kEvCovered) continue;
        ++covered_events;
        REQUIRE(k > 0);
        REQUIRE(rec.events[k - 1].kind == sh::kEvCell);
        REQUIRE(rec.events[k].code < 6u);
        REQUIRE(rec.events[k].slot > 0u);
        if (k + 1 < rec.events.size()) REQUIRE(rec.events[k + 1].kind != sh::kEvSlot);
        if (covered_events > 2000) break;
      }
    }
    CHECK(covered_events > 0);
  }
}
