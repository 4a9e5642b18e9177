// test_vulkan_rtx.cpp: the device's ray tracing pipeline side by side with the grid (vulkan/rtx.h).
// On a device without VK_KHR_ray_tracing_pipeline (lavapipe here and in CI) the tracer and the
// tool must refuse plainly, naming the device and what it lacks, and asking for ray tracing must
// change nothing else (validation silent). On a device with it, the RT pipeline's hits are
// compared with the grid's exact traversal on the built-in scenes. The RT path cannot run on
// lavapipe; docs/VULKAN.md says so and how it was run on the H200.
#include <array>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <string>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/reference/grid.h"
#include "tests/run_tool.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/rtx.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::VulkanGridTracer;
using gridrt::vulkan::VulkanRtxTracer;

namespace {

bool contains(const std::string& s, const std::string& part) { return s.find(part) != std::string::npos; }

// A validated context that asks for ray tracing (the [vulkan] tests' shared one does not).
vulkan::Context& rt_context() {
  static vulkan::Context* ctx = nullptr;
  if (!ctx) {
    vulkan::ContextOptions o = vulkan::ContextOptions::from_env();
    o.validation = true;
    o.raster_build = false;  // the compute build: fewer requirements
    o.ray_tracing = true;
    ctx = new vulkan::Context(o);
    std::atexit([] {
      delete ctx;
      ctx = nullptr;
    });
  }
  return *ctx;
}

}  // namespace

TEST_CASE("Vulkan RT side by side: the RT pipeline traces the grid's rays, or the tracer says plainly why not",
          "[vulkan][rtx][badinput]") {
  vulkan::Context& ctx = rt_context();
  ctx.clear_messages();
  const vulkan::DeviceInfo& info = ctx.info();
  // Enabled exactly when present
  CHECK(ctx.ray_tracing() == info.ray_tracing_missing.empty());
  if (!ctx.ray_tracing()) {
    // The device lacks it (lavapipe): nothing enabled, the grid works as ever, the tracer refuses
    const Scene scene = make_builtin("cornell");
    reference::GridOptions o;
    VulkanGridTracer grid(ctx, o, {.build = vulkan::BuildMode::compute});
    grid.build(scene, 0.0f);
    try {
      VulkanRtxTracer rtx(grid);
      FAIL("the RT tracer was made on " << info.name << ", which lacks " << info.ray_tracing_missing);
    } catch (const Error& e) {
      INFO(e.what());
      CHECK(contains(e.what(), info.name));
      CHECK(contains(e.what(), "VK_KHR_ray_tracing_pipeline"));
      CHECK(contains(e.what(), "lacks " + info.ray_tracing_missing));
    }
    GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
    return;
  }
  // The device has it: camera rays and one glossy bounce off the reference's gather, traced by the
  // grid (exact traversal) and by the RT pipeline, at three animation times
  WARN("ray tracing pipeline on " << info.name);
  for (const std::string& name : builtin_names()) {
    const Scene scene = make_builtin(name);
    INFO(name);
    reference::GridOptions o;
    o.traversal = reference::Traversal::exact;
    VulkanGridTracer grid(ctx, o, {.build = vulkan::BuildMode::compute});
    grid.build(scene, 0.0f);
    // Both ways of ignoring the launch triangle: in the any-hit shader, or by tracing again
    for (const bool any_hit_all : {true, false}) {
      INFO("any-hit on every triangle: " << any_hit_all);
      VulkanRtxTracer rtx(grid, {.any_hit_all = any_hit_all});
      for (const float time : {0.0f, 0.5f, 1.0f}) {
        grid.update(time);
        GatherBuffer gather = make_gather(scene, grid, scene.frame_camera(), 96, 64, time);
        std::vector<Ray> rays;
        for (uint32_t y = 0; y < 64; ++y)
          for (uint32_t x = 0; x < 96; ++x) rays.push_back(camera_ray(scene.frame_camera(), 96, 64, x, y));
        const std::vector<Ray> bounce = bounce_rays(scene, gather, 0);
        rays.insert(rays.end(), bounce.begin(), bounce.end());
        std::vector<Hit> grid_hits(rays.size()), rtx_hits(rays.size());
        grid.trace(rays, grid_hits);
        rtx.update_and_trace(rays, rtx_hits);
        size_t same = 0, hits = 0;
        for (size_t i = 0; i < rays.size(); ++i) {
          const Hit& g = grid_hits[i];
          const Hit& r = rtx_hits[i];
          hits += g.instance != shared::kNoInstance;
          same += g.instance == r.instance && (g.instance == shared::kNoInstance || g.triangle == r.triangle);
          // The launch triangle is never reported, nor a miss with the wrong record
          if (r.instance != shared::kNoInstance && rays[i].launch_ref != shared::kNoRef)
            CHECK(shared::ref_pack(r.instance, r.triangle) != rays[i].launch_ref);
          if (r.instance == shared::kNoInstance) CHECK((r.triangle == 0 && std::isinf(r.t)));
        }
        INFO("time " << time << ": " << same << " of " << rays.size() << " rays agree, " << hits << " grid hits");
        CHECK(hits > rays.size() / 10);  // not a comparison of misses (the teapot alone: 13 %)
        CHECK(double(same) >= 0.99 * double(rays.size()));
      }
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("gridrt bench --rtx: the side by side on a device with ray tracing, a clear error without",
          "[vulkan][rtx][cli][badinput]") {
  const vulkan::DeviceInfo& info = vk_context().info();
  const Run r = run_tool("bench builtin:atrium --backend vulkan --rtx --width 32 --height 24 --frames 1 --warmup 0");
  INFO(r.output);
  if (info.ray_tracing_missing.empty()) {
    CHECK(r.exit_code == 0);
    CHECK(contains(r.output, "rtx trace ms"));
    CHECK(contains(r.output, "agreement, the last frame"));
  } else {
    CHECK(r.exit_code == 1);
    CHECK(contains(r.output, "--rtx"));
    CHECK(contains(r.output, info.name));
    CHECK(contains(r.output, "lacks " + info.ray_tracing_missing));
  }
  // Asked for without the vulkan backend, or its variants without --rtx
  const Run cpu = run_tool("bench builtin:cornell --backend cpu --rtx --width 8 --height 8 --frames 1");
  INFO(cpu.output);
  CHECK(cpu.exit_code == 2);  // a bad command line
  CHECK(contains(cpu.output, "--backend vulkan"));
  const Run alone = run_tool("bench builtin:cornell --backend vulkan --rtx-opaque --frames 1");
  INFO(alone.output);
  CHECK(alone.exit_code == 2);
  CHECK(contains(alone.output, "--rtx"));
}
