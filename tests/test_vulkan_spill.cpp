// test_vulkan_spill.cpp: the spill list on the Vulkan port against the CPU reference (lavapipe,
// validation layer on): the spill list equal as a multiset of (cell, ref) with the same header
// (count, capacity, static count), images texel for texel, every hit record and the explained
// ray's events bit for bit, through updates that move dynamic references in and out of saturated
// cells; first-empty's slots and spill together hold every candidate; gap-fill's pipeline comes
// and goes with saturation and changes no hit.
#include <catch2/catch.hpp>

#include <cstring>

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

namespace {

GridOptions small_capacity(Traversal traversal, GridOptions::Spill spill) {
  GridOptions o;
  o.traversal = traversal;
  o.spill = spill;
  o.resolution = glm::uvec3(8);
  o.capacity = 4;
  o.threads = 2;
  return o;
}

size_t differing_hits(std::span<const Ray> rays, std::span<const Hit> want, std::span<const Hit> got) {
  size_t n = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (std::memcmp(&want[i], &got[i], sizeof(Hit)) == 0) continue;
    if (++n <= 3)
      UNSCOPED_INFO("ray " << i << ": " << reference::hex_ray(rays[i]) << "\n  reference " << reference::hex_hit(want[i])
                           << "\n  vulkan    " << reference::hex_hit(got[i]));
  }
  return n;
}

// The spill lists: the same header, the same entries as multisets.
void check_spill(const reference::SpillDump& want, const reference::SpillDump& got) {
  const reference::SpillDiff d = reference::compare_spill(want, got);
  INFO("reference: count " << want.header.count << " static " << want.header.static_count << " capacity "
                           << want.header.capacity << "; vulkan: count " << got.header.count << " static "
                           << got.header.static_count << " capacity " << got.header.capacity << "; "
                           << d.only_want.size() << " entries only in the reference, " << d.only_got.size()
                           << " only in vulkan");
  CHECK(d.same());
}

}  // namespace

TEST_CASE("Vulkan spill: a fan in one cell of capacity 4 - the spill list equal as a multiset, every hit and the "
          "explained events bit for bit, raster and compute builds",
          "[vulkan][diff][grid][hardcase]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::fan_scene(64);
  for (Traversal traversal : {Traversal::exact, Traversal::paper}) {
    const GridOptions o = small_capacity(traversal, GridOptions::Spill::on);
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    REQUIRE(ref.spill().stored() >= 124);
    const std::vector<Ray> rays = gridtest::fan_rays(ref.data(), 2500, 21);
    std::vector<Hit> want(rays.size()), got(rays.size());
    ref.trace(rays, want);
    for (BuildMode mode : {BuildMode::raster, BuildMode::compute}) {
      INFO((traversal == Traversal::exact ? "exact, " : "paper, ") << (mode == BuildMode::raster ? "raster" : "compute"));
      VulkanGridTracer vk(ctx, o, {.build = mode});
      vk.build(scene, 0.0f);
      CHECK(std::memcmp(&vk.params(), &ref.params(), sizeof(sh::GridParams)) == 0);
      check_spill(ref.spill(), vk.spill());
      CHECK(reference::compare_texels(ref.dump(), vk.dump()).differing.empty());
      vk.trace(rays, got);
      CHECK(differing_hits(rays, want, got) == 0);
      // Explained rays that scan the spill list leave the reference's events
      size_t explained = 0;
      for (size_t i = 0; i < rays.size() && explained < 4; i += 97) {
        const reference::ExplainRecord a = ref.explain_ray(rays[i]);
        bool spilled = false;
        for (const sh::ExplainEvent& e : a.events) spilled = spilled || e.kind == sh::kEvSpilled;
        if (!spilled) continue;
        ++explained;
        const reference::ExplainRecord b = vk.explain_ray(rays[i]);
        INFO("ray " << i);
        REQUIRE(a.events.size() == b.events.size());
        CHECK(std::memcmp(a.events.data(), b.events.data(), a.events.size() * sizeof(sh::ExplainEvent)) == 0);
        CHECK(std::memcmp(&a.hit, &b.hit, sizeof(Hit)) == 0);
      }
      CHECK(explained == 4);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan spill: dynamic references spill and move - the clear pass resets the counter on the device, the "
          "order pass walks in shared memory or in the buffer, both layouts",
          "[vulkan][diff][grid][hardcase]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::fan_scene(32, 16);
  // Both layouts: the image's spill list holds static entries before the dynamic ones (the
  // dynamic order pass starts past them), the compact layout's only dynamic ones
  for (GridOptions::Layout layout : {GridOptions::Layout::compact, GridOptions::Layout::image}) {
    GridOptions o = small_capacity(Traversal::exact, GridOptions::Spill::on);
    o.layout = layout;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    REQUIRE((layout == GridOptions::Layout::compact) == (ref.data().spill_header.static_count == 0u));
    // The order pass's walks in its shared copy of the entries (the device's size, and exactly the
    // build's dynamic entries) and in the buffer (one entry fewer than those: the copy too small)
    const uint32_t dynamic = ref.data().spill_header.count - ref.data().spill_header.static_count;
    REQUIRE(dynamic > 1u);
    for (uint32_t shared_entries : {0u, dynamic, dynamic - 1u}) {
      INFO((layout == GridOptions::Layout::compact ? "compact" : "image") << " layout, order pass's shared copy "
           << shared_entries << " entries (0: the device's), " << dynamic << " dynamic");
      ReferenceGridTracer want_grid(o);
      want_grid.build(scene, 0.0f);
      VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute, .order_shared_entries = shared_entries});
      vk.build(scene, 0.0f);
      check_spill(want_grid.spill(), vk.spill());
      for (float time : {1.0f, 2.0f, 3.0f, 2.0f}) {
        INFO("t = " << time);
        want_grid.update(time);
        vk.update(time);
        check_spill(want_grid.spill(), vk.spill());
        CHECK(vk.spill_header().count == want_grid.data().spill_header.count);
        CHECK(reference::compare_texels(want_grid.dump(), vk.dump()).differing.empty());
        const std::vector<Ray> rays = gridtest::fan_rays(want_grid.data(), 1500, uint32_t(time * 10));
        std::vector<Hit> want(rays.size()), got(rays.size());
        want_grid.trace(rays, want);
        vk.trace(rays, got);
        CHECK(differing_hits(rays, want, got) == 0);
      }
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan spill: an update past the forecast grows the list like the reference's - the same header, entries "
          "and hits in bits",
          "[vulkan][diff][grid][hardcase]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  for (GridOptions::Layout layout : {GridOptions::Layout::compact, GridOptions::Layout::image}) {
    INFO((layout == GridOptions::Layout::compact ? "compact" : "image") << " layout");
    const gridtest::SpillGrowthCase growth = gridtest::spill_growth_case(layout);
    const Scene& scene = growth.scene;
    const GridOptions& o = growth.options;
    const float peak = growth.peak;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
    vk.build(scene, 0.0f);
    const uint32_t forecast = ref.data().spill_header.capacity;
    REQUIRE(vk.spill_header().capacity == forecast);
    for (float time : {peak, 0.25f, 1.5f, peak}) {
      INFO("t = " << time);
      ref.update(time);
      vk.update(time);
      CHECK(ref.data().spill_header.capacity > forecast);
      CHECK(vk.spill_header().capacity == ref.data().spill_header.capacity);
      CHECK(vk.spill_header().count == ref.data().spill_header.count);
      CHECK(vk.spill().overflow() == 0u);
      check_spill(ref.spill(), vk.spill());
      const std::vector<Ray> rays = gridtest::walk_rays(ref.data().params, uint32_t(5 + time * 8));
      std::vector<Hit> want(rays.size()), got(rays.size());
      ref.trace(rays, want);
      vk.trace(rays, got);
      CHECK(differing_hits(rays, want, got) == 0);
    }
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan spill: first-empty - a saturated cell's slots and spilled entries are exactly its candidates",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::fan_scene(48, 12);
  GridOptions o = small_capacity(Traversal::exact, GridOptions::Spill::on);
  o.insertion = reference::Insertion::first_empty;
  ReferenceGridTracer ref(o);
  ref.build(scene, 0.0f);
  VulkanGridTracer vk(ctx, o);
  vk.build(scene, 0.0f);
  for (float time : {0.0f, 2.0f}) {
    INFO("t = " << time);
    if (time > 0.0f) {
      ref.update(time);
      vk.update(time);
    }
    const reference::SpillDump spill = vk.spill();
    CHECK(spill.header.count == ref.spill().header.count);
    CHECK(spill.header.static_count == ref.spill().header.static_count);
    const reference::CellCheck c = reference::check_cells_as_multisets(ref.data(), vk.dump(), &spill);
    CHECK(c.bad.empty());
    CHECK(c.saturated > 0);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan spill: overflow counted like the reference's, and gap-fill's pipeline only while a cell is "
          "saturated, no hit changed",
          "[vulkan][diff][grid]") {
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  {
    // Overflow: the same count; the device stored `capacity` of the references the reference spills
    const Scene scene = gridtest::fan_scene(64);
    GridOptions o = small_capacity(Traversal::exact, GridOptions::Spill::on);
    o.spill_capacity = 20;
    ReferenceGridTracer ref(o);
    ref.build(scene, 0.0f);
    GridOptions roomy = o;
    roomy.spill_capacity = 4096;
    ReferenceGridTracer all(roomy);
    all.build(scene, 0.0f);
    VulkanGridTracer vk(ctx, o);
    vk.build(scene, 0.0f);
    const reference::SpillDump got = vk.spill();
    CHECK(got.header.count == ref.spill().header.count);
    CHECK(got.overflow() == ref.spill().overflow());
    CHECK(got.overflow() > 0);
    CHECK(got.entries.size() == 20);
    // No entry stored past the list, no head or link beyond it: the stored 20 linked in order
    std::string problem;
    const std::vector<reference::SpillList> lists = reference::walk_spill_lists(got, &problem);
    INFO(problem);
    CHECK(problem.empty());
    size_t linked = 0;
    for (const reference::SpillList& l : lists) linked += l.refs.size();
    CHECK(linked == 20);
    reference::SpillDump part = all.spill();
    part.header = got.header;
    CHECK(reference::compare_spill(part, got).only_got.empty());  // a choice of the spilled references
  }
  {
    // The toggling case of test_spill.cpp on the device: the same flags and hits as the reference
    Scene scene = gridtest::fan_scene(3, 3);  // 6 and 6 triangles: 12 where they meet
    GridOptions o;
    o.traversal = Traversal::paper;
    o.resolution = glm::uvec3(8);
    o.capacity = 8;
    o.threads = 2;
    ReferenceGridTracer ref(o);
    VulkanGridTracer vk(ctx, o);
    ref.build(scene, 0.0f);
    vk.build(scene, 0.0f);
    bool on = false, off = false;
    for (float time : {0.0f, 2.0f, 3.0f}) {
      INFO("t = " << time);
      if (time > 0.0f) {
        ref.update(time);
        vk.update(time);
      }
      CHECK(vk.params().flags == ref.params().flags);
      ((vk.params().flags & sh::kGridGapFill) ? on : off) = true;
      const std::vector<Ray> rays = gridtest::fan_rays(ref.data(), 1200, uint32_t(time + 3));
      std::vector<Hit> want(rays.size()), got(rays.size());
      ref.trace(rays, want);
      vk.trace(rays, got);
      CHECK(differing_hits(rays, want, got) == 0);
    }
    CHECK(on);
    CHECK(off);
  }
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}

TEST_CASE("Vulkan grid: the clear pass empties dynamic slots beyond a workgroup's 64 lanes (capacity 160)",
          "[vulkan][diff][grid]") {
  // 150 moving triangles through one cell: its dynamic references fill slots up to about 158, so
  // the clear pass's lanes take each cell's slots in more than two strides of 64
  vulkan::Context& ctx = vk_context();
  ctx.clear_messages();
  const Scene scene = gridtest::fan_scene(8, 150);
  GridOptions o = small_capacity(Traversal::exact, GridOptions::Spill::off);
  o.capacity = 160;
  ReferenceGridTracer ref(o);
  VulkanGridTracer vk(ctx, o, {.build = BuildMode::compute});
  ref.build(scene, 0.0f);
  vk.build(scene, 0.0f);
  uint32_t fullest = 0;
  for (float time : {0.0f, 1.0f, 2.0f}) {
    INFO("t = " << time);
    if (time > 0.0f) {
      ref.update(time);
      vk.update(time);
    }
    CHECK(reference::compare_texels(ref.dump(), vk.dump()).differing.empty());
    const AccelDump d = ref.dump();
    const sh::GridParams g = ref.params();
    for (uint32_t z = 0; z < g.cells.z; ++z)
      for (uint32_t y = 0; y < g.cells.y; ++y)
        for (uint32_t x = 0; x < g.cells.x; ++x) {
          uint32_t used = 0;
          for (uint32_t s = 0; s < g.capacity; ++s) {
            const glm::uvec3 t = sh::cell_slot_texel(g, glm::uvec3(x, y, z), s);
            used += d.texels[t.x + d.extent.x * (t.y + size_t(d.extent.y) * t.z)] != sh::kBlank;
          }
          fullest = std::max(fullest, used);
        }
  }
  CHECK(fullest > 128);  // the third stride is reached
  GRIDRT_REQUIRE_NO_VALIDATION_MESSAGES(ctx);
}
