#include "gridrt/common/camera.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace gridrt {

CameraFrame camera_frame(const Camera& camera) {
  // The view and up directions scaled by a power of two into a range where their lengths neither
  // underflow nor overflow (direction_in_range: exact, the same directions; vectors whose largest
  // component lies in [2^-20, 2^20] keep their bits). An up of 1e-22 (dot(up, up) subnormal) gave a
  // frame of a few bits and a wrong picture with exit 0 (an outside sweep).
  const auto finite3 = [](glm::vec3 v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); };
  if (!finite3(camera.eye) || !finite3(camera.target) || !finite3(camera.up))
    throw Error("camera: its eye, target or up is not finite (NaN or inf)");
  const glm::vec3 view = direction_in_range(camera.target - camera.eye);
  const glm::vec3 up = direction_in_range(camera.up);
  if (!std::isfinite(view.x) || !std::isfinite(view.y) || !std::isfinite(view.z))
    throw Error("camera: eye and target are too far apart (their difference overflows single precision)");
  if (!(glm::length(view) > 0.0f)) throw Error("camera: eye and target coincide");
  if (!(glm::length(up) > 0.0f)) throw Error("camera: up is zero");
  CameraFrame f;
  f.forward = glm::normalize(view);
  const glm::vec3 r = glm::cross(f.forward, up);
  if (!(glm::length(r) > 1e-6f * glm::length(up))) throw Error("camera: up is parallel to the view direction");
  f.right = glm::normalize(r);
  // An up within a few degrees of the view direction: the float cross product's rounding, relative
  // to its small length, turned `right` off the perpendicular (forward . right 0.057 with up 1e-6
  // rad off the view): every bound of the GPU gather that takes the pixel directions' frame as
  // orthonormal (the screen box, the depth plane) then left out pixels the ray test accepts (an
  // outside sweep). There `right` is made in double and made perpendicular to the float forward;
  // other cameras keep the float frame they always had.
  if (glm::length(r) < 0.0625f * glm::length(up)) {
    const glm::dvec3 fw(f.forward);
    glm::dvec3 rd = glm::cross(fw, glm::dvec3(up));
    rd -= glm::dot(rd, fw) / glm::dot(fw, fw) * fw;
    f.right = glm::vec3(glm::normalize(rd));
  }
  f.up = glm::cross(f.right, f.forward);
  if (!(camera.vfov_degrees > 0.0f && camera.vfov_degrees < 180.0f))
    throw Error("camera: vertical field of view must lie in (0, 180) degrees");
  f.tan_half_fov = std::tan(glm::radians(camera.vfov_degrees) * 0.5f);
  return f;
}

shared::CameraParams camera_params(const Camera& camera, uint32_t width, uint32_t height) {
  if (width == 0 || height == 0) throw Error("camera: image size must be at least 1 x 1");
  const CameraFrame f = camera_frame(camera);
  shared::CameraParams c{};
  c.eye = camera.eye;
  c.tan_half_fov = f.tan_half_fov;
  c.right = f.right;
  c.aspect = float(width) / float(height);
  c.up = f.up;
  c.width = width;
  c.forward = f.forward;
  c.height = height;
  return c;
}

Ray camera_ray(const Camera& camera, uint32_t width, uint32_t height, uint32_t x, uint32_t y) {
  if (width == 0 || height == 0) throw Error("camera: image size must be at least 1 x 1");
  if (x >= width || y >= height) throw Error("camera: pixel outside the image");
  // The pixel centre's direction (common/shared/bounce.h, shared with the GPU gather)
  Ray ray;
  ray.org = camera.eye;
  ray.dir = shared::camera_direction(camera_params(camera, width, height), x, y);
  ray.tmin = 0.0f;
  ray.tmax = std::numeric_limits<float>::infinity();
  ray.launch_normal = glm::vec3(0.0f);
  ray.launch_ref = shared::kNoRef;
  return ray;
}

std::vector<Ray> camera_rays(const Camera& camera, uint32_t width, uint32_t height) {
  std::vector<Ray> rays;
  rays.reserve(size_t(width) * height);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) rays.push_back(camera_ray(camera, width, height, x, y));
  return rays;
}

std::vector<Ray> camera_grid_rays(const Camera& camera, size_t n) {
  const uint32_t w = std::max<uint32_t>(1, uint32_t(std::sqrt(double(n) * 16.0 / 9.0)));
  const uint32_t h = std::max<uint32_t>(1, uint32_t((n + w - 1) / w));
  std::vector<Ray> rays;
  rays.reserve(n);
  for (uint32_t y = 0; y < h && rays.size() < n; ++y)
    for (uint32_t x = 0; x < w && rays.size() < n; ++x) rays.push_back(camera_ray(camera, w, h, x, y));
  return rays;
}

}  // namespace gridrt
