// test_grid_skip.cpp: empty-space skipping in the exact traversal (docs/SPEC.md "Empty-space
// skipping"):
//  - the skip field's static distances are the Chebyshev distances to the nearest occupied cell,
//    against a 26-neighbour breadth-first search over the image (an independent construction);
//  - the dynamic boxes cover every cell that holds a dynamic reference, through updates;
//  - with skipping, every hit record equals the plain DDA's in every field but `cells`, and no
//    ray visits more cells, on every ray of a batch (random, axis-parallel and lattice-diagonal
//    rays, finite and infinite tmax), through animated updates.
#include <catch2/catch.hpp>

#include <deque>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using reference::GridOptions;
using reference::ReferenceGridTracer;
namespace sh = gridrt::shared;

namespace {

GridOptions skip_options(bool skip) {
  GridOptions o;
  o.threads = 2;
  o.traversal = reference::Traversal::exact;
  o.skip_empty = skip;
  o.skip_covered = false;  // skipping alone (covered cells: test_grid_covered.cpp)
  o.resolution = glm::uvec3(40, 36, 44);  // fine cells: room to skip (the automatic grid has few)
  return o;
}


// The static distances by breadth-first search over 26 neighbours from the cells holding a static
// reference (slot 0 below the comparison offset: the static references come first): within a box a
// Chebyshev path stays inside, so the BFS depth is the distance.
std::vector<uint32_t> bfs_distances(const reference::GridData& grid) {
  const sh::GridParams& g = grid.params;
  const uint32_t n = sh::grid_cell_count(g);
  std::vector<uint32_t> dist(n, ~0u);
  std::deque<uint32_t> queue;
  for (uint32_t i = 0; i < n; ++i)
    if (const std::vector<uint32_t> refs = reference::cell_references(grid, sh::cell_of_linear_index(g, i));
        !refs.empty() && refs.front() < g.comparison_offset) {
      dist[i] = 0;
      queue.push_back(i);
    }
  while (!queue.empty()) {
    const uint32_t i = queue.front();
    queue.pop_front();
    const glm::ivec3 c(sh::cell_of_linear_index(g, i));
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const glm::ivec3 m = c + glm::ivec3(dx, dy, dz);
          if (glm::any(glm::lessThan(m, glm::ivec3(0))) || glm::any(glm::greaterThanEqual(m, glm::ivec3(g.cells))))
            continue;
          const uint32_t j = sh::cell_linear_index(g, glm::uvec3(m));
          if (dist[j] != ~0u) continue;
          dist[j] = dist[i] + 1;
          queue.push_back(j);
        }
  }
  for (uint32_t& v : dist) v = std::min(v, sh::kSkipMaxDistance);
  return dist;
}

uint32_t static_distance(const reference::GridData& grid, uint32_t i) {
  return sh::skip_byte_distance((grid.skip[sh::skip_distance_word(i)] >> sh::skip_distance_shift(i)) & 0xFFu);
}

}  // namespace

TEST_CASE("The skip field's distances are the Chebyshev distances to the nearest reference", "[grid][skip]") {
  // Grids whose sides are multiples of the search's brick (kSkipBrick) and grids whose last bricks
  // are partial
  for (uint32_t seed : {3u, 8u, 9u}) {
    INFO("seed " << seed);
    const Scene scene = gridtest::random_scene(seed == 3u ? 40 : 300, 0.5f, 10.0f, seed, 20);
    REQUIRE(scene.static_instance_count() > 0);
    GridOptions o = skip_options(true);
    if (seed == 9u) o.resolution = glm::uvec3(41, 35, 47);
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    const reference::GridData& grid = ref.data();
    REQUIRE((grid.params.flags & sh::kGridSkipEmpty) != 0u);
    REQUIRE(grid.skip.size() == sh::skip_words(grid.params));
    const std::vector<uint32_t> want = bfs_distances(grid);
    size_t far = 0;
    for (uint32_t i = 0; i < sh::grid_cell_count(grid.params); ++i) {
      INFO("cell " << i);
      REQUIRE(static_distance(grid, i) == want[i]);
      far += want[i] >= 3;
    }
    CHECK(far > 0);  // the scene has room to skip
    // Every cell holding a dynamic reference is inside a dynamic box, through updates
    for (float time : {0.0f, 0.9f, 2.4f}) {
      if (time > 0.0f) ref.update(time);
      const uint32_t boxes = grid.skip[0];
      for (uint32_t i : reference::dirty_cells(grid)) {
        const glm::uvec3 c = sh::cell_of_linear_index(grid.params, i);
        uint32_t d = ~0u;
        for (uint32_t b = 0; b < boxes; ++b) {
          const uint32_t w = sh::skip_box_word(b);
          d = std::min(d, sh::skip_box_distance(c, {grid.skip[w], grid.skip[w + 1], grid.skip[w + 2]},
                                                {grid.skip[w + 4], grid.skip[w + 5], grid.skip[w + 6]}));
        }
        INFO("time " << time << " dirty cell " << i);
        REQUIRE(d == 0u);
      }
    }
  }
}

TEST_CASE("The skip field's distances past the cap and across partial bricks", "[grid][skip]") {
  const Scene scene = gridtest::far_apart_scene();
  for (const glm::uvec3 res : {glm::uvec3(601, 3, 2), glm::uvec3(530, 5, 7), glm::uvec3(258, 1, 1)}) {
    INFO("resolution " << gridtest::hx(res));
    GridOptions o = skip_options(true);
    o.resolution = res;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    const reference::GridData& grid = ref.data();
    REQUIRE(grid.params.cells == res);
    const std::vector<uint32_t> want = bfs_distances(grid);
    size_t capped = 0;
    for (uint32_t i = 0; i < sh::grid_cell_count(grid.params); ++i) {
      INFO("cell " << i);
      REQUIRE(static_distance(grid, i) == want[i]);
      capped += want[i] == sh::kSkipMaxDistance;
    }
    if (res.x > 600) CHECK(capped > 0);  // the middle cells lie 300 cells from either triangle
  }
}

TEST_CASE("Skipping: every hit record equals the plain DDA's but `cells`, never more cells", "[grid][skip]") {
  for (const char* name : {"random", "atrium"}) {
    INFO(name);
    const bool random = std::string(name) == "random";
    const Scene scene = random ? gridtest::random_scene(200, 0.6f, 10.0f, 21, 40) : make_builtin(name);
    ReferenceGridTracer plain(skip_options(false)), skip(skip_options(true));
    plain.build(scene, 0.0f);
    skip.build(scene, 0.0f);
    REQUIRE(plain.params().cells == skip.params().cells);
    REQUIRE((plain.params().flags & sh::kGridSkipEmpty) == 0u);
    for (float time : {0.0f, 0.7f, 2.2f}) {
      INFO("time " << time);
      if (time > 0.0f) {
        plain.update(time);
        skip.update(time);
      }
      const std::vector<Ray> rays = gridtest::walk_rays(plain.params(), 40 + uint32_t(time * 10));
      std::vector<Hit> want(rays.size()), got(rays.size());
      plain.trace(rays, want);
      skip.trace(rays, got);
      uint64_t cells_plain = 0, cells_skip = 0, hits = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        INFO("ray " << i << " " << gridtest::hx(rays[i]) << "\nplain " << gridtest::hx(want[i]) << "\nskip  "
                    << gridtest::hx(got[i]));
        Hit a = want[i], b = got[i];
        REQUIRE(b.cells <= a.cells);
        cells_plain += a.cells;
        cells_skip += b.cells;
        hits += !is_miss(a);
        INFO("tests " << a.tests << " / " << b.tests << " cells " << a.cells << " / " << b.cells);
        a.cells = b.cells = 0;
        if (std::memcmp(&a, &b, sizeof a) != 0) {
          for (const auto* t : {&plain, &skip}) {
            const reference::ExplainRecord rec = t->explain_ray(rays[i]);
            std::string line;
            for (const sh::ExplainEvent& e : rec.events)
              if (e.kind == sh::kEvCell || e.kind == sh::kEvSkip)
                line += (e.kind == sh::kEvSkip ? " S" + std::to_string(e.code) : " C") + std::string("(") +
                        std::to_string(e.cell.x) + "," + std::to_string(e.cell.y) + "," + std::to_string(e.cell.z) + ")";
            std::printf("%s\n", line.c_str());
          }
        }
        REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);
      }
      WARN(name << " time " << time << ": cells per ray " << double(cells_plain) / rays.size() << " plain, "
                << double(cells_skip) / rays.size() << " skipping; " << hits << " hits of " << rays.size());
      CHECK(hits > rays.size() / 50);
      CHECK(cells_skip < cells_plain);
    }
  }
}

// The ray's dynamic boxes (shared/grid.h, "The ray's dynamic boxes"): a box that the plain DDA walk
// of a ray visits a cell of is always "reached" (else a skip could pass a dynamic reference), on
// every ray of the skip batch (axis-parallel, lattice-diagonal, from inside and outside) against
// random boxes, boxes on the grid's faces and single cells; and the test is tight enough to pay: a
// box the walk never visits is mostly not reached.
TEST_CASE("Skipping: a dynamic box on a ray's plain walk is always reached, most others are not", "[grid][skip]") {
  ReferenceGridTracer plain(skip_options(false));
  plain.build(make_builtin("atrium"), 0.0f);
  const sh::GridParams& g = plain.params();
  std::mt19937 rng(7);
  std::vector<std::pair<glm::uvec3, glm::uvec3>> boxes;
  for (uint32_t b = 0; b < 48; ++b) {
    glm::uvec3 lo, hi;
    for (int a = 0; a < 3; ++a) {
      std::uniform_int_distribution<uint32_t> c(0, g.cells[a] - 1);
      uint32_t x = c(rng), y = c(rng);
      if (b % 4 == 1) y = x;                                  // one cell thick
      if (b % 4 == 2) x = 0, y = std::min(y, g.cells[a] / 4);  // on the lower face
      if (b % 4 == 3) y = g.cells[a] - 1;                      // on the upper face
      lo[a] = std::min(x, y);
      hi[a] = std::max(x, y);
    }
    boxes.push_back({lo, hi});
  }
  uint64_t visited = 0, unvisited = 0, unvisited_unreached = 0;
  for (const Ray& ray : gridtest::walk_rays(g, 99)) {
    sh::RaySetup rs;
    if (!sh::ray_setup(g, ray.org, ray.dir, ray.tmin, ray.tmax, rs)) continue;
    const glm::vec3 inv = sh::dda_inverse_direction(ray.dir);
    sh::DdaWalk w = sh::dda_walk_begin(g, ray.org, ray.dir, rs.t_start);
    const glm::uvec3 k0 = w.cell;
    std::vector<glm::uvec3> cells;
    for (uint32_t k = 0; k < g.max_segments; ++k) {
      sh::dda_walk_exits(g, ray.org, ray.dir, inv, 0u, w);
      cells.push_back(w.cell);
      if (w.t_exit >= rs.t_end || !sh::dda_walk_next(g, ray.org, ray.dir, inv, w)) break;
    }
    for (const auto& [lo, hi] : boxes) {
      bool on_walk = false;
      for (const glm::uvec3& c : cells) on_walk = on_walk || sh::skip_box_distance(c, lo, hi) == 0u;
      const bool reached = sh::skip_box_reached(g, ray.org, ray.dir, inv, k0, rs.t_end, lo, hi);
      INFO("ray " << gridtest::hx(ray) << " box " << lo.x << "," << lo.y << "," << lo.z << " .. " << hi.x << ","
                  << hi.y << "," << hi.z);
      if (on_walk) REQUIRE(reached);
      visited += on_walk;
      unvisited += !on_walk;
      unvisited_unreached += !on_walk && !reached;
    }
  }
  INFO(visited << " visited, " << unvisited << " unvisited, of them unreached " << unvisited_unreached);
  CHECK(visited > 5000);
  CHECK(double(unvisited_unreached) >= 0.9 * double(unvisited));
}
