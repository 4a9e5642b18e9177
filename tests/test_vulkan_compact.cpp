// test_vulkan_compact.cpp: the compact layout on the Vulkan port against the CPU reference
// (lavapipe, validation layer on, the raster-free compute build and the raster build): the
// offsets and references word for word, the spill lists equal, every hit record and an explained
// ray's events bit for bit, through update frames; the device's allocation equal to the plan's
// memory function.
#include <catch2/catch.hpp>

#include <cstring>
#include <random>

#include "gridrt/reference/compare.h"
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

TEST_CASE("Vulkan compact layout: arrays, spill lists, hits and explain events bit for bit with the reference "
          "through updates - compute and raster build",
          "[vulkan][diff][grid][compact]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::random_scene(500, 0.6f, 8.0f, 17, 100);
  for (BuildMode mode : {BuildMode::compute, BuildMode::raster}) {
    if (mode == BuildMode::raster && (!ctx.info().geometry_shader || !ctx.info().vertex_pipeline_stores_and_atomics))
      continue;
    INFO((mode == BuildMode::compute ? "compute build" : "raster build"));
    GridOptions o;
    o.traversal = Traversal::exact;
    o.layout = GridOptions::Layout::compact;
    o.threads = 2;
    o.shuffle_seed = 3;
    ReferenceGridTracer ref(o);
    VulkanGridTracer vk(ctx, o, {.build = mode});
    ref.build(scene, 0.0f);
    vk.build(scene, 0.0f);
    REQUIRE((vk.params().flags & sh::kGridCompact) != 0u);
    // The allocation is the plan's memory function
    const plan::GridMemory want = reference::grid_allocated(ref.data()), got = vk.memory();
    CHECK(want.total() == got.total());
    CHECK(want.offsets == got.offsets);
    CHECK(want.refs == got.refs);
    CHECK(want.heads == got.heads);
    for (float time : {0.0f, 0.9f, 2.2f}) {
      INFO("t = " << time);
      if (time > 0.0f) ref.update(time), vk.update(time);
      const AccelDump a = ref.dump(), b = vk.dump();
      CHECK(a.kind == "grid-compact");
      CHECK(reference::compare_texels(a, b).differing.empty());
      const reference::SpillDiff sd = reference::compare_spill(ref.spill(), vk.spill());
      CHECK(sd.same_header);
      CHECK(sd.same_lists);
      CHECK(sd.only_want.empty());
      CHECK(sd.only_got.empty());
      CHECK(vk.download_skip() == ref.data().skip);
      const std::vector<Ray> rays = gridtest::box_rays(ref.data(), 2000, 8.0f, uint32_t(time * 10) + 1);
      std::vector<Hit> w(rays.size()), g(rays.size());
      ref.trace(rays, w);
      vk.trace(rays, g);
      size_t differ = 0;
      for (size_t i = 0; i < rays.size(); ++i) differ += std::memcmp(&w[i], &g[i], sizeof(Hit)) != 0;
      CHECK(differ == 0);
      // An explained ray that visits a cell of the dynamic region: the same events
      const plan::ExplainRecord re = ref.explain_ray(rays[5]);
      const plan::ExplainRecord ge = vk.explain_ray(rays, 5);
      REQUIRE(re.events.size() == ge.events.size());
      CHECK(std::memcmp(re.events.data(), ge.events.data(), re.events.size() * sizeof(sh::ExplainEvent)) == 0);
      // A ray whose mailbox (kGridMailbox, the exact traversal's default) skips a re-test: the same events
      REQUIRE((vk.params().flags & sh::kGridMailbox) != 0u);
      size_t m = rays.size();
      for (size_t i = 0; i < rays.size() && m == rays.size(); ++i)
        if (w[i].tests > 4)
          for (const sh::ExplainEvent& e : ref.explain_ray(rays[i]).events)
            if (e.kind == sh::kEvTest && e.code == sh::kTestMailboxed) m = i;
      REQUIRE(m < rays.size());
      const plan::ExplainRecord rm = ref.explain_ray(rays[m]);
      const plan::ExplainRecord gm = vk.explain_ray(rays, uint32_t(m));
      REQUIRE(rm.events.size() == gm.events.size());
      CHECK(std::memcmp(rm.events.data(), gm.events.data(), rm.events.size() * sizeof(sh::ExplainEvent)) == 0);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
