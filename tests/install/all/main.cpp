// A scene file loaded through the io component, traced by the reference grid and by Embree: the
// two agree on which camera rays hit (the install test's second consumer).
#include <cstdio>
#include <fstream>
#include <vector>

#include "gridrt/common/camera.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/reference/grid.h"

int main(int argc, char** argv) {
  if (argc != 2) return 2;
  // A closed box of 12 triangles, as an OBJ
  {
    std::ofstream obj(argv[1]);
    obj << "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0 0 1\nv 1 0 1\nv 1 1 1\nv 0 1 1\n"
           "f 1 3 2\nf 1 4 3\nf 5 6 7\nf 5 7 8\nf 1 2 6\nf 1 6 5\nf 2 3 7\nf 2 7 6\nf 3 4 8\nf 3 8 7\n"
           "f 4 1 5\nf 4 5 8\n";
  }
  const gridrt::Scene scene = gridrt::load_scene(argv[1]);
  gridrt::reference::GridOptions options;
  options.traversal = gridrt::reference::Traversal::exact;
  gridrt::reference::ReferenceGridTracer grid(options);
  gridrt::EmbreeTracer embree;
  grid.build(scene, 0.0f);
  embree.build(scene, 0.0f);
  const std::vector<gridrt::Ray> rays = gridrt::camera_rays(scene.frame_camera(), 32, 24);
  std::vector<gridrt::Hit> a(rays.size()), b(rays.size());
  grid.trace(rays, a);
  embree.trace(rays, b);
  size_t hit = 0, differ = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    hit += !gridrt::is_miss(a[i]);
    differ += gridrt::is_miss(a[i]) != gridrt::is_miss(b[i]);
  }
  std::printf("%zu of %zu rays hit the box, %zu differ from Embree\n", hit, rays.size(), differ);
  return hit > 0 && differ == 0 ? 0 : 1;
}
