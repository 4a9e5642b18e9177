// test_grid_mailbox_size.cpp (hidden: run by name or [.mailbox-size]): how large the exact
// traversal's mailbox should be (docs/SPEC.md "Mailbox", docs/BENCHMARKS.md "The mailbox"). Per
// scene, the reference grid at its defaults without the mailbox traces the frame's glossy bounce
// rays (or, without a glossy material, none) and camera rays of a 160x90 gather buffer with
// explain on; from each ray's test events (the references tested, in order) it counts the tests a
// mailbox of N entries would leave, FIFO (shared/grid.h's: a tested reference enters at the
// front) and LRU (a held reference moves to the front), and the ray's distinct references (an
// unbounded mailbox). Scenes: MAILBOX_SCENES (comma-separated: builtin:NAME or a scene file),
// default builtin:atrium.
//   GRIDRT_SCENES=/path/to/scenes MAILBOX_SCENES=builtin:atrium,data/scenes/sponza-teapots.json
//   build/release/tests/gridrt_tests "[.mailbox-size]"
#include <catch2/catch.hpp>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <deque>
#include <set>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/scene_io.h"
#include "tests/test_grid_util.h"

using namespace gridrt;
namespace sh = gridrt::shared;

namespace {

// The tests a mailbox of `size` entries leaves of the sequence `refs`; `lru`: a held reference
// moves to the front.
uint32_t mailbox_tests(const std::vector<uint32_t>& refs, size_t size, bool lru) {
  std::deque<uint32_t> box;
  uint32_t n = 0;
  for (uint32_t ref : refs) {
    const auto it = std::find(box.begin(), box.end(), ref);
    if (it != box.end()) {
      if (lru) box.erase(it), box.push_front(ref);
      continue;
    }
    ++n;
    box.push_front(ref);
    if (box.size() > size) box.pop_back();
  }
  return n;
}

}  // namespace

TEST_CASE("Mailbox size: the tests a FIFO or LRU mailbox of N entries leaves per ray, from the mailbox-off "
          "explain events",
          "[.mailbox-size]") {
  const char* env = std::getenv("MAILBOX_SCENES");
  const std::string list = env && *env ? env : "builtin:atrium";
  std::vector<std::string> names;
  for (size_t p = 0; p < list.size();) {
    size_t q = list.find(',', p);
    if (q == std::string::npos) q = list.size();
    names.push_back(list.substr(p, q - p));
    p = q + 1;
  }
  const uint32_t w = 160, h = 90;
  const std::vector<size_t> sizes = {1, 2, 4, 8, 16, 32};
  std::printf("| scene | rays | count | tests/ray without | distinct/ray |");
  for (size_t n : sizes) std::printf(" N=%zu FIFO / LRU |", n);
  std::printf("\n|---|---|---|---|---|");
  for (size_t i = 0; i < sizes.size(); ++i) std::printf("---|");
  std::printf("\n");
  for (const std::string& name : names) {
    const Scene scene = name.rfind("builtin:", 0) == 0 ? make_builtin(name.substr(8)) : load_scene(name);
    reference::GridOptions o;
    o.threads = 2;
    o.traversal = reference::Traversal::exact;
    o.mailbox = false;
    reference::ReferenceGridTracer grid(o);
    grid.build(scene, 0.0f);
    const GatherBuffer gather = make_gather(scene, grid, scene.frame_camera(), w, h, 0.0f);
    std::vector<Ray> bounce;
    for (const Ray& r : bounce_rays(scene, gather, 0))
      if (!is_unused(r)) bounce.push_back(r);
    const std::vector<Ray> camera = camera_rays(scene.frame_camera(), w, h);
    using Kind = std::pair<const char*, const std::vector<Ray>*>;
    for (const auto& [kind, rays] : {Kind{"glossy bounce", &bounce}, Kind{"camera", &camera}}) {
      if (rays->empty()) continue;
      double without = 0.0, distinct = 0.0;
      std::vector<double> fifo(sizes.size(), 0.0), lru(sizes.size(), 0.0);
      for (const Ray& r : *rays) {
        const reference::ExplainRecord rec = grid.explain_ray(r);
        std::vector<uint32_t> refs;
        for (const sh::ExplainEvent& e : rec.events)
          if (e.kind == sh::kEvTest && e.code != sh::kTestSelfHit) refs.push_back(e.ref);
        CHECK(refs.size() == rec.hit.tests);
        without += double(refs.size());
        distinct += double(std::set<uint32_t>(refs.begin(), refs.end()).size());
        for (size_t k = 0; k < sizes.size(); ++k) {
          fifo[k] += mailbox_tests(refs, sizes[k], false);
          lru[k] += mailbox_tests(refs, sizes[k], true);
        }
      }
      const double n = double(rays->size());
      std::printf("| %s | %s | %zu | %.2f | %.2f |", name.c_str(), kind, rays->size(), without / n, distinct / n);
      for (size_t k = 0; k < sizes.size(); ++k) std::printf(" %.2f / %.2f |", fifo[k] / n, lru[k] / n);
      std::printf("\n");
      std::fflush(stdout);
    }
  }
}
