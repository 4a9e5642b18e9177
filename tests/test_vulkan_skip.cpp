// test_vulkan_skip.cpp: the Vulkan skip field (skip_field.comp, the dynamic boxes) identical in
// every word to the reference's, and the skipping trace's hit records identical in bits, through
// animated updates, on lavapipe with the validation layer on.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstring>
#include <random>

#include "tests/test_grid_util.h"
#include "tests/vulkan_test_util.h"
#include "gridrt/vulkan/grid.h"

using namespace gridrt;
using namespace gridrt::test;
using gridrt::vulkan::BuildMode;
using gridrt::vulkan::VulkanGridTracer;
using reference::GridOptions;
using reference::ReferenceGridTracer;
namespace sh = gridrt::shared;

TEST_CASE("Vulkan skip field and skipping trace identical in bits to the reference's", "[vulkan][diff][grid][skip]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::random_scene(200, 0.6f, 10.0f, 12, 40);
  // The compact layout (the exact traversal's default) and the image layout: the skip field reads
  // a cell's occupancy from its offsets or from its first slot; the compact layout's cover bits
  // (docs/SPEC.md "Covered cells") with dense and, on a finer grid, sparse offsets
  using Layout = GridOptions::Layout;
  using Offsets = GridOptions::Offsets;
  for (const auto& [layout, offsets] : {std::pair{Layout::compact, Offsets::automatic}, std::pair{Layout::image, Offsets::automatic},
                                        std::pair{Layout::compact, Offsets::sparse}}) {
    INFO((layout == Layout::compact ? "compact layout" : "image layout") << (offsets == Offsets::sparse ? ", sparse offsets" : ""));
    GridOptions o;
    o.threads = 2;
    o.traversal = reference::Traversal::exact;
    o.layout = layout;
    o.offsets = offsets;
    if (offsets == Offsets::sparse) o.resolution = glm::uvec3(40, 36, 44);
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    vk.build(scene, 0.0f);
    REQUIRE((vk.params().flags & sh::kGridSkipEmpty) != 0u);
    REQUIRE(((vk.params().flags & sh::kGridCompact) != 0u) == (layout == Layout::compact));
    REQUIRE(((vk.params().flags & sh::kGridSkipCovered) != 0u) == (layout == Layout::compact));
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> p(-1.0f, 11.0f), d(-1.0f, 1.0f);
    for (float time : {0.0f, 0.8f, 1.9f}) {
      INFO("time " << time);
      if (time > 0.0f) {
        ref.update(time);
        vk.update(time);
      }
      const std::vector<uint32_t> got = vk.download_skip();
      REQUIRE(got.size() == ref.data().skip.size());
      for (size_t i = 0; i < got.size(); ++i) {
        INFO("word " << i);
        REQUIRE(got[i] == ref.data().skip[i]);
      }
      std::vector<Ray> rays;
      for (uint32_t i = 0; i < 4000; ++i) {
        glm::vec3 dir(d(rng), d(rng), d(rng));
        if (i % 5 == 0) dir.y = 0.0f;
        if (glm::dot(dir, dir) < 1e-6f) dir = {1.0f, 0.0f, 0.0f};
        rays.push_back(gridtest::make_ray({p(rng), p(rng), p(rng)}, dir, 0.0f, (i % 3) ? INFINITY : 5.0f));
      }
      std::vector<Hit> want(rays.size()), hits(rays.size());
      ref.trace(rays, want);
      vk.trace(rays, hits);
      size_t found = 0;
      for (size_t i = 0; i < rays.size(); ++i) {
        INFO("ray " << i << " " << gridtest::hx(rays[i]) << "\nref " << gridtest::hx(want[i]) << "\nvk  "
                    << gridtest::hx(hits[i]));
        REQUIRE(std::memcmp(&want[i], &hits[i], sizeof(Hit)) == 0);
        found += !is_miss(want[i]);
      }
      CHECK(found > rays.size() / 20);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan skip field past the cap and across partial bricks identical to the reference's",
          "[vulkan][diff][grid][skip]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::far_apart_scene();
  for (const glm::uvec3 res : {glm::uvec3(601, 3, 2), glm::uvec3(258, 5, 7)}) {
    INFO("resolution " << gridtest::hx(res));
    GridOptions o;
    o.threads = 2;
    o.traversal = reference::Traversal::exact;
    o.resolution = res;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    vk.build(scene, 0.0f);
    REQUIRE(vk.params().cells == res);
    const std::vector<uint32_t> got = vk.download_skip();
    REQUIRE(got.size() == ref.data().skip.size());
    size_t capped = 0;
    for (size_t i = 0; i < got.size(); ++i) {
      INFO("word " << i);
      REQUIRE(got[i] == ref.data().skip[i]);
      capped += i >= sh::kSkipHeaderWords && (got[i] & 0xFFu) == sh::kSkipMaxDistance;
    }
    if (res.x > 600) CHECK(capped > 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan build with pass timestamps: every query written, no validation message", "[vulkan][grid][skip]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::random_scene(200, 0.6f, 10.0f, 12, 40);
  // The compact layout with the skip field, and the image layout without it: each writes every
  // query of the pass pool (a query left unwritten would leave the read waiting)
  for (const bool compact : {true, false}) {
    INFO((compact ? "compact layout, skip field" : "image layout, no skip field"));
    GridOptions o;
    o.threads = 2;
    o.traversal = reference::Traversal::exact;
    o.layout = compact ? GridOptions::Layout::compact : GridOptions::Layout::image;
    o.skip_empty = compact;
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute, .build_pass_timestamps = true});
    vk.build(scene, 0.0f);
    REQUIRE(((vk.params().flags & sh::kGridSkipEmpty) != 0u) == compact);
    const vulkan::GridTimings& t = vk.timings();
    for (double ms : t.build_static_passes_ms) CHECK((std::isfinite(ms) && ms >= 0.0));
    for (double ms : t.build_skip_passes_ms) CHECK((std::isfinite(ms) && ms >= 0.0));
    // The same grid as a build without them
    VulkanGridTracer plain(ctx, o, {.build = BuildMode::compute});
    plain.build(scene, 0.0f);
    CHECK(plain.download_skip() == vk.download_skip());
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
