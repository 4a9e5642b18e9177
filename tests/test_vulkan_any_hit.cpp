// test_vulkan_any_hit.cpp: the trace shader's any-hit mode (docs/SPEC.md "Any hit"; the frame's
// shadow rays) against the reference's on every ray of each batch (lavapipe, validation layer on):
// hit records bit for bit, and an explained ray that stops at its first candidate event for
// event, in both traversals and layouts, with saturated cells (spill list, gap-fill) and alpha
// keying, through an update.
#include <catch2/catch.hpp>

#include <cstring>

#include "gridrt/common/builtin/builtin.h"
#include "tests/test_grid_util.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/grid.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::BuildMode;
using gridrt::vulkan::VulkanGridTracer;
using reference::GridOptions;
using reference::ReferenceGridTracer;
using reference::Traversal;
namespace sh = gridrt::shared;

TEST_CASE("Vulkan any hit: hit records and explain events bit for bit with the reference",
          "[vulkan][diff][grid][any-hit]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  struct Case {
    const char* scene;
    Traversal traversal;
    bool compact;
    std::optional<uint32_t> capacity;
  };
  const Case cases[] = {{"atrium", Traversal::exact, true, {}},
                        {"atrium", Traversal::paper, false, 4u},
                        {"fan", Traversal::exact, false, 4u}};
  for (const Case& k : cases) {
    INFO(k.scene << (k.traversal == Traversal::exact ? " exact" : " paper") << (k.compact ? " compact" : " image"));
    const std::string name = k.scene;
    const Scene scene = name == "fan" ? gridtest::fan_scene(120, 1) : make_builtin(name);
    GridOptions o;
    o.threads = 2;
    o.traversal = k.traversal;
    o.layout = k.compact ? GridOptions::Layout::compact : GridOptions::Layout::image;
    o.capacity = k.capacity;
    ReferenceGridTracer ref(o);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    ref.build(scene, 0.0f);
    vk.build(scene, 0.0f);
    for (float time : {0.0f, 1.3f}) {
      INFO("t = " << time);
      if (time > 0.0f) ref.update(time), vk.update(time);
      const std::vector<Ray> rays = gridtest::leaving_rays(ref.data(), 1500, 31 + uint32_t(time * 10));
      std::vector<Hit> want(rays.size()), got(rays.size()), closest(rays.size());
      ref.trace_any(rays, want);
      vk.trace_any(rays, got);
      ref.trace(rays, closest);
      size_t differ = 0, shorter = 0, hits = 0;
      size_t stopped = rays.size();  // a ray that stopped at a candidate before the closest trace's end
      for (size_t i = 0; i < rays.size(); ++i) {
        differ += std::memcmp(&want[i], &got[i], sizeof(Hit)) != 0;
        hits += !is_miss(want[i]);
        if (want[i].tests < closest[i].tests) {
          shorter += 1;
          if (stopped == rays.size()) stopped = i;
        }
      }
      CHECK(differ == 0);
      CHECK(hits > rays.size() / 10);
      CHECK(shorter > 0);  // the mode is on in the shader: it cut some rays short
      REQUIRE(stopped < rays.size());
      const plan::ExplainRecord re = ref.explain_ray(rays[stopped], sh::kTraceAnyHit);
      const plan::ExplainRecord ge = vk.explain_ray(rays, uint32_t(stopped), sh::kTraceAnyHit);
      CHECK(ge.mode == sh::kTraceAnyHit);
      REQUIRE(re.events.size() == ge.events.size());
      CHECK(std::memcmp(re.events.data(), ge.events.data(), re.events.size() * sizeof(sh::ExplainEvent)) == 0);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
