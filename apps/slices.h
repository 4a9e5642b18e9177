// slices.h: stats --slices (slices.cpp).
#pragma once

#include <string>

#include "gridrt/reference/grid.h"

namespace gridrt::app {

// --slices: an existing folder (checked before the build, and again before writing)
void check_slices_folder(const std::string& dir);

// Writes DIR/occupancy.png: the grid's cells slice by slice along `axis` ('x', 'y' or 'z'). With
// `ray`, the cells its traversal visits are outlined black and the paper's midpoint samples (or
// the exact traversal's entry points) drawn as dots in the slice that holds them.
void write_slices(const reference::ReferenceGridTracer& ref, const std::string& scene_name, const std::string& dir,
                  char axis, const reference::ExplainRecord* ray = nullptr, const std::string& ray_name = "");

}  // namespace gridrt::app
