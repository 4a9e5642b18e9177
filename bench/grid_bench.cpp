// grid_bench: the reference grid's build, update and trace times, rays/s and memory on built-in
// and scene-file scenes, beside Embree on the same rays, and its agreement with Embree.
//   gridrt_grid_bench [--threads N] [--width W] [--height H] [--repeat R] [--traversal paper|exact]
//                     [--insertion sorted|first-empty] [--cell-test auto|sphere|box]
//                     [--max-image-dimension D] [--spill auto|on|off]
//                     SCENE...   (SCENE: builtin:NAME, a .json, ...; the option names are gridrt's)
// Rays: the camera's primary rays, then one mirror bounce per primary hit off the gather buffer
// (the paper's use). Times: the best of R runs, wall clock.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <map>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>

#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/common/util.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_BENCH_EMBREE
#include "gridrt/common/embree/embree_tracer.h"
#endif

using namespace gridrt;
using Clock = std::chrono::steady_clock;

namespace {

template <class F>
double best_ms(int repeat, F&& f) {
  double best = 1e300;
  for (int i = 0; i < repeat; ++i) {
    const auto t0 = Clock::now();
    f();
    best = std::min(best, std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
  }
  return best;
}

std::vector<Ray> make_rays(const Scene& scene, Tracer& primary, uint32_t w, uint32_t h) {
  const Camera cam = scene.frame_camera();
  const GatherBuffer gb = make_gather(scene, primary, cam, w, h, 0.0f);
  std::vector<Ray> rays = camera_rays(cam, w, h);
  for (size_t i = 0; i < gb.size(); ++i) {
    if (!gb.valid[i]) continue;
    const glm::vec3 n = gb.normal[i], d = gb.incident[i];
    Ray r{};
    r.org = gb.position[i];
    r.dir = d - 2.0f * glm::dot(d, n) * n;
    r.tmin = 0.0f;
    r.tmax = INFINITY;
    r.launch_normal = n;
    r.launch_ref = gb.launch_ref[i];
    rays.push_back(r);
  }
  return rays;
}

}  // namespace

int main(int argc, char** argv) {
  reference::GridOptions o;
  uint32_t w = 320, h = 240;
  int repeat = 3;
  std::vector<std::string> scenes;
  using GO = reference::GridOptions;
  CLI::App app("gridrt_grid_bench: the reference grid's build, update and trace beside Embree on the same rays");
  app.add_option("scenes", scenes, "Scenes: builtin:NAME, a scene file or a mesh (default: cornell, teapot, atrium)");
  app.add_option("--threads", o.threads, "CPU threads (0: all)");
  app.add_option("--width", w, "Gather buffer width")->check(CLI::Range(1u, 16384u));
  app.add_option("--height", h, "Gather buffer height")->check(CLI::Range(1u, 16384u));
  app.add_option("--repeat", repeat, "Time each phase this many times (best)")->check(CLI::Range(1, 1000));
  app.add_option("--traversal", o.traversal, "The trace: the paper's segments or the exact cell walk (default paper)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, reference::Traversal>{
          {"paper", reference::Traversal::paper}, {"exact", reference::Traversal::exact}}).description(""))
      ->type_name("paper|exact");
  app.add_option("--insertion", o.insertion, "How a reference takes a slot in its cell (default sorted)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, reference::Insertion>{
          {"sorted", reference::Insertion::sorted}, {"first-empty", reference::Insertion::first_empty}}).description(""))
      ->type_name("sorted|first-empty");
  app.add_option("--cell-test", o.cell_test, "Which cells of a triangle's range take it (auto: box for the exact traversal)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, GO::CellTest>{
          {"auto", GO::CellTest::automatic}, {"sphere", GO::CellTest::sphere}, {"box", GO::CellTest::box}}).description(""))
      ->type_name("auto|sphere|box");
  app.add_option("--max-image-dimension", o.max_image_dimension, "Largest grid image dimension");
  app.add_option("--spill", o.spill, "The list of references that find no slot (auto: on for the exact traversal)")
      ->transform(CLI::CheckedTransformer(std::map<std::string, GO::Spill>{
          {"auto", GO::Spill::automatic}, {"on", GO::Spill::on}, {"off", GO::Spill::off}}).description(""))
      ->type_name("auto|on|off");
  CLI11_PARSE(app, argc, argv);
  if (scenes.empty()) scenes = {"builtin:cornell", "builtin:teapot", "builtin:atrium"};
  const unsigned threads = reference::thread_count(o);
  std::printf("threads %u, %ux%u camera rays + mirror bounces, best of %d, traversal %s, insertion %s, max image dim %u, "
              "spill %s\n",
              threads, w, h, repeat, o.traversal == reference::Traversal::exact ? "exact" : "paper",
              o.insertion == reference::Insertion::sorted ? "sorted" : "first-empty", o.max_image_dimension,
              reference::spill_enabled(o) ? "on" : "off");
  std::printf("| scene | triangles | cells | capacity | image MiB | geometry MiB | build ms | update ms | rays | grid Mrays/s | embree Mrays/s | agree %% | differ | ties (max ulps) | holes | gap-fill %% | saturated cells | spilled (lost) |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  for (const std::string& spec : scenes) {
    const Scene scene = load_scene(spec);
    reference::ReferenceGridTracer grid(o);
    const double build = best_ms(repeat, [&] { grid.build(scene, 0.0f); });
    const bool dynamic = scene.has_dynamic();
    const double update = dynamic ? best_ms(repeat, [&] { grid.update(0.5f); }) : 0.0;
    grid.build(scene, 0.0f);
#ifdef GRIDRT_BENCH_EMBREE
    EmbreeTracer embree(threads);
    embree.build(scene, 0.0f);
    const std::vector<Ray> rays = make_rays(scene, embree, w, h);
#else
    const std::vector<Ray> rays = make_rays(scene, grid, w, h);
#endif
    std::vector<Hit> hits(rays.size()), want(rays.size());
    const double trace = best_ms(repeat, [&] { grid.trace(rays, hits); });
    double etrace = 0.0, agree = 0.0;
    size_t holes = 0, ties = 0, differ = 0;
    uint32_t tie_ulps = 0;  // ties: another triangle at a t within 64 ulps of Embree's
#ifdef GRIDRT_BENCH_EMBREE
    etrace = best_ms(repeat, [&] { embree.trace(rays, want); });
    size_t same = 0;
    for (size_t i = 0; i < rays.size(); ++i)
      same += (is_miss(hits[i]) && is_miss(want[i])) ||
              (!is_miss(hits[i]) && !is_miss(want[i]) && !(hits[i].flags & shared::kHitGapFill) &&
               hits[i].instance == want[i].instance && hits[i].triangle == want[i].triangle);
    agree = 100.0 * double(same) / double(rays.size());
    differ = rays.size() - same;
    for (size_t i = 0; i < rays.size(); ++i) {
      holes += is_miss(hits[i]) && !is_miss(want[i]);
      if (!is_miss(hits[i]) && !is_miss(want[i]) && !(hits[i].flags & shared::kHitGapFill) &&
          (hits[i].instance != want[i].instance || hits[i].triangle != want[i].triangle)) {
        const uint32_t ulps = ulp_distance(hits[i].t, want[i].t);
        if (ulps <= 64u) ++ties, tie_ulps = std::max(tie_ulps, ulps);
      }
    }
#endif
    size_t gaps = 0;
    for (const Hit& hit : hits) gaps += (hit.flags & shared::kHitGapFill) != 0;
    const reference::GridStats s = grid.stats();
    std::printf("| %s | %llu | %ux%ux%u | %u | %.1f | %.1f | %.1f | %.2f | %zu | %.3f | %.2f | %.2f | %zu | %zu (%u) | %zu | %.1f | %llu+%llu | %s |\n",
                spec.c_str(), (unsigned long long)s.triangles, s.cells.x, s.cells.y, s.cells.z, s.capacity,
                double(s.image_bytes) / 1048576.0, double(s.geometry_bytes) / 1048576.0, build, update,
                rays.size(), double(rays.size()) / trace / 1e3, etrace > 0 ? double(rays.size()) / etrace / 1e3 : 0.0,
                agree, differ, ties, tie_ulps, holes, 100.0 * double(gaps) / double(rays.size()), (unsigned long long)s.saturated_static,
                (unsigned long long)s.saturated_dynamic,
                s.spill_on ? (std::to_string(s.spill_stored) + " (" + std::to_string(s.spill_overflow) + ")").c_str() : "off");
    std::fflush(stdout);
  }
  return 0;
}
