// gridrt render --view: per-pixel pictures of what the grid did for each pixel's ray, from the hit
// records and the reference's event records (reference/grid.h, explain_ray), as PNG figures with a
// colour bar or a legend (common/plot.h):
//   cells       cells the ray visited (HitRecord::cells)
//   tests       references tested (HitRecord::tests)
//   saturation  saturated cells (status texel != 0) among the visited
//   gap-fill    where a gap-fill voxel answered (kHitGapFill)
//   spill       where a spilled reference answered (the reported hit's test followed a kEvSpilled)
//   diff        where the Vulkan shader's hit record differs from the CPU reference's
// The rays: each pixel's glossy bounce off the gather buffer (the rays the paper's frame traces
// through the grid; pixels without one are grey), or with --rays primary the camera rays, traced
// through the grid as the options set it (the frame itself rasterizes them).
#include <algorithm>
#include <cstdio>
#include <cstring>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/parallel.h"
#include "gridrt/common/plot.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/grid.h"
#endif

namespace gridrt::app {

namespace sh = gridrt::shared;

const std::vector<std::string>& view_names() {
  static const std::vector<std::string> names{"shaded", "cells", "tests", "saturation", "gap-fill", "spill", "diff"};
  return names;
}

namespace {

// What one ray's record says, per pixel.
struct PixelRecord {
  bool used = false;   // the pixel has a ray (bounce views: a glossy pixel)
  Hit hit{};
  uint32_t saturated = 0;  // visits of saturated cells
  bool spill = false;      // a spilled reference answered
};

PixelRecord summarize(const reference::ExplainRecord& r, const reference::GridData& grid) {
  PixelRecord p;
  p.used = true;
  p.hit = r.hit;
  uint32_t spilled_ref = sh::kBlank;
  bool candidate_spilled = false;
  for (const sh::ExplainEvent& e : r.events) {
    switch (e.kind) {
      case sh::kEvCell: {
        const uint32_t status = reference::cell_status(grid, e.cell);
        p.saturated += status != 0u;
        break;
      }
      case sh::kEvSlot: spilled_ref = sh::kBlank; break;
      case sh::kEvSpilled: spilled_ref = e.ref; break;
      case sh::kEvCandidate: candidate_spilled = e.ref == spilled_ref; break;
      default: break;
    }
  }
  p.spill = !is_miss(r.hit) && !(r.hit.flags & sh::kHitGapFill) && candidate_spilled;
  return p;
}

std::string traversal_name(const reference::GridOptions& g) {
  return g.traversal == reference::Traversal::paper ? "paper" : "exact";
}

#ifdef GRIDRT_HAVE_VULKAN
// --view diff: the Vulkan shader's hit records against the reference's `px`, pixel by pixel.
void diff_view(const ViewOptions& o, const Scene& scene, const reference::GridOptions& grid, const std::vector<Ray>& rays,
               const std::vector<PixelRecord>& px, size_t used, const plot::LegendEntry& no_ray, plot::ImageFigure& f) {
  const size_t n = rays.size();
  const vulkan::VulkanGridOptions vk = vulkan_grid_options(o.backend_options);
  vulkan::VulkanGridTracer gpu(grid, vk);
  gpu.build(scene, o.time);
  std::vector<Hit> got(n);
  gpu.trace(rays, got);
  // First-empty insertion fills a saturated cell's slots in arrival order, which differs between
  // runs and devices by design: a ray through such a cell may meet another triangle (gridrt diff
  // excuses those records; this view painted them as defects: an outside sweep)
  const bool first_empty = grid.insertion == reference::Insertion::first_empty;
  size_t bits = 0, floats = 0, other = 0, by_design = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!px[i].used) continue;
    const Hit& a = px[i].hit;
    const Hit& b = got[i];
    if (std::memcmp(&a, &b, sizeof a) == 0) {
      ++bits;
      f.rgb[i] = plot::colors::white;
    } else if (a.instance == b.instance && a.triangle == b.triangle && a.flags == b.flags && a.cells == b.cells &&
               a.tests == b.tests) {
      ++floats;  // never by design: the same triangle gives the same bits
      f.rgb[i] = plot::colors::orange;
    } else if (first_empty && px[i].saturated > 0) {
      ++by_design;
      f.rgb[i] = plot::colors::grey;
    } else {
      ++other;
      f.rgb[i] = plot::colors::red;
    }
  }
  char t[200];
  std::snprintf(t, sizeof t, "CPU reference vs Vulkan (%s): %zu of %zu rays differ", gpu.context().info().name.c_str(),
                floats + other, used);
  f.title = t;
  f.legend = {{plot::colors::white, "identical bits"},
              {plot::colors::orange, "t, u or v differ"},
              {plot::colors::red, "another hit or counters"}};
  if (first_empty) f.legend.push_back({plot::colors::grey, "differ through a saturated cell (first-empty: by design)"});
  if (used < n) f.legend.push_back(no_ray);
  std::printf("diff: %zu rays: %zu identical in bits, %zu differ in floats only, %zu differ in the hit", used, bits,
              floats, other);
  if (first_empty)
    std::printf(", %zu differ through a saturated cell (first-empty insertion: its slots in arrival order, by design)",
                by_design);
  std::printf("\n");
}
#endif

// Whether the options name a view this build can draw from the backend asked for.
void check_view(const ViewOptions& o) {
  const auto& names = view_names();
  if (std::find(names.begin(), names.end(), o.view) == names.end()) throw Error("unknown view '" + o.view + "'");
  if (o.view == "diff" && o.backend != "vulkan")
    throw OptionsError("--view diff compares the CPU reference with the Vulkan shader: add --backend vulkan");
  if (o.view != "diff" && !o.backend.empty() && o.backend != "cpu")
    throw OptionsError("--view " + o.view + " shows the CPU reference's records (the shader's agree bit for bit, "
                       "which --view diff checks): use --backend cpu");
#ifndef GRIDRT_HAVE_VULKAN
  if (o.view == "diff") throw Error("--view diff needs the Vulkan backend, which this build does not have");
#endif
  if (!plot::available())
    throw Error("--view needs OpenImageIO and the DejaVu fonts (Debian: libopenimageio-dev, fonts-dejavu-core)");
}

// The rays: glossy bounces off a gather buffer made through the exact traversal, or camera rays
// (o.primary); a scene without glossy materials gets the camera rays too (o.primary set, as the
// trace-cost policy samples it). `used`: the rays that are not unused.
std::vector<Ray> view_rays(ViewOptions& o, const Scene& scene, const reference::GridOptions& grid, size_t& used) {
  const uint32_t w = o.width, h = o.height;
  const size_t n = size_t(w) * h;
  std::vector<Ray> rays;
  if (o.primary) {
    rays = camera_rays(scene.frame_camera(), w, h);
  } else {
    reference::ReferenceGridTracer gather_tracer(plan::gather_options(grid));
    gather_tracer.build(scene, o.time);
    Progress progress("gather buffer", n);
    ProgressTracer traced(gather_tracer, progress);
    const GatherBuffer gather = make_gather(scene, traced, scene.frame_camera(), w, h, o.time);
    rays = bounce_rays(scene, gather, 0);
  }
  used = 0;
  for (const Ray& r : rays) used += !is_unused(r);
  if (used == 0) {
    // A scene without glossy materials: the camera rays (as the trace-cost policy samples it)
    std::fprintf(stderr, "view: %s has no glossy bounce ray: showing the camera rays\n", scene.name.c_str());
    o.primary = true;
    rays = camera_rays(scene.frame_camera(), w, h);
    used = n;
  }
  return rays;
}

// The figure a view draws into, with the per-pixel records it draws from.
struct ViewFigure {
  plot::ImageFigure& f;
  const std::vector<PixelRecord>& px;
  size_t used;
  const plot::LegendEntry& no_ray;
  const std::string& view;
};

// A heat view: value(p) per ray on viridis, with its bar.
template <class Value>
void heat(const ViewFigure& v, const std::string& title, const std::string& label, Value value) {
  plot::ImageFigure& f = v.f;
  const std::vector<PixelRecord>& px = v.px;
  const size_t n = px.size(), used = v.used;
  double lo = 0.0, hi = 0.0, sum = 0.0;
  for (size_t i = 0; i < n; ++i)
    if (px[i].used) hi = std::max(hi, double(value(px[i]))), sum += double(value(px[i]));
  for (size_t i = 0; i < n; ++i)
    if (px[i].used) f.rgb[i] = plot::viridis(hi > lo ? float((double(value(px[i])) - lo) / (hi - lo)) : 0.0f);
  char t[160];
  std::snprintf(t, sizeof t, "%s (mean %.2f, max %.0f per ray)", title.c_str(), sum / double(used), hi);
  f.title = t;
  std::printf("view %s: %zu rays, mean %.3f, max %.0f per ray\n", v.view.c_str(), used, sum / double(used), hi);
  f.has_bar = true;
  f.bar = {float(lo), float(std::max(hi, 1.0)), label, true};
  if (used < n) f.legend.push_back(v.no_ray);
}

// A mask view: the rays pred(p) holds for in yes_color, the others white (a hit) or dark (a miss).
template <class Pred>
void mask(const ViewFigure& v, const std::string& title, const std::string& yes, glm::vec3 yes_color, Pred pred) {
  plot::ImageFigure& f = v.f;
  const std::vector<PixelRecord>& px = v.px;
  const size_t n = px.size(), used = v.used;
  size_t count = 0;
  for (size_t i = 0; i < n; ++i) {
    if (!px[i].used) continue;
    const bool y = pred(px[i]);
    count += y;
    f.rgb[i] = y ? yes_color : is_miss(px[i].hit) ? plot::colors::dark_grey : plot::colors::white;
  }
  char t[160];
  std::snprintf(t, sizeof t, "%s: %zu of %zu rays", title.c_str(), count, used);
  f.title = t;
  std::printf("view %s: %zu of %zu rays\n", v.view.c_str(), count, used);
  f.legend = {{yes_color, yes}, {plot::colors::white, "another hit"}, {plot::colors::dark_grey, "miss"}};
  if (used < n) f.legend.push_back(v.no_ray);
}

}  // namespace

void run_view(const ViewOptions& options) {
  ViewOptions o = options;
  check_view(o);
  check_output_path(o.output);
  resolve_image_limit(o.backend_options, o.view == "diff");
  const Scene scene = load_scene_or_default(o.scene);
  const reference::GridOptions grid = grid_options_for(o.backend_options, scene);
  reference::ReferenceGridTracer ref(grid);
  ref.build(scene, o.time);
  const sh::GridParams& g = ref.params();

  const uint32_t w = o.width, h = o.height;
  const size_t n = size_t(w) * h;
  size_t used = 0;
  const std::vector<Ray> rays = view_rays(o, scene, grid, used);

  std::vector<PixelRecord> px(n);
  {
    Progress progress("view " + o.view, n);
    parallel_for(n, reference::thread_count(grid), [&](size_t i) {
      if (!is_unused(rays[i])) px[i] = summarize(ref.explain_ray(rays[i]), ref.data());
      progress.advance();
    });
  }

  plot::ImageFigure f;
  f.width = w;
  f.height = h;
  f.scale = o.scale;
  f.rgb.assign(n, plot::colors::light_grey);
  const std::string which = o.primary ? "camera rays" : "glossy bounce rays";
  char grid_text[160];
  std::snprintf(grid_text, sizeof grid_text, "%s, %s traversal, grid %ux%ux%u, capacity %u, %s", scene.name.c_str(),
                traversal_name(grid).c_str(), g.cells.x, g.cells.y, g.cells.z, g.capacity, which.c_str());
  f.subtitle = grid_text;
  const plot::LegendEntry no_ray{plot::colors::light_grey, o.primary ? "no ray" : "no glossy bounce"};

  const ViewFigure v{f, px, used, no_ray, o.view};
  if (o.view == "cells") {
    heat(v, "Cells visited per ray", "cells", [](const PixelRecord& p) { return p.hit.cells; });
  } else if (o.view == "tests") {
    heat(v, "References tested per ray", "tests", [](const PixelRecord& p) { return p.hit.tests; });
  } else if (o.view == "saturation") {
    heat(v, "Saturated cells visited per ray", "saturated", [](const PixelRecord& p) { return p.saturated; });
  } else if (o.view == "gap-fill") {
    mask(v, "Answered by a gap-fill voxel", "gap-fill voxel", plot::colors::red,
         [](const PixelRecord& p) { return (p.hit.flags & sh::kHitGapFill) != 0u; });
  } else if (o.view == "spill") {
    mask(v, "Answered by a spilled reference", "spilled reference", plot::colors::orange,
         [](const PixelRecord& p) { return p.spill; });
  } else if (o.view == "diff") {
#ifdef GRIDRT_HAVE_VULKAN
    diff_view(o, scene, grid, rays, px, used, no_ray, f);
#endif
  }
  plot::draw_image_figure(f).write(o.output);
  std::fprintf(stderr, "view %s -> %s\n", o.view.c_str(), o.output.c_str());
}

}  // namespace gridrt::app
