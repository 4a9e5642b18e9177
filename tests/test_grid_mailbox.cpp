// test_grid_mailbox.cpp: the exact traversal's mailbox (kGridMailbox; docs/SPEC.md "Mailbox"):
//  - the shared mailbox holds the last kMailboxSize references put, newest first;
//  - with the mailbox, every hit record equals the mailbox-off trace's in every field but `tests`,
//    and no ray makes more tests, on every ray of a batch: built-in scenes, a fan of triangles
//    about one vertex (a triangle in many cells along a ray), random scenes with a moving
//    instance through updates, both layouts, with and without empty-space skipping, and a real
//    scene with random rays (and rays launched from its surfaces);
//  - the explained ray's events are the mailbox-off ones where each skipped re-test is a test
//    event of code kTestMailboxed (and the alpha event of that re-test is gone), named by the
//    text and JSON formatters;
//  - the paper traversal never takes it.
#include <catch2/catch.hpp>

#include <cstring>
#include <filesystem>
#include <random>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/plan/explain_format.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
namespace sh = gridrt::shared;

namespace {

// Rays over the grid's box (10 % around it): from random points at random triangles' points (3 in
// 8), at random points (1 in 8, half with a finite tmax), and launched from a random triangle's
// point with its reference and normal into either side (1 in 2, as the frame's bounce rays).
std::vector<Ray> mailbox_rays(const reference::GridData& g, uint32_t count, uint32_t seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f), box(-0.1f, 1.1f), d(-1.0f, 1.0f);
  const glm::vec3 lo = g.params.origin, ext = g.params.upper - g.params.origin;
  const auto tri_point = [&](uint32_t& ref, glm::vec3& n) {
    const uint32_t inst = std::uniform_int_distribution<uint32_t>(0, uint32_t(g.instances.size() - 1))(rng);
    const sh::GridInstance& gi = g.instances[inst];
    const uint32_t k = std::uniform_int_distribution<uint32_t>(0, gi.tri_count - 1)(rng);
    const sh::GridTriangle& t = g.triangles[gi.tri_offset + k];
    float a = unit(rng), b = unit(rng);
    if (a + b > 1.0f) a = 1.0f - a, b = 1.0f - b;
    ref = (inst << 16) | k;
    n = glm::cross(t.v1 - t.v0, t.v2 - t.v0);
    return t.v0 + a * (t.v1 - t.v0) + b * (t.v2 - t.v0);
  };
  std::vector<Ray> rays;
  for (uint32_t i = 0; i < count; ++i) {
    uint32_t ref = 0;
    glm::vec3 n(0.0f);
    if (i % 2 == 1) {
      const glm::vec3 o = tri_point(ref, n);
      glm::vec3 dir(d(rng), d(rng), d(rng));
      if (glm::dot(dir, dir) < 1e-6f) dir = glm::vec3(0.0f, 0.0f, 1.0f);
      if (glm::dot(dir, n) < 0.0f) n = -n;
      Ray r = gridtest::make_ray(o, dir);
      r.launch_ref = ref;
      r.launch_normal = glm::dot(n, n) > 0.0f ? glm::normalize(n) : glm::vec3(0.0f);
      rays.push_back(r);
      continue;
    }
    const glm::vec3 o = lo + ext * glm::vec3(box(rng), box(rng), box(rng));
    const glm::vec3 target = i % 8 == 6 ? lo + ext * glm::vec3(box(rng), box(rng), box(rng)) : tri_point(ref, n);
    const glm::vec3 dir = target - o;
    rays.push_back(gridtest::make_ray(o, glm::dot(dir, dir) > 1e-12f ? dir : glm::vec3(0.0f, 0.0f, 1.0f), 0.0f,
                                      i % 16 == 6 ? 0.5f : INFINITY));
  }
  return rays;
}

struct Totals {
  uint64_t on = 0, off = 0, rays = 0, fewer = 0;
};

// The scene traced with the mailbox on and off at `times` (updates between): every hit record the
// same but `tests`, never more tests with it.
Totals compare_on_off(const Scene& scene, GridOptions o, std::initializer_list<float> times, uint32_t count,
                      uint32_t seed) {
  o.traversal = Traversal::exact;
  o.mailbox = true;
  ReferenceGridTracer on(o);
  o.mailbox = false;
  ReferenceGridTracer off(o);
  Totals s;
  bool built = false;
  for (float time : times) {
    INFO("t = " << time);
    if (!built) {
      on.build(scene, time);
      off.build(scene, time);
      built = true;
      REQUIRE((on.params().flags & sh::kGridMailbox) != 0u);
      REQUIRE((off.params().flags & sh::kGridMailbox) == 0u);
      REQUIRE(sh::mailbox_enabled(on.params()));
      sh::GridParams a = on.params(), b = off.params();
      a.flags &= ~sh::kGridMailbox;
      REQUIRE(std::memcmp(&a, &b, sizeof a) == 0);  // the same grid otherwise
    } else {
      on.update(time);
      off.update(time);
    }
    const std::vector<Ray> rays = mailbox_rays(on.data(), count, seed + uint32_t(time * 10.0f));
    std::vector<Hit> a(rays.size()), b(rays.size());
    on.trace(rays, a);
    off.trace(rays, b);
    size_t bad = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      Hit x = a[i], y = b[i];
      const bool more = x.tests > y.tests;
      x.tests = y.tests = 0;
      if ((std::memcmp(&x, &y, sizeof x) != 0 || more) && ++bad <= 3)
        UNSCOPED_INFO("ray " << i << ": " << gridtest::hx(rays[i]) << "\n on  " << gridtest::hx(a[i]) << " cells "
                             << a[i].cells << " tests " << a[i].tests << "\n off " << gridtest::hx(b[i]) << " cells "
                             << b[i].cells << " tests " << b[i].tests);
      s.on += a[i].tests;
      s.off += b[i].tests;
      s.fewer += a[i].tests < b[i].tests;
    }
    s.rays += rays.size();
    CHECK(bad == 0);
  }
  return s;
}

// The explain events of `on` (the mailbox) against `off` (without): the same events but that each
// kTestMailboxed test stands where `off` re-tested the reference (with no result: not accepted;
// its alpha event, if any, gone). Returns the mailboxed events.
size_t check_events(const plan::ExplainRecord& on, const plan::ExplainRecord& off) {
  size_t i = 0, j = 0, mailboxed = 0;
  std::vector<uint32_t> tested;
  while (i < on.events.size() && j < off.events.size()) {
    const sh::ExplainEvent& a = on.events[i];
    if (a.kind == sh::kEvTest && a.code == sh::kTestMailboxed) {
      ++mailboxed;
      CHECK(std::find(tested.begin(), tested.end(), a.ref) != tested.end());  // tested before on the ray
      CHECK(a.f0 == glm::vec4(0.0f));
      CHECK(a.f1 == glm::vec4(0.0f));
      if (off.events[j].kind == sh::kEvAlpha && off.events[j].ref == a.ref) ++j;
      REQUIRE(j < off.events.size());
      const sh::ExplainEvent& b = off.events[j];
      CHECK(b.kind == sh::kEvTest);
      CHECK(b.ref == a.ref);
      CHECK(b.step == a.step);
      CHECK(b.cell == a.cell);
      CHECK(b.slot == a.slot);
      CHECK(b.code != sh::kTestAccepted);
      CHECK(b.code != sh::kTestSelfHit);
      ++i, ++j;
      continue;
    }
    if (a.kind == sh::kEvTest && a.code != sh::kTestSelfHit) tested.push_back(a.ref);
    if (std::memcmp(&a, &off.events[j], sizeof a) != 0) {
      FAIL_CHECK("event " << i << " (kind " << a.kind << ") differs from the mailbox-off event " << j << " (kind "
                          << off.events[j].kind << ")");
      return mailboxed;
    }
    ++i, ++j;
  }
  CHECK(i == on.events.size());
  CHECK(j == off.events.size());
  // The hit's test counter counts the tests made
  size_t tests = 0;
  for (const sh::ExplainEvent& e : on.events)
    tests += e.kind == sh::kEvTest && e.code != sh::kTestSelfHit && e.code != sh::kTestMailboxed;
  CHECK(tests == on.hit.tests);
  return mailboxed;
}

std::string real_scenes() {
  const std::string dir = real_scenes_dir();
  if (std::filesystem::is_directory(dir)) return dir;
  if (std::getenv("CI")) FAIL("the real scenes folder '" << dir << "' is missing, and CI must test with it");
  WARN("skipped: the real scenes folder '" << dir << "' is missing (set GRIDRT_SCENES)");
  return "";
}

}  // namespace

TEST_CASE("Mailbox: the last kMailboxSize references put, newest first", "[unit][grid][mailbox]") {
  sh::Mailbox m;
  sh::mailbox_clear(m);
  for (uint32_t i = 0; i < sh::kMailboxSize; ++i) CHECK(m.refs[i] == sh::kBlank);
  CHECK_FALSE(sh::mailbox_holds(m, 0u));
  for (uint32_t r = 1; r <= sh::kMailboxSize + 3; ++r) {
    sh::mailbox_put(m, r * 7u);
    CHECK(m.refs[0] == r * 7u);
    for (uint32_t k = 1; k <= sh::kMailboxSize + 3; ++k)
      CHECK(sh::mailbox_holds(m, k * 7u) == (k <= r && k + sh::kMailboxSize > r));
  }
  // The paper traversal never takes it; the exact one with the flag only
  sh::GridParams g{};
  g.flags = sh::kGridMailbox;
  g.insertion = sh::kInsertSorted;
  g.traversal = sh::kTraversalPaper;
  CHECK_FALSE(sh::mailbox_enabled(g));
  g.traversal = sh::kTraversalExact;
  CHECK(sh::mailbox_enabled(g));
  g.insertion = sh::kInsertFirstEmpty;  // a cell's slot order is the build's timing
  CHECK_FALSE(sh::mailbox_enabled(g));
  g.insertion = sh::kInsertSorted;
  g.flags = 0u;
  CHECK_FALSE(sh::mailbox_enabled(g));
}

TEST_CASE("Mailbox: on and off by the options - exact traversal with sorted insertion only", "[grid][mailbox]") {
  const Scene scene = make_builtin("cornell");
  using reference::Insertion;
  for (Traversal t : {Traversal::paper, Traversal::exact})
    for (Insertion insertion : {Insertion::sorted, Insertion::first_empty})
      for (bool mailbox : {false, true}) {
        INFO("traversal " << int(t) << ", insertion " << int(insertion) << ", mailbox " << mailbox);
        GridOptions o;
        o.threads = 2;
        o.traversal = t;
        o.insertion = insertion;
        o.mailbox = mailbox;
        const bool on = mailbox && t == Traversal::exact && insertion == Insertion::sorted;
        CHECK(plan::mailbox_enabled(o) == on);
        ReferenceGridTracer grid(o);
        grid.build(scene, 0.0f);
        CHECK(((grid.params().flags & sh::kGridMailbox) != 0u) == on);
      }
  // The default: off (on an H100 the mailbox made the trace slower; docs/BENCHMARKS.md "The mailbox")
  GridOptions o;
  o.traversal = Traversal::exact;
  CHECK(!o.mailbox);
}

TEST_CASE("Mailbox: every hit record equals the mailbox-off trace's but `tests`, never more tests - built-in, fan "
          "and random scenes, both layouts, skipping on and off, through updates",
          "[grid][mailbox]") {
  using L = GridOptions::Layout;
  for (const char* name : {"cornell", "teapot", "atrium"}) {
    INFO(name);
    GridOptions o;
    o.threads = 2;
    const Totals s = compare_on_off(make_builtin(name), o, {0.0f, 1.3f}, 3000, 11);
    WARN(name << ": tests per ray " << double(s.off) / double(s.rays) << " without the mailbox, "
              << double(s.on) / double(s.rays) << " with it");
    CHECK(s.on < s.off);
  }
  // A fan of 2 x 96 triangles about two vertices with a moving fan passing through: a triangle
  // spans many cells along a ray; image layout (the spill list: slots, then spilled references)
  // and compact layout, fine cells, skipping on and off
  const Scene fan = gridtest::fan_scene(96, 24);
  for (L layout : {L::image, L::compact})
    for (bool skip : {true, false}) {
      INFO((layout == L::image ? "image" : "compact") << " layout, skipping " << skip);
      GridOptions o;
      o.threads = 2;
      o.layout = layout;
      o.skip_empty = skip;
      o.resolution = glm::uvec3(24, 24, 24);
      if (layout == L::image) o.capacity = 4;
      const Totals s = compare_on_off(fan, o, {0.0f, 1.0f, 2.0f}, 2000, 5);
      CHECK(s.on < s.off);
      CHECK(s.fewer > 0);
    }
  // Random triangles with a moving instance
  for (uint32_t seed : {4u, 9u}) {
    INFO("random scene " << seed);
    GridOptions o;
    o.threads = 2;
    const Totals s = compare_on_off(gridtest::random_scene(400, 0.8f, 10.0f, seed, 60), o, {0.0f, 0.7f, 2.1f}, 2000, seed);
    CHECK(s.on < s.off);
  }
}

TEST_CASE("Mailbox: every hit record equals the mailbox-off trace's but `tests` on a real scene", "[grid][mailbox][scenes]") {
  if (real_scenes().empty()) return;
  const Scene scene = load_scene(std::string(GRIDRT_DATA_DIR) + "/scenes/sibenik-teapots.json");
  GridOptions o;
  o.threads = 2;
  const Totals s = compare_on_off(scene, o, {0.0f, 1.5f}, 20000, 21);
  WARN("sibenik-teapots, random rays: tests per ray " << double(s.off) / double(s.rays) << " without the mailbox, "
                                                      << double(s.on) / double(s.rays) << " with it");
  CHECK(s.on < s.off);
}

TEST_CASE("Mailbox: the explained ray's events are the mailbox-off ones, each re-test a kTestMailboxed test, named "
          "by the text and JSON formatters",
          "[grid][mailbox][explain]") {
  const Scene scene = gridtest::fan_scene(96, 24);
  for (GridOptions::Layout layout : {GridOptions::Layout::image, GridOptions::Layout::compact}) {
    GridOptions o;
    o.threads = 2;
    o.traversal = Traversal::exact;
    o.layout = layout;
    o.resolution = glm::uvec3(24, 24, 24);
    if (layout == GridOptions::Layout::image) o.capacity = 4;
    o.mailbox = true;
    ReferenceGridTracer on(o);
    o.mailbox = false;
    ReferenceGridTracer off(o);
    on.build(scene, 2.0f);
    off.build(scene, 2.0f);
    const std::vector<Ray> rays = mailbox_rays(on.data(), 300, 3);
    size_t mailboxed = 0, shown = 0;
    for (size_t i = 0; i < rays.size(); ++i) {
      INFO("ray " << i << ": " << gridtest::hx(rays[i]));
      const plan::ExplainRecord a = on.explain_ray(rays[i]), b = off.explain_ray(rays[i]);
      const size_t m = check_events(a, b);
      mailboxed += m;
      if (m == 0 || shown++ > 0) continue;
      // The formatters name it: the grid line, the test's reason, its code name in JSON
      const std::string text = plan::explain_text(a, {false, nullptr});
      CHECK_THAT(text, Catch::Contains("mailbox on") && Catch::Contains("tested earlier on this ray (mailbox)"));
      CHECK_THAT(plan::explain_text(b, {false, nullptr}), !Catch::Contains("mailbox"));
      CHECK_THAT(plan::explain_text(a, {true, nullptr}), Catch::Contains(": mailboxed"));
      const nlohmann::json j = plan::explain_json(a, {false, nullptr});
      CHECK(j["grid"]["mailbox"] == true);
      size_t named = 0;
      // (const operator[] on a missing key is undefined: not every event has a code name)
      for (const auto& e : j["events"]) named += e.value("code_name", std::string()) == "mailboxed";
      CHECK(named == m);
    }
    CHECK(mailboxed > 0);
    CHECK(shown > 0);
  }
}
