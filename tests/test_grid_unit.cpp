// Each step of the grid's shared math alone (common/shared/grid.h, triangle.h).
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "gridrt/common/shared/alpha.h"
#include "test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;

namespace {
sh::GridParams unit_grid(glm::uvec3 cells, uint32_t capacity, float cell_size = 1.0f, glm::vec3 origin = glm::vec3(0.0f)) {
  sh::GridParams g{};
  g.origin = origin;
  g.cell_size = cell_size;
  g.inv_cell_size = 1.0f / cell_size;
  g.cells = cells;
  g.capacity = capacity;
  g.upper = origin + glm::vec3(cells) * cell_size;
  g.sphere_r2 = float(std::pow(1.25 * cell_size * std::sqrt(3.0) / 2.0, 2.0));
  g.aabb_padding = 1e-3f;
  g.elongation = 0.25f;
  g.max_segments = cells.x + cells.y + cells.z + 3u;
  return g;
}
}  // namespace

TEST_CASE("References pack instance << 16 | triangle", "[unit][grid]") {
  CHECK(sh::ref_pack(0, 0) == 0u);
  CHECK(sh::ref_pack(3, 7) == 0x00030007u);
  CHECK(sh::ref_pack(65534, 65535) == 0xFFFEFFFFu);
  CHECK(sh::ref_pack(65534, 65535) != sh::kBlank);
  for (uint32_t i : {0u, 1u, 255u, 65534u})
    for (uint32_t t : {0u, 1u, 4095u, 65535u}) {
      const uint32_t r = sh::ref_pack(i, t);
      CHECK(sh::ref_instance(r) == i);
      CHECK(sh::ref_triangle(r) == t);
    }
}

TEST_CASE("Cell addressing: slots, status texel, extent, linear index", "[unit][grid]") {
  const sh::GridParams g = unit_grid({5, 3, 2}, 4);
  CHECK(sh::grid_image_extent(g) == glm::uvec3(25, 3, 2));
  CHECK(sh::slot_texel({0, 0, 0}, 0, 4) == glm::uvec3(0, 0, 0));
  CHECK(sh::slot_texel({2, 1, 1}, 3, 4) == glm::uvec3(13, 1, 1));
  CHECK(sh::status_texel({2, 1, 1}, 4) == glm::uvec3(14, 1, 1));
  CHECK(sh::status_texel({4, 2, 1}, 4) == glm::uvec3(24, 2, 1));  // the last texel of a row
  CHECK(sh::texel_index({24, 2, 1}, {25, 3, 2}) == 25u * 3u * 2u - 1u);
  CHECK(sh::texel_index({1, 1, 0}, {25, 3, 2}) == 26u);
}

TEST_CASE("Cell of a point: floor, boundaries, clamping of huge and non-finite values", "[unit][grid]") {
  const sh::GridParams g = unit_grid({4, 4, 4}, 4, 0.5f, {-1.0f, 0.0f, 2.0f});
  CHECK(sh::cell_of_point(g, {-1.0f, 0.0f, 2.0f}) == glm::uvec3(0, 0, 0));
  CHECK(sh::cell_of_point(g, {-0.5f, 0.5f, 2.5f}) == glm::uvec3(1, 1, 1));  // on a face: the upper cell
  CHECK(sh::cell_of_point(g, {-0.5000001f, 0.4999999f, 2.4999998f}) == glm::uvec3(0, 0, 0));
  CHECK(sh::cell_of_point(g, {0.999f, 1.999f, 3.999f}) == glm::uvec3(3, 3, 3));
  CHECK(sh::cell_of_point(g, {1.0f, 2.0f, 4.0f}) == glm::uvec3(3, 3, 3));  // the far face clamps
  const float inf = std::numeric_limits<float>::infinity();
  CHECK(sh::cell_of_point(g, {1e30f, -1e30f, 3e38f}) == glm::uvec3(3, 0, 3));
  CHECK(sh::cell_of_point(g, {inf, -inf, 1e10f}) == glm::uvec3(3, 0, 3));
  CHECK(sh::grid_contains(g, {-1.0f, 0.0f, 2.0f}));
  CHECK_FALSE(sh::grid_contains(g, {1.0f, 0.5f, 2.5f}));
  CHECK_FALSE(sh::grid_contains(g, {-1.0000001f, 0.5f, 2.5f}));
  CHECK(sh::cell_center(g, {1, 2, 3}) == glm::vec3(-0.25f, 1.25f, 3.75f));
}

TEST_CASE("A triangle's cell range pads its AABB so that a face-touching triangle is in both cells", "[unit][grid]") {
  const sh::GridParams g = unit_grid({4, 4, 4}, 4);
  glm::uvec3 lo, hi;
  // The triangle lies in the plane x = 2, the face between cells x=1 and x=2
  sh::triangle_cell_range(g, {2.0f, 0.2f, 0.2f}, {2.0f, 0.8f, 0.2f}, {2.0f, 0.2f, 0.8f}, lo, hi);
  CHECK(lo == glm::uvec3(1, 0, 0));
  CHECK(hi == glm::uvec3(2, 0, 0));
  // Well inside one cell
  sh::triangle_cell_range(g, {2.5f, 1.2f, 3.2f}, {2.6f, 1.8f, 3.2f}, {2.5f, 1.2f, 3.8f}, lo, hi);
  CHECK(lo == glm::uvec3(2, 1, 3));
  CHECK(hi == glm::uvec3(2, 1, 3));
}

TEST_CASE("The cell test's decisions do not depend on the model's scale (models 1e-5 to 1e-7 across)", "[unit][grid]") {
  // The same triangles and grid, scaled by 2^-20, 2^-24 and 2^-26 (exact): every decision the
  // same. In world units the test's products fall into denormals there (s*s below 1e-38), where
  // a device may flush them (lavapipe's geometry shaders: the raster build differed from the
  // reference on a model 1e-6 across) and where even the CPU's gradual underflow rounds them
  // coarsely; in the cell test's unit they stay normal.
  const sh::GridParams g = unit_grid({8, 8, 8}, 4, 0.75f, glm::vec3(-3.0f));
  for (const int e : {-20, -24, -26}) {
    INFO("scale 2^" << e);
    const float k = std::ldexp(1.0f, e);
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> p(-3.0f, 3.0f), small(-0.05f, 0.05f);
    const sh::GridParams gk = unit_grid({8, 8, 8}, 4, 0.75f * k, glm::vec3(-3.0f * k));
    REQUIRE(gk.sphere_r2 == g.sphere_r2 * k * k);
    REQUIRE(sh::cell_test_scale(gk) == sh::cell_test_scale(g) / k);
    uint64_t decided = 0, world_units_differ = 0;
    for (int i = 0; i < 2000; ++i) {
      // Large triangles and small ones (a tenth of a cell)
      const glm::vec3 v0(p(rng), p(rng), p(rng));
      const glm::vec3 v1 = i % 2 ? glm::vec3(p(rng), p(rng), p(rng)) : v0 + glm::vec3(small(rng), small(rng), small(rng));
      const glm::vec3 v2 = i % 2 ? glm::vec3(p(rng), p(rng), p(rng)) : v0 + glm::vec3(small(rng), small(rng), small(rng));
      const glm::vec3 n = sh::triangle_normal(v0, v1, v2), nk = sh::triangle_normal(v0 * k, v1 * k, v2 * k);
      glm::uvec3 lo, hi;
      sh::triangle_cell_range(g, v0, v1, v2, lo, hi);
      for (uint32_t z = lo.z; z <= hi.z; ++z)
        for (uint32_t y = lo.y; y <= hi.y; ++y)
          for (uint32_t x = lo.x; x <= hi.x; ++x) {
            const glm::uvec3 c(x, y, z);
            const bool want = sh::triangle_overlaps_cell(g, v0, v1, v2, n, c);
            REQUIRE(sh::triangle_overlaps_cell(gk, v0 * k, v1 * k, v2 * k, nk, c) == want);
            ++decided;
            // The world-unit evaluation at the small scale (the test before its unit)
            const float s = sh::sh_dot(nk, sh::cell_center(gk, c) - v0 * k);
            world_units_differ += (s * s <= gk.sphere_r2 * sh::sh_dot(nk, nk)) != want;
          }
    }
    CHECK(decided > 5000);
    if (e == -26) CHECK(world_units_differ > 0);  // the hazard is real at this scale
  }
}

TEST_CASE("Plane vs enlarged sphere agrees with a double-precision distance check", "[unit][grid]") {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> p(-3.0f, 3.0f);
  const float cs = 0.75f;
  const sh::GridParams g = unit_grid({8, 8, 8}, 4, cs, glm::vec3(-3.0f));
  const double r = 1.25 * cs * std::sqrt(3.0) / 2.0;
  int disagreements = 0, tested = 0;
  for (int i = 0; i < 20000; ++i) {
    const glm::vec3 v0(p(rng), p(rng), p(rng)), v1(p(rng), p(rng), p(rng)), v2(p(rng), p(rng), p(rng));
    const glm::uvec3 cell(rng() % 8, rng() % 8, rng() % 8);
    const glm::vec3 c = sh::cell_center(g, cell);
    const glm::vec3 n = sh::triangle_normal(v0, v1, v2);
    const bool got = sh::plane_intersects_enlarged_sphere(v0, n, c, g.sphere_r2, sh::cell_test_scale(g));
    const glm::dvec3 nd = glm::cross(glm::dvec3(v1) - glm::dvec3(v0), glm::dvec3(v2) - glm::dvec3(v0));
    const double dist = std::abs(glm::dot(glm::normalize(nd), glm::dvec3(c) - glm::dvec3(v0)));
    const bool want = dist <= r;
    ++tested;
    if (got != want) {
      ++disagreements;
      // Only within a tiny relative band around the sphere's surface
      INFO("v0 " << hx(v0) << " v1 " << hx(v1) << " v2 " << hx(v2) << " cell " << hx(cell) << " dist " << dist);
      CHECK(std::abs(dist - r) < 1e-5 * r);
    }
  }
  CHECK(disagreements <= tested / 1000);
}

namespace {
// Whether the triangle (local coordinates, double) meets the box [m - h, m + h]: the triangle
// clipped against the box's six planes (Sutherland-Hodgman, in double) keeps a point. Points on a
// plane are kept, so a touching triangle overlaps.
bool clip_overlap(const std::array<glm::dvec3, 3>& tri, glm::dvec3 m, double h) {
  std::vector<glm::dvec3> poly(tri.begin(), tri.end());
  for (int axis = 0; axis < 3 && !poly.empty(); ++axis)
    for (double side : {-1.0, 1.0}) {
      // Keep side * (p[axis] - m[axis]) <= h
      const auto inside = [&](const glm::dvec3& p) { return side * (p[axis] - m[axis]) <= h; };
      std::vector<glm::dvec3> out;
      for (size_t i = 0; i < poly.size(); ++i) {
        const glm::dvec3 a = poly[i], b = poly[(i + 1) % poly.size()];
        if (inside(a)) out.push_back(a);
        if (inside(a) != inside(b)) {
          const double s = (side * h + m[axis] - a[axis]) / (b[axis] - a[axis]);
          glm::dvec3 q = a + s * (b - a);
          q[axis] = m[axis] + side * h;
          out.push_back(q);
        }
      }
      poly = std::move(out);
    }
  return !poly.empty();
}
}  // namespace

TEST_CASE("The separating-axis cell test keeps every cell a double-precision clip says the triangle meets, and "
          "drops those it misses by more than 0.01 cell", "[unit][grid]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  struct Grid {
    float cs;
    glm::vec3 origin;
  };
  // Unit cells at the origin; small cells far from it (coarse ulps relative to a cell)
  for (const Grid& gd : {Grid{1.0f, glm::vec3(0.0f)}, Grid{0.37f, glm::vec3(-1000.5f, 3000.25f, 77.0f)}}) {
    sh::GridParams g = unit_grid({8, 8, 8}, 4, gd.cs, gd.origin);
    g.flags = sh::kGridCellBox;
    const glm::uvec3 cell(3, 4, 2);
    const glm::dvec3 m = glm::dvec3(cell) + 0.5;
    uint64_t kept = 0, dropped = 0, far = 0;
    for (int i = 0; i < 40000; ++i) {
      // Vertices in local coordinates around the cell: random, snapped to cell planes, a corner's
      // plane x + y + z = const (the box touches the triangle at a corner or an edge)
      std::array<glm::vec3, 3> f;
      const int family = i % 4;
      const float spread = i % 3 == 0 ? 0.6f : (i % 3 == 1 ? 3.0f : 40.0f);
      for (glm::vec3& v : f)
        v = glm::vec3(m) + spread * (glm::vec3(u(rng), u(rng), u(rng)) * 2.0f - 1.0f);
      if (family == 1)
        for (glm::vec3& v : f) v[rng() % 3] = float(cell[rng() % 3] + (rng() % 2));
      if (family == 2) {
        const float k = float(cell.x + cell.y + cell.z + 1u + rng() % 2u);
        for (glm::vec3& v : f) v.z = k - v.x - v.y;
      }
      if (family == 3) f[2] = f[0] + (f[1] - f[0]) * 1.0e-3f * u(rng);  // a sliver
      // World vertices; the test and the truth both see the local coordinates the grid computes
      std::array<glm::vec3, 3> w;
      std::array<glm::dvec3, 3> local;
      for (int k = 0; k < 3; ++k) {
        w[k] = g.origin + f[k] * gd.cs;
        local[k] = glm::dvec3(sh::grid_local(g, w[k]));
      }
      if (sh::triangle_zero_area(w[0], w[1], w[2])) continue;
      // The box's own axes are the cell range's; the test adds the plane and the edge products
      glm::uvec3 lo, hi;
      sh::triangle_cell_range(g, w[0], w[1], w[2], lo, hi);
      const bool in_range = glm::all(glm::greaterThanEqual(cell, lo)) && glm::all(glm::lessThanEqual(cell, hi));
      const bool got = in_range && sh::triangle_box_overlap(g, w[0], w[1], w[2], cell);
      INFO("grid " << gd.cs << " v0 " << hx(w[0]) << " v1 " << hx(w[1]) << " v2 " << hx(w[2]));
      if (clip_overlap(local, m, 0.5)) {
        CHECK(got);  // conservative: a cell the triangle meets is never dropped
      } else if (!clip_overlap(local, m, 0.51)) {
        ++far;
        CHECK_FALSE(got);  // tight: a triangle clear of the cell by 0.01 is dropped
      }
      (got ? kept : dropped) += 1;
    }
    // Every family produced both outcomes and the tight branch ran
    CHECK(kept > 1000);
    CHECK(dropped > 1000);
    CHECK(far > 1000);
  }
}

TEST_CASE("The cell test: the sphere test alone without kGridCellBox, a subset of it with", "[unit][grid]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> p(-3.0f, 3.0f);
  sh::GridParams g = unit_grid({8, 8, 8}, 4, 0.75f, glm::vec3(-3.0f));
  sh::GridParams box = g;
  box.flags |= sh::kGridCellBox;
  uint64_t sphere_cells = 0, box_cells = 0;
  for (int i = 0; i < 2000; ++i) {
    const glm::vec3 v0(p(rng), p(rng), p(rng)), v1(p(rng), p(rng), p(rng)), v2(p(rng), p(rng), p(rng));
    const glm::vec3 n = sh::triangle_normal(v0, v1, v2);
    glm::uvec3 lo, hi;
    sh::triangle_cell_range(g, v0, v1, v2, lo, hi);
    for (uint32_t z = lo.z; z <= hi.z; ++z)
      for (uint32_t y = lo.y; y <= hi.y; ++y)
        for (uint32_t x = lo.x; x <= hi.x; ++x) {
          const bool s = sh::triangle_overlaps_cell(g, v0, v1, v2, n, {x, y, z});
          const bool b = sh::triangle_overlaps_cell(box, v0, v1, v2, n, {x, y, z});
          CHECK(s == sh::plane_intersects_enlarged_sphere(v0, n, sh::cell_center(g, {x, y, z}), g.sphere_r2, sh::cell_test_scale(g)));
          CHECK(b == (s && sh::triangle_box_overlap(box, v0, v1, v2, {x, y, z})));
          sphere_cells += s;
          box_cells += b;
        }
  }
  // The box test is tighter on large random triangles
  CHECK(box_cells < sphere_cells);
}

TEST_CASE("Moller-Trumbore: analytic cases and every outcome code", "[unit][grid]") {
  const glm::vec3 v0(0, 0, 0), v1(1, 0, 0), v2(0, 1, 0);
  const float inf = std::numeric_limits<float>::infinity();
  sh::TriangleTest r;
  // Straight down onto (0.25, 0.25): t = 2, front face (det > 0 for a ray against the normal +z)
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestAccepted);
  CHECK(r.det > 0.0f);
  CHECK(sh::moller_trumbore_t(r) == 2.0f);
  CHECK(r.u_det / std::abs(r.det) == 0.25f);
  CHECK(r.v_det / std::abs(r.det) == 0.25f);
  // From below: back face, same t
  CHECK(sh::moller_trumbore({0.25f, 0.25f, -2.0f}, {0, 0, 1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestAccepted);
  CHECK(r.det < 0.0f);
  CHECK(sh::moller_trumbore_t(r) == 2.0f);
  // Direction units: a direction of length 2 halves t
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -2}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestAccepted);
  CHECK(sh::moller_trumbore_t(r) == 1.0f);
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {1, 0, 0}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestParallel);
  CHECK(sh::moller_trumbore({-0.1f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestOutsideU);
  CHECK(sh::moller_trumbore({0.25f, -0.1f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestOutsideV);
  CHECK(sh::moller_trumbore({0.6f, 0.6f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestOutsideUV);
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 2.0f, inf, inf, r) == sh::kTestBehind);
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, 2.0f, inf, r) == sh::kTestBeyond);
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, 3.0f, 1.5f, r) == sh::kTestNotCloser);
  CHECK(sh::moller_trumbore({0.25f, 0.25f, 2.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, 3.0f, 2.0f, r) == sh::kTestAccepted);
  // On an edge and a vertex: inside (closed triangle)
  CHECK(sh::moller_trumbore({0.5f, 0.0f, 1.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestAccepted);
  CHECK(sh::moller_trumbore({0.0f, 0.0f, 1.0f}, {0, 0, -1}, v0, v1, v2, 0.0f, inf, inf, r) == sh::kTestAccepted);
}

TEST_CASE("Moller-Trumbore's division-free decisions agree with double precision on random triangles", "[unit][grid]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> p(-1.0f, 1.0f);
  int disagreements = 0;
  const int n = 50000;
  for (int i = 0; i < n; ++i) {
    const glm::vec3 v0(p(rng), p(rng), p(rng)), v1(p(rng), p(rng), p(rng)), v2(p(rng), p(rng), p(rng));
    const glm::vec3 o(p(rng) * 3.0f, p(rng) * 3.0f, p(rng) * 3.0f);
    const glm::vec3 target(p(rng), p(rng), p(rng));
    const glm::vec3 d = target - o;
    const float tlo = 0.1f, thi = 0.9f;
    sh::TriangleTest r;
    const bool got = sh::moller_trumbore(o, d, v0, v1, v2, tlo, thi, INFINITY, r) == sh::kTestAccepted;
    // Double precision, with the distance of the decision to its nearest boundary
    const glm::dvec3 od(o), dd(d), a(v0), e1 = glm::dvec3(v1) - a, e2 = glm::dvec3(v2) - a;
    const glm::dvec3 pv = glm::cross(dd, e2);
    const double det = glm::dot(e1, pv);
    const glm::dvec3 s = od - a, q = glm::cross(s, e1);
    const double u = glm::dot(s, pv) / det, v = glm::dot(dd, q) / det, t = glm::dot(e2, q) / det;
    const bool want = u >= 0 && v >= 0 && u + v <= 1 && t > tlo && t < thi;
    const double margin = std::min({std::abs(u), std::abs(v), std::abs(1 - u - v), std::abs(t - tlo), std::abs(t - thi)});
    if (got != want) {
      ++disagreements;
      INFO("org " << hx(o) << " dir " << hx(d) << " v0 " << hx(v0) << " v1 " << hx(v1) << " v2 " << hx(v2)
                  << " u " << u << " v " << v << " t " << t);
      CHECK(margin < 1e-5);
    }
    if (got && want && std::abs(double(sh::moller_trumbore_t(r)) - t) > 1e-5 * std::max(1.0, std::abs(t))) {
      INFO("org " << hx(o) << " dir " << hx(d) << " t " << t);
      CHECK(double(sh::moller_trumbore_t(r)) == Approx(t));
    }
  }
  CHECK(disagreements < n / 5000);
}

TEST_CASE("Cramer's-rule barycentrics match Moller-Trumbore's", "[unit][grid]") {
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> p(-1.0f, 1.0f);
  int checked = 0;
  for (int i = 0; i < 200000 && checked < 3000; ++i) {
    const glm::vec3 v0(p(rng), p(rng), p(rng)), v1(p(rng), p(rng), p(rng)), v2(p(rng), p(rng), p(rng));
    const glm::vec3 o(p(rng) * 3.0f, p(rng) * 3.0f, 3.0f), d = glm::vec3(p(rng), p(rng), p(rng)) - o;
    sh::TriangleTest r;
    if (sh::moller_trumbore(o, d, v0, v1, v2, 0.0f, INFINITY, INFINITY, r) != sh::kTestAccepted) continue;
    // Skip slivers, where both methods lose digits
    const glm::vec3 n = sh::triangle_normal(v0, v1, v2);
    if (glm::length(n) < 0.05f) continue;
    ++checked;
    const float t = sh::moller_trumbore_t(r);
    const glm::vec2 bc = sh::cramer_barycentrics(v0, v1, v2, sh::point_at(o, d, t));
    const float ad = std::abs(r.det);
    if (std::abs(bc.x - r.u_det / ad) >= 2e-4f || std::abs(bc.y - r.v_det / ad) >= 2e-4f) {
      INFO("org " << hx(o) << " dir " << hx(d) << " v0 " << hx(v0) << " v1 " << hx(v1) << " v2 " << hx(v2));
      CHECK(bc.x == Approx(r.u_det / ad));
      CHECK(bc.y == Approx(r.v_det / ad));
    }
  }
  CHECK(checked == 3000);
}

TEST_CASE("Paper segments: one cell edge in t units, midpoint samples, elongation", "[unit][grid]") {
  const sh::GridParams g = unit_grid({10, 10, 10}, 4, 0.5f);
  sh::RaySetup rs;
  // Direction of length 2: one cell edge (0.5) is 0.25 in t
  REQUIRE(sh::ray_setup(g, {0.1f, 0.1f, 0.1f}, {2.0f, 0.0f, 0.0f}, 0.0f, INFINITY, rs));
  CHECK(rs.seg_t == 0.25f);
  CHECK(rs.t_start == 0.0f);
  CHECK(rs.t_end == 2.45f);  // x leaves the grid at 5.0: (5.0 - 0.1) / 2
  CHECK(sh::segment_begin(rs, 3) == 0.75f);
  CHECK(sh::segment_end(rs, 3) == 1.0f);
  CHECK(sh::segment_sample_t(rs, 3) == 0.875f);
  CHECK(sh::segment_elongated_begin(g, rs, 3) == 0.6875f);
  CHECK(sh::segment_elongated_end(g, rs, 3) == 1.0625f);
  // A ray from outside starts at the grid's entry
  REQUIRE(sh::ray_setup(g, {-1.0f, 1.0f, 1.0f}, {1.0f, 0.0f, 0.0f}, 0.0f, INFINITY, rs));
  CHECK(rs.t_start == 1.0f);
  CHECK(rs.t_end == 6.0f);
  CHECK_FALSE(sh::ray_setup(g, {-1.0f, 1.0f, 1.0f}, {-1.0f, 0.0f, 0.0f}, 0.0f, INFINITY, rs));
  CHECK_FALSE(sh::ray_setup(g, {-1.0f, 1.0f, 1.0f}, {1.0f, 0.0f, 0.0f}, 0.0f, 0.5f, rs));
  CHECK_FALSE(sh::ray_setup(g, {-1.0f, 6.0f, 1.0f}, {1.0f, 0.0f, 0.0f}, 0.0f, INFINITY, rs));
  // From the box's face outward: the slab's (lo - o) * inv is -0, which min and max may pass on
  // or not (a GPU's differed from C++'s); the setup's zeros are +0 (an outside sweep's find)
  (void)sh::ray_setup(g, {0.0f, 1.0f, 1.0f}, {-1.0f, 0.0f, 0.0f}, 0.0f, INFINITY, rs);
  CHECK(glm::floatBitsToUint(rs.t_end) == 0u);
  CHECK(glm::floatBitsToUint(rs.t_start) == 0u);
}

// An outside sweep's find: uvs of +-3e38 interpolate to infinities, frac() of which is NaN, and
// max(NaN, 0) and a NaN's conversion to uint are either or undefined on a GPU: texel 0 now, by a
// comparison; every finite uv keeps its texel.
TEST_CASE("The uv rule: an infinite or NaN uv reads texel 0, finite ones their texel", "[unit][alpha]") {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  for (const glm::vec2 uv : {glm::vec2(inf, 0.5f), glm::vec2(-inf, 0.5f), glm::vec2(0.5f, inf), glm::vec2(nan, nan)}) {
    const glm::uvec2 xy = sh::alpha_texel_coords(uv, 7, 5);
    CHECK(xy.x < 7);
    CHECK(xy.y < 5);
    if (!std::isfinite(uv.x)) CHECK(xy.x == 0u);
    if (!std::isfinite(uv.y)) CHECK(xy.y == 0u);
  }
  // Finite uvs: u in [0, 1) spans the columns, v = 0 the last row, v just below 1 the first
  CHECK(sh::alpha_texel_coords({0.0f, 0.0f}, 7, 5) == glm::uvec2(0, 4));
  CHECK(sh::alpha_texel_coords({0.99f, 0.99f}, 7, 5) == glm::uvec2(6, 0));
  CHECK(sh::alpha_texel_coords({0.5f, 0.5f}, 7, 5) == glm::uvec2(3, 2));
  CHECK(sh::alpha_texel_coords({-0.25f, 2.25f}, 8, 4) == glm::uvec2(6, 3));
}

TEST_CASE("Ray validation rejects NaN, inf and zero directions", "[unit][grid]") {
  const float inf = std::numeric_limits<float>::infinity(), nan = std::numeric_limits<float>::quiet_NaN();
  CHECK(sh::ray_valid({0, 0, 0}, {1, 0, 0}, 0.0f, inf));
  CHECK_FALSE(sh::ray_valid({nan, 0, 0}, {1, 0, 0}, 0.0f, inf));
  CHECK_FALSE(sh::ray_valid({0, inf, 0}, {1, 0, 0}, 0.0f, inf));
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {1, 0, -inf}, 0.0f, inf));
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {0, 0, 0}, 0.0f, inf));
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {1e-30f, 0, 0}, 0.0f, inf));  // dot(dir, dir) underflows to 0
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {1e30f, 0, 0}, 0.0f, inf));   // dot(dir, dir) overflows
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {1, 0, 0}, nan, inf));
  CHECK_FALSE(sh::ray_valid({0, 0, 0}, {1, 0, 0}, 0.0f, nan));
}

TEST_CASE("Gap-fill's left-the-surface test: projection onto the launch normal", "[unit][grid]") {
  glm::vec2 vals;
  // Normal of length 2, distance 1.5 along it: 1.5^2 >= 1.0^2
  CHECK(sh::gap_fill_left_surface({5.0f, 1.5f, 0.0f}, {0, 0, 0}, {0, 2, 0}, 1.0f, vals));
  CHECK_FALSE(sh::gap_fill_left_surface({5.0f, 0.5f, 0.0f}, {0, 0, 0}, {0, 2, 0}, 1.0f, vals));
  CHECK(sh::gap_fill_left_surface({5.0f, -1.5f, 0.0f}, {0, 0, 0}, {0, 2, 0}, 1.0f, vals));  // either side
  // Without a launch normal: the distance from the origin
  CHECK(sh::gap_fill_left_surface({0.6f, 0.8f, 0.0f}, {0, 0, 0}, {0, 0, 0}, 1.0f, vals));
  CHECK_FALSE(sh::gap_fill_left_surface({0.6f, 0.7f, 0.0f}, {0, 0, 0}, {0, 0, 0}, 1.0f, vals));
}

namespace {
// Cells the DDA visits, with the ray inside the grid from t_start.
std::vector<glm::uvec3> dda_cells(const sh::GridParams& g, const Ray& r) {
  std::vector<glm::uvec3> out;
  sh::RaySetup rs;
  if (!sh::ray_setup(g, r.org, r.dir, r.tmin, r.tmax, rs)) return out;
  const glm::vec3 inv = sh::dda_inverse_direction(r.dir);
  glm::uvec3 cell = sh::cell_of_point(g, sh::point_at(r.org, r.dir, rs.t_start));
  for (uint32_t k = 0; k < g.max_segments; ++k) {
    out.push_back(cell);
    const glm::vec3 ex = sh::dda_exits(g, r.org, r.dir, inv, cell);
    if (sh::dda_cell_exit(ex) >= rs.t_end) break;
    if (!sh::dda_step(g, r.dir, sh::dda_step_axis(ex), cell)) break;
  }
  return out;
}
// The length of the ray's parameter interval inside a cell, in double precision (slab test).
double pierce(const sh::GridParams& g, const Ray& r, glm::uvec3 c) {
  double t0 = r.tmin, t1 = r.tmax;
  for (int a = 0; a < 3; ++a) {
    const double lo = double(g.origin[a]) + double(c[a]) * g.cell_size, hi = lo + g.cell_size;
    const double o = r.org[a], d = r.dir[a];
    if (d == 0.0) {
      if (o < lo || o > hi) return -1.0;
      continue;
    }
    const double ta = (lo - o) / d, tb = (hi - o) / d;
    t0 = std::max(t0, std::min(ta, tb));
    t1 = std::min(t1, std::max(ta, tb));
  }
  return t1 - t0;
}
}  // namespace

TEST_CASE("The DDA visits exactly the cells a double-precision slab test says the ray pierces", "[unit][grid]") {
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> p(-2.0f, 8.0f), d(-1.0f, 1.0f);
  const sh::GridParams g = unit_grid({6, 5, 7}, 4, 0.75f, {0.5f, -0.25f, 0.0f});
  for (int i = 0; i < 3000; ++i) {
    Ray r = make_ray({p(rng), p(rng), p(rng)}, {d(rng), d(rng), d(rng)}, 0.0f, 4.0f + 10.0f * d(rng));
    if (i % 10 == 0) r.dir[i % 3] = 0.0f;  // axis-parallel components
    const std::vector<glm::uvec3> visited = dda_cells(g, r);
    const double len = glm::length(glm::dvec3(r.dir));
    for (uint32_t z = 0; z < g.cells.z; ++z)
      for (uint32_t y = 0; y < g.cells.y; ++y)
        for (uint32_t x = 0; x < g.cells.x; ++x) {
          const glm::uvec3 c(x, y, z);
          const double in = pierce(g, r, c) * len;  // world length inside the cell
          const bool was = std::find(visited.begin(), visited.end(), c) != visited.end();
          if ((in > 1e-4 && !was) || (in < -1e-4 && was)) {
            INFO(hx(r) << " cell " << hx(c) << " inside " << in);
            CHECK(was == (in > 0.0));
          }
        }
    // Visited cells are distinct and adjacent (one axis, one step)
    for (size_t k = 1; k < visited.size(); ++k) {
      const glm::ivec3 step = glm::ivec3(visited[k]) - glm::ivec3(visited[k - 1]);
      if (std::abs(step.x) + std::abs(step.y) + std::abs(step.z) != 1) {
        INFO(hx(r) << " step " << k);
        CHECK(std::abs(step.x) + std::abs(step.y) + std::abs(step.z) == 1);
      }
    }
  }
}
