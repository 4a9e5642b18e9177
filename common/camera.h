// camera.h: primary rays of a pinhole camera.
#pragma once

#include <vector>

#include <cstdint>

#include "gridrt/common/scene.h"
#include "gridrt/common/shared/bounce.h"
#include "gridrt/common/tracer.h"

namespace gridrt {

// The ray through the centre of pixel (x, y) of a width x height image; row 0 is the top row.
// Pinhole at camera.eye, vertical field of view camera.vfov_degrees, square pixels. The direction
// is normalized; tmin 0, tmax +inf, launch_normal 0, launch_ref shared::kNoRef.
// Throws Error for an empty image, a pixel outside it, or a degenerate camera (eye == target, or
// up parallel to the view direction).
Ray camera_ray(const Camera& camera, uint32_t width, uint32_t height, uint32_t x, uint32_t y);
// Every pixel's camera_ray, row by row from the top (ray y * width + x).
std::vector<Ray> camera_rays(const Camera& camera, uint32_t width, uint32_t height);
// n camera rays: the first n pixels, row by row, of a 16:9 image of about n pixels (verify's camera
// family, and bench's primary rays).
std::vector<Ray> camera_grid_rays(const Camera& camera, size_t n);

// The camera's orthonormal frame: right, up, and forward (towards the target).
struct CameraFrame {
  glm::vec3 right, up, forward;
  float tan_half_fov;
};
CameraFrame camera_frame(const Camera& camera);

// The camera as the per-pixel code of common/shared/bounce.h reads it (CPU and GPU alike).
shared::CameraParams camera_params(const Camera& camera, uint32_t width, uint32_t height);

}  // namespace gridrt
