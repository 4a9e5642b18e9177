// features.cpp: which effects a scene calls for (only those are simulated; docs/SPEC.md, "Gap-fill
// only if a cell is saturated").
#include "gridrt/common/tracer.h"

namespace gridrt {

Features Features::for_scene(const Scene& scene) {
  Features f;
  f.alpha_keying = scene.has_alpha_masks();
  f.update = scene.has_dynamic();
  f.glossy = scene.has_glossy();
  f.shadows = !scene.lights.empty();
  f.gap_fill = true;  // only the grid knows whether a cell saturates: it decides after each build
                      // and update (reference::trace_flags)
  return f;
}

}  // namespace gridrt
