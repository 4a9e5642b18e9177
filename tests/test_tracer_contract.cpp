// The Tracer contract on the reference grid (tests/tracer_contract.h; Embree's in test_oracle.cpp,
// the Vulkan port's in test_vulkan_grid.cpp), and the library's checks of what a program sets itself:
// GridOptions, a cell size, a camera.
#include <catch2/catch.hpp>

#include <functional>
#include <limits>
#include <vector>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/reference/grid.h"
#include "tests/test_grid_util.h"
#include "tests/tracer_contract.h"

namespace gridrt {
namespace {

using gridtest::check_contract;
using gridtest::hit_count;
using gridtest::make_ray;
using gridtest::random_scene;
using gridtest::refused_scene;

reference::GridOptions exact_options() {
  reference::GridOptions o;
  o.traversal = reference::Traversal::exact;
  o.threads = 2;
  return o;
}

}  // namespace

TEST_CASE("Library: the reference grid keeps the Tracer contract - failed builds, times, unfinalized scenes", "[unit][grid]") {
  SECTION("exact traversal") {
    check_contract([] { return std::make_unique<reference::ReferenceGridTracer>(exact_options()); });
  }
  SECTION("paper traversal") {
    reference::GridOptions o;
    o.threads = 2;
    check_contract([o] { return std::make_unique<reference::ReferenceGridTracer>(o); });
  }
  // After a failed build the reference's own views see no half-made grid
  reference::ReferenceGridTracer t(exact_options());
  t.build(random_scene(50, 0.5f, 10.0f, 3), 0.0f);
  REQUIRE_THROWS_AS(t.build(refused_scene(), 0.0f), Error);
  REQUIRE_THROWS_WITH(t.explain_ray(make_ray(glm::vec3(-1.0f), glm::vec3(1.0f))), Catch::Contains("before a build"));
  REQUIRE(t.dump().texels.empty());
  REQUIRE(t.stats().references == 0);
}

TEST_CASE("Library: GridOptions set in code are held to the command line's ranges", "[unit][grid]") {
  const Scene s = make_builtin("cornell");
  const auto refused = [&](const std::function<void(reference::GridOptions&)>& set, const char* field) {
    reference::GridOptions o = exact_options();
    set(o);
    reference::ReferenceGridTracer t(o);
    REQUIRE_THROWS_AS(t.build(s, 0.0f), OptionsError);
    REQUIRE_THROWS_WITH(t.build(s, 0.0f), Catch::Contains(field));
  };
  // A capacity of 0 built a grid in which every ray missed; the paper trace with a negative
  // elongation found nothing
  refused([](auto& o) { o.capacity = 0u; }, "capacity");
  refused([](auto& o) { o.layout = reference::GridOptions::Layout::image, o.capacity = 70000u; }, "capacity");
  refused([](auto& o) { o.max_capacity = 2u; }, "max_capacity");
  refused([](auto& o) { o.traversal = reference::Traversal::paper, o.elongation = -1.0f; }, "elongation");
  refused([](auto& o) { o.density = std::numeric_limits<float>::quiet_NaN(); }, "density");
  refused([](auto& o) { o.capacity_percentile = 2.0f; }, "capacity_percentile");
  refused([](auto& o) { o.work_sample_width = 0; }, "work_sample_width");
  refused([](auto& o) { o.resolution = glm::uvec3(0u, 4u, 4u); }, "resolution");
  refused([](auto& o) { o.cell_size = -1.0f; }, "cell_size");
  refused([](auto& o) { o.memory_budget = ~uint64_t(0); }, "memory_budget");
  // At the edges of the ranges: accepted, and every camera ray of the box hits
  reference::GridOptions o = exact_options();
  o.capacity = 1u;
  o.layout = reference::GridOptions::Layout::image;
  reference::ReferenceGridTracer t(o);
  t.build(s, 0.0f);
  const std::vector<Ray> rays = camera_rays(s.frame_camera(), 32, 24);
  REQUIRE(hit_count(t, rays) == rays.size());
}

TEST_CASE("Library: a cell size past the grid's index range is named as such, not as memory", "[unit][grid]") {
  const Scene s = random_scene(100, 0.5f, 5.0f, 11);
  reference::GridOptions o = exact_options();
  o.cell_size = 1e-3f;  // 5,000 cells an axis: over 2^31 cells
  reference::ReferenceGridTracer t(o);
  REQUIRE_THROWS_WITH(t.build(s, 0.0f), Catch::Contains("more than a grid may have"));
}

TEST_CASE("Library: a camera whose eye is not finite is named as such", "[unit]") {
  Camera c;
  c.eye = glm::vec3(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f);
  REQUIRE_THROWS_WITH(camera_frame(c), Catch::Contains("not finite"));
  c.eye = glm::vec3(0.0f, std::numeric_limits<float>::infinity(), 0.0f);
  REQUIRE_THROWS_WITH(camera_frame(c), Catch::Contains("not finite"));
}

}  // namespace gridrt
