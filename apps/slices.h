// slices.h: stats --slices (slices.cpp).
#pragma once

#include <string>

#include "reference/grid.h"

namespace gridrt::app {

// Writes DIR/occupancy.png: the grid's cells slice by slice along `axis` ('x', 'y' or 'z').
void write_slices(const reference::ReferenceGridTracer& ref, const std::string& scene_name, const std::string& dir,
                  char axis);

}  // namespace gridrt::app
