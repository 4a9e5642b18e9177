// scene_trace against a double-precision brute force on analytic and random scenes; explain.
#include <catch2/catch.hpp>

#include "test_grid_util.h"

using namespace gridrt;
using namespace gridtest;
namespace sh = gridrt::shared;
using reference::GridOptions;
using reference::ReferenceGridTracer;

namespace {

std::vector<Ray> random_rays(uint32_t n, float extent, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> p(0.0f, extent), d(-1.0f, 1.0f);
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < n; ++i) {
    glm::vec3 dir(d(rng), d(rng), d(rng));
    if (glm::length(dir) < 1e-3f) dir = {1, 0, 0};
    rays.push_back(make_ray({p(rng), p(rng), p(rng)}, dir));
  }
  return rays;
}

struct Agreement {
  uint32_t rays = 0, same = 0, holes = 0, false_hits = 0, gap_fills = 0;
  double max_dt = 0.0;
  std::string first_difference;
};

Agreement compare(const reference::GridData& g, std::span<const Ray> rays, std::span<const Hit> hits) {
  Agreement a;
  for (size_t i = 0; i < rays.size(); ++i) {
    const RefHit want = brute_force(g, rays[i]);
    const Hit& got = hits[i];
    ++a.rays;
    if (got.flags & sh::kHitGapFill) ++a.gap_fills;
    const bool got_hit = !is_miss(got);
    bool same = got_hit == want.hit;
    if (same && got_hit) {
      same = got.instance == want.instance && got.triangle == want.triangle;
      // A tie in double precision (shared edges) counts as the same hit when t agrees
      if (!same && !(got.flags & sh::kHitGapFill)) same = std::abs(double(got.t) - want.t) <= 1e-5 * std::max(1.0, want.t);
      if (same) a.max_dt = std::max(a.max_dt, std::abs(double(got.t) - want.t));
    }
    if (same) ++a.same;
    else {
      if (want.hit && !got_hit) ++a.holes;
      if (got_hit && !want.hit) ++a.false_hits;
      if (a.first_difference.empty())
        a.first_difference = hx(rays[i]) + "\n got " + hx(got) + "\n want " + (want.hit ? "hit inst " + std::to_string(want.instance) + " tri " + std::to_string(want.triangle) + " t " + std::to_string(want.t) : "miss");
    }
  }
  return a;
}

// 3000 random rays through a grid of `o` over 400 random triangles, against the brute force.
Agreement random_triangles_agreement(const GridOptions& o) {
  const Scene scene = random_scene(400, 0.6f, 10.0f, 1);
  ReferenceGridTracer tracer(o);
  tracer.build(scene, 0.0f);
  const std::vector<Ray> rays = random_rays(3000, 10.0f, 2);
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  return compare(tracer.data(), rays, hits);
}

}  // namespace

TEST_CASE("Exact mode agrees with a double-precision brute force on random triangles", "[grid]") {
  GridOptions o;
  o.traversal = reference::Traversal::exact;
  o.threads = 2;
  const Agreement a = random_triangles_agreement(o);
  INFO("agree " << a.same << "/" << a.rays << " holes " << a.holes << " false " << a.false_hits << " first:\n"
                << a.first_difference);
  CHECK(a.gap_fills == 0);
  CHECK(a.same >= a.rays - 2);
  CHECK(a.max_dt < 1e-4);
}

TEST_CASE("Paper mode finds nearly every hit on random triangles", "[grid]") {
  GridOptions o;
  o.threads = 2;
  o.gap_fill = false;
  const Agreement a = random_triangles_agreement(o);
  INFO("agree " << a.same << "/" << a.rays << " holes " << a.holes << " false " << a.false_hits << " first:\n"
                << a.first_difference);
  CHECK(double(a.same) >= 0.97 * a.rays);
}

TEST_CASE("Rays with NaN or inf components miss with kHitRejected", "[grid][badinput]") {
  const Scene scene = random_scene(50, 0.6f, 10.0f, 1);
  GridOptions one_thread;
  one_thread.threads = 1;
  ReferenceGridTracer tracer(one_thread);
  tracer.build(scene, 0.0f);
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  std::vector<Ray> rays = {make_ray({nan, 0, 0}, {1, 0, 0}), make_ray({0, 0, 0}, {inf, 0, 0}),
                           make_ray({0, 0, 0}, {0, 0, 0}), make_ray({1, 1, 1}, {1, 0, 0}, nan)};
  std::vector<Hit> hits(rays.size());
  tracer.trace(rays, hits);
  for (size_t i = 0; i < rays.size(); ++i) {
    INFO(hx(rays[i]));
    CHECK(is_miss(hits[i]));
    CHECK(hits[i].flags == sh::kHitRejected);
  }
}

TEST_CASE("explain_ray records every step and to_text reads as the algorithm", "[grid]") {
  // One quad at z = 1 facing +z, hit straight on
  Scene s;
  s.name = "quad";
  Mesh m;
  m.positions = {{0, 0, 1}, {2, 0, 1}, {2, 2, 1}, {0, 2, 1}, {0, 0, -1}, {2, 2, -1}, {2, 0, -1}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}};
  m.materials = {0, 0, 0};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "quad", .mesh = 0});
  s.finalize();
  for (auto mode : {reference::Traversal::paper, reference::Traversal::exact}) {
    GridOptions o;
    o.traversal = mode;
    o.threads = 1;
    ReferenceGridTracer tracer(o);
    tracer.build(s, 0.0f);
    const Ray r = make_ray({0.5f, 1.5f, 3.0f}, {0.0f, 0.0f, -1.0f});
    const reference::ExplainRecord rec = tracer.explain_ray(r);
    const std::string text = reference::to_text(rec);
    INFO(text);
    REQUIRE_FALSE(is_miss(rec.hit));
    CHECK(rec.hit.instance == 0u);
    CHECK(rec.hit.triangle == 1u);
    CHECK(rec.hit.t == 2.0f);
    CHECK(text.find("ACCEPTED") != std::string::npos);
    CHECK(text.find("HIT at step") != std::string::npos);
    CHECK(text.find("[0x40000000]") != std::string::npos);  // t = 2 in hex bits
    CHECK(rec.events.front().kind == sh::kEvRay);
    CHECK(rec.events.back().kind == sh::kEvReport);
    // The same ray through trace() gives the same record
    Hit h;
    tracer.trace(std::span<const Ray>(&r, 1), std::span<Hit>(&h, 1));
    CHECK(std::memcmp(&h, &rec.hit, sizeof h) == 0);
  }
}
