// gridrt portal render --view: per-pixel pictures of the portal traversal's work on the world's
// camera rays, with a colour bar (common/plot.h):
//   divs   divs the portal tracer visits per ray (HitRecord::cells of trace_portal)
//   dda    voxels the exact voxel DDA steps through per ray (HitRecord::cells of trace_dda), the
//          work the divs save
#include <algorithm>
#include <cstdio>

#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/plot.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/trace.h"

namespace gridrt::app {

portal::World load_world(const std::string& spec, uint32_t voxels);  // cmd_portal.cpp
portal::PortalOptions portal_options(const std::string& div_choice, uint32_t atlas_width, bool progress);  // cmd_portal.cpp

void run_portal_view(const PortalRenderOptions& o) {
  check_frame_size(o.width, o.height);
  if (o.view != "divs" && o.view != "dda") throw Error("unknown portal view '" + o.view + "'");
  if (o.backend != "portal-cpu")
    throw OptionsError("portal --view shows the CPU reference's records: use --backend portal-cpu");
  if (!plot::available())
    throw Error("--view needs OpenImageIO and the DejaVu fonts (Debian: libopenimageio-dev, fonts-dejavu-core)");
  check_output_path(o.output);
  portal::World world = load_world(o.scene, o.voxels);
  const Camera camera = world.camera;
  const portal::PortalOptions options = portal_options(o.div_choice, o.atlas_width, false);
  portal::PortalBuild build = portal::build_portal(std::move(world), options);
  const size_t n = size_t(o.width) * o.height;
  const std::vector<Ray> rays = camera_rays(camera, o.width, o.height);
  std::vector<Hit> hits(n);
  const std::string world_name = build.world.name;
  const glm::uvec3 dims = build.world.dims;
  const size_t divs = build.divs.size();
  if (o.view == "divs") {
    portal::PortalTracer tracer(std::move(build), options);
    tracer.trace(rays, hits);
  } else {
    portal::VoxelDdaTracer tracer(build.world);
    tracer.trace(rays, hits);
  }
  double hi = 0.0, sum = 0.0;
  for (const Hit& h : hits) hi = std::max(hi, double(h.cells)), sum += double(h.cells);
  plot::ImageFigure f;
  f.width = o.width;
  f.height = o.height;
  f.rgb.resize(n);
  for (size_t i = 0; i < n; ++i) f.rgb[i] = plot::viridis(hi > 0.0 ? float(double(hits[i].cells) / hi) : 0.0f);
  char t[200];
  std::snprintf(t, sizeof t, "%s per ray (mean %.2f, max %.0f)", o.view == "divs" ? "Divs visited" : "Voxels stepped (DDA)",
                sum / double(n), hi);
  f.title = t;
  std::snprintf(t, sizeof t, "%s: %ux%ux%u voxels, %zu divs, camera rays", world_name.c_str(), dims.x, dims.y, dims.z,
                divs);
  f.subtitle = t;
  f.has_bar = true;
  f.bar = {0.0f, float(std::max(hi, 1.0)), o.view == "divs" ? "divs" : "voxels", true};
  plot::draw_image_figure(f).write(o.output);
  std::printf("view %s: %zu rays, mean %.3f, max %.0f per ray\n", o.view.c_str(), n, sum / double(n), hi);
}

}  // namespace gridrt::app
