// The program of docs/API.md: build a grid over a built-in scene and trace a camera's rays.
#include <cstdio>
#include <vector>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/reference/grid.h"

int main() {
  const gridrt::Scene scene = gridrt::make_builtin("cornell");

  gridrt::reference::GridOptions options;  // defaults: docs/SPEC.md, "Parameters"
  options.traversal = gridrt::reference::Traversal::exact;
  gridrt::reference::ReferenceGridTracer grid(options);
  grid.build(scene, 0.0f);

  // One ray per pixel of a 64 x 48 image from the scene's camera
  const std::vector<gridrt::Ray> rays = gridrt::camera_rays(scene.frame_camera(), 64, 48);
  std::vector<gridrt::Hit> hits(rays.size());
  grid.trace(rays, hits);

  size_t hit = 0;
  for (const gridrt::Hit& h : hits) hit += !gridrt::is_miss(h);
  std::printf("%zu of %zu rays hit\n", hit, rays.size());
  std::printf("%s", gridrt::reference::to_text(grid.stats()).c_str());
  return hit > 0 ? 0 : 1;
}
