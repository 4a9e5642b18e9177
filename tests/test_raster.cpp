// test_raster.cpp: the compute gather's rasterizer bounds (common/shared/raster.h) are
// conservative: every pixel the gather's ray test (either triangle test: Moller-Trumbore or the
// watertight one, plan::gather_options) accepts passes the pixel test and the tile and
// bin tests of every rectangle holding it, and its t is not below the triangle's depth bound nor
// its depth plane's bound over the pixel, its tile or its bin, on
// adversarial triangles (sub-pixel, huge, behind the camera, edge-on, slivers, far away, vertices on
// pixel centres and tile edges); and they do reject: most pixels far from a triangle fail them.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <random>

#include "gridrt/common/camera.h"
#include "gridrt/common/shared/raster.h"
#include "gridrt/common/shared/triangle.h"

using namespace gridrt;

namespace {

struct Counts {
  size_t triangles = 0, set_up = 0, accepted = 0, missed = 0, rejected_pixels = 0, rejected_tiles = 0;
  size_t pixel_fail = 0, tile_fail = 0, bin_fail = 0, depth_fail = 0;
  // The depth plane's bound over the pixel's 8x8 tile and 32x32 bin (raster_tile_t_lo): accepted
  // pixels whose t is below it, and those where it is above the triangle's own t_lo by 1 % or more
  size_t tile_depth_fail = 0, tile_depth_tighter = 0;
  // The gather's box (gather_box): accepted pixels outside it (edge box: any; frustum box: any
  // whose hit lies beyond the near plane), and accepted pixels whose hit is nearer than the near
  // plane, which a frustum box leaves out by its rule and the edge box holds
  size_t box_fail = 0, frustum_boxes = 0, within_near = 0, within_near_boxed = 0;
  size_t bound_needed = 0;  // accepted pixels beyond the near plane outside the frustum box without its rounding bound
  size_t within_near_edge = 0;  // accepted pixels nearer than the near plane held by an edge box
};

// The frame's near plane for the test's scale (VulkanFrame: the scene's extent x 1e-6).
constexpr float kNear = 1.0e-5f;

// Every pixel of a w x h image against one triangle, by the gather's ray test `which`
// (shared::kTriangleMoller or kTriangleWatertight: the grid's triangle test).
void check_triangle(uint32_t which, const shared::CameraParams& c, const glm::vec3& v0, const glm::vec3& v1,
                    const glm::vec3& v2, Counts& n) {
  glm::vec3 e0, e1, e2;
  glm::vec4 depth;
  float t_lo = 0.0f;
  ++n.triangles;
  n.set_up += shared::raster_setup_depth(c, shared::raster_camera(c), v0, v1, v2, e0, e1, e2, t_lo, depth);
  // The gather's box; it holds every accepted pixel whose hit lies beyond the near plane, and
  // every accepted pixel where the edge functions give it (set up, crossing the near plane)
  glm::uvec4 box(0u);
  const bool boxed = shared::gather_box(c, shared::raster_camera(c), kNear, v0, v1, v2, box);
  const glm::vec3 q0 = shared::gather_camera_space(c, v0), q1 = shared::gather_camera_space(c, v1),
                  q2 = shared::gather_camera_space(c, v2);
  glm::vec3 b0, b1, b2;
  float b_lo = 0.0f;
  const bool edge_box = std::min({q0.z, q1.z, q2.z}) < kNear && shared::raster_setup(c, shared::raster_camera(c), v0, v1, v2, b0, b1, b2, b_lo);
  n.frustum_boxes += !edge_box;
  glm::uvec4 box0(0u);
  const bool boxed0 = !edge_box && shared::gather_frustum_box(c, shared::raster_camera(c), kNear, q0, q1, q2, 0.0f, box0);
  for (uint32_t y = 0; y < c.height; ++y)
    for (uint32_t x = 0; x < c.width; ++x) {
      const glm::vec3 dir = shared::camera_direction(c, x, y);
      shared::TriangleTest r;
      const bool hit =
          shared::triangle_test(which, c.eye, dir, v0, v1, v2, 0.0f, INFINITY, INFINITY, -1.0f, r) == shared::kTestAccepted;
      const bool pixel = shared::raster_pixel_may_hit(e0, e1, e2, x, y);
      // The 8x8 tile and the 32x32 bin holding the pixel (clipped to the image), and a rectangle
      // of the pixel alone
      const uint32_t tx = x & ~7u, ty = y & ~7u, bx = x & ~31u, by = y & ~31u;
      const bool tile = shared::raster_rect_may_hit(e0, e1, e2, tx, ty, std::min(tx + 7, c.width - 1),
                                                    std::min(ty + 7, c.height - 1));
      const bool bin = shared::raster_rect_may_hit(e0, e1, e2, bx, by, std::min(bx + 31, c.width - 1),
                                                   std::min(by + 31, c.height - 1));
      const bool single = shared::raster_rect_may_hit(e0, e1, e2, x, y, x, y);
      if (hit) {
        ++n.accepted;
        n.pixel_fail += !pixel || !single;
        n.tile_fail += !tile;
        n.bin_fail += !bin;
        const float t = shared::moller_trumbore_t(r);
        n.depth_fail += !(t >= t_lo);
        const float tile_lo = shared::raster_tile_t_lo(depth, t_lo, tx, ty, std::min(tx + 7, c.width - 1),
                                                       std::min(ty + 7, c.height - 1));
        const float bin_lo = shared::raster_tile_t_lo(depth, t_lo, bx, by, std::min(bx + 31, c.width - 1),
                                                      std::min(by + 31, c.height - 1));
        const float pixel_lo = shared::raster_tile_t_lo(depth, t_lo, x, y, x, y);
        n.tile_depth_fail += !(t >= tile_lo) || !(t >= bin_lo) || !(t >= pixel_lo);
        n.tile_depth_tighter += tile_lo >= 1.01f * t_lo;
        const bool in_box = boxed && x >= box.x && x <= box.z && y >= box.y && y <= box.w;
        const float view_depth = glm::dot(shared::moller_trumbore_t(r) * dir, c.forward);
        const bool near = view_depth < kNear;
        n.within_near += near;
        n.within_near_boxed += near && in_box;
        n.within_near_edge += near && in_box && edge_box;
        n.box_fail += !in_box && (edge_box || !near);
        const bool in_box0 = boxed0 && x >= box0.x && x <= box0.z && y >= box0.y && y <= box0.w;
        n.bound_needed += !edge_box && !near && !in_box0;
      } else {
        ++n.missed;
        n.rejected_pixels += !pixel;
        n.rejected_tiles += !tile;
      }
    }
}

}  // namespace

TEST_CASE("Gather rasterizer: its bin, tile and pixel tests keep every pixel the ray test accepts", "[unit][gather]") {
  const uint32_t which = GENERATE(shared::kTriangleMoller, shared::kTriangleWatertight);
  INFO((which == shared::kTriangleWatertight ? "the watertight test" : "Moller-Trumbore"));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  auto rvec = [&] { return glm::vec3(u(rng), u(rng), u(rng)); };
  Counts n, near_eye;  // near_eye: the two near-eye families
  const uint32_t sizes[2][2] = {{64, 48}, {45, 37}};  // a multiple of the tile, and neither of tile nor bin
  // Cameras 24..29: up within 1e-6 to 1e-3 rad of the view direction, narrow fields of view among
  // them (an outside sweep: the float frame's right was 0.057 off the perpendicular there, and
  // the screen box and the depth plane left out accepted pixels)
  for (int cam = 0; cam < 30; ++cam) {
    Camera camera;
    camera.eye = 5.0f * rvec();
    camera.target = camera.eye + glm::vec3(u(rng), 0.3f * u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.01f);
    camera.vfov_degrees = 20.0f + 100.0f * (0.5f + 0.5f * u(rng));
    if (cam >= 24) {
      const glm::vec3 view = glm::normalize(camera.target - camera.eye);
      const glm::vec3 side = glm::normalize(glm::cross(view, glm::vec3(0.3f, 1.0f, 0.2f)));
      camera.up = view + std::pow(10.0f, -6.0f + float(cam - 24) * 0.6f) * side;
      if (cam % 2) camera.vfov_degrees = 0.5f + 3.5f * (0.5f + 0.5f * u(rng));
    }
    const uint32_t w = sizes[cam % 2][0], h = sizes[cam % 2][1];
    const shared::CameraParams c = camera_params(camera, w, h);
    const glm::vec3 eye = c.eye, f = c.forward, r = c.right, up = c.up;
    // A point in front of the eye at depth z through continuous pixel (px, py)
    auto at_pixel = [&](float px, float py, float z) {
      const float sx = (2.0f * px / float(w) - 1.0f) * c.tan_half_fov * c.aspect;
      const float sy = (1.0f - 2.0f * py / float(h)) * c.tan_half_fov;
      return eye + z * (f + sx * r + sy * up);
    };
    auto rpx = [&] { return (0.5f + 0.6f * u(rng)) * float(w); };
    auto rpy = [&] { return (0.5f + 0.6f * u(rng)) * float(h); };
    for (int i = 0; i < 78; ++i) {
      glm::vec3 v0, v1, v2;
      const float z = std::exp2(4.0f * u(rng));  // depths 1/16 .. 16
      switch (i % 13) {
        case 0:  // ordinary, across tiles and bins
          v0 = at_pixel(rpx(), rpy(), z);
          v1 = at_pixel(rpx(), rpy(), z * (1.0f + 0.5f * u(rng)));
          v2 = at_pixel(rpx(), rpy(), z * (1.0f + 0.5f * u(rng)));
          break;
        case 1: {  // sub-pixel, near a pixel centre
          const float px = std::floor(rpx()) + 0.5f, py = std::floor(rpy()) + 0.5f, s = 0.3f * (1.0f + u(rng));
          v0 = at_pixel(px - s, py - s, z);
          v1 = at_pixel(px + s, py, z);
          v2 = at_pixel(px, py + s, z);
          break;
        }
        case 2:  // vertices exactly on pixel centres and on tile corners
          v0 = at_pixel(8.0f * std::floor(rpx() / 8.0f), 8.0f * std::floor(rpy() / 8.0f), z);
          v1 = at_pixel(std::floor(rpx()) + 0.5f, std::floor(rpy()) + 0.5f, z);
          v2 = at_pixel(32.0f, std::floor(rpy()) + 0.5f, z * 1.5f);
          break;
        case 3:  // huge, around the eye
          v0 = eye + 1.0e4f * rvec();
          v1 = eye + 1.0e4f * rvec();
          v2 = eye + 1.0e4f * rvec();
          break;
        case 4:  // one vertex behind the eye
          v0 = at_pixel(rpx(), rpy(), z);
          v1 = at_pixel(rpx(), rpy(), z);
          v2 = eye - z * f + 3.0f * z * rvec();
          break;
        case 5:  // two behind the eye
          v0 = at_pixel(rpx(), rpy(), z);
          v1 = eye - z * f + z * rvec();
          v2 = eye - 2.0f * z * f + z * rvec();
          break;
        case 6: {  // nearly edge-on: the plane passes within a hair of the eye
          const glm::vec3 a = glm::normalize(rvec() + f), b = glm::normalize(glm::cross(a, rvec()));
          const glm::vec3 nrm = glm::cross(a, b);
          const float hair = std::exp2(-8.0f - 14.0f * (0.5f + 0.5f * u(rng)));
          v0 = eye + z * (a + 0.5f * u(rng) * b) + hair * nrm;
          v1 = eye + z * (2.0f * a + u(rng) * b) + hair * nrm;
          v2 = eye + z * (0.5f * a + u(rng) * b) + hair * nrm;
          break;
        }
        case 7: {  // sliver: v2 almost on the line v0 v1
          v0 = at_pixel(rpx(), rpy(), z);
          v1 = at_pixel(rpx(), rpy(), 2.0f * z);
          v2 = v0 + (0.5f + 0.4f * u(rng)) * (v1 - v0) + 1.0e-4f * z * rvec();
          break;
        }
        case 8: {  // far and small (a few pixels)
          const float far = 1.0e3f * (1.5f + u(rng));
          const float px = rpx(), py = rpy();
          v0 = at_pixel(px, py, far);
          v1 = at_pixel(px + 3.0f * u(rng), py + 3.0f, far);
          v2 = at_pixel(px + 3.0f, py + 3.0f * u(rng), far);
          break;
        }
        case 10: {  // large, its plane a fraction of a near plane to 16 near planes from the eye
          const glm::vec3 nrm = glm::normalize(rvec()), t1 = glm::normalize(glm::cross(nrm, rvec()));
          const glm::vec3 t2 = glm::cross(nrm, t1);
          const glm::vec3 o = eye + kNear * std::exp2(-1.0f + 5.0f * (0.5f + 0.5f * u(rng))) * nrm;
          auto around = [&] {
            const float a = 3.14159265f * u(rng), l = 10.0f * (1.0f + 0.5f * u(rng));
            return o + l * (std::cos(a) * t1 + std::sin(a) * t2);
          };
          v0 = around();
          v1 = around();
          v2 = around();
          break;
        }
        case 11: {  // large, an edge passing a fraction of a near plane to 16 near planes from the eye
          const glm::vec3 a = glm::normalize(rvec()), nrm = glm::normalize(glm::cross(a, rvec()));
          const glm::vec3 p = eye + kNear * std::exp2(-1.0f + 5.0f * (0.5f + 0.5f * u(rng))) * nrm;
          v0 = p - 10.0f * (1.0f + 0.5f * u(rng)) * a;
          v1 = p + 10.0f * (1.0f + 0.5f * u(rng)) * a;
          v2 = p + 10.0f * glm::normalize(glm::cross(a, rvec()) + 0.5f * rvec());
          break;
        }
        case 12: {  // small, around the eye: crossing the near plane, hits nearer than it
          const glm::vec3 o = eye + kNear * (2.0f * f + 2.0f * rvec());
          v0 = o + 4.0f * kNear * rvec();
          v1 = o + 4.0f * kNear * rvec();
          v2 = o + 4.0f * kNear * rvec();
          break;
        }
        default:  // a screen-filling one, partly behind the eye
          v0 = at_pixel(-2.0f * float(w), 0.5f * float(h), z);
          v1 = at_pixel(3.0f * float(w), -float(h), z * 0.5f);
          v2 = eye + z * (0.2f * u(rng) * f + 2.0f * up) - 4.0f * z * f;
          break;
      }
      check_triangle(which, c, v0, v1, v2, i % 13 >= 10 ? near_eye : n);
    }
  }
  INFO(n.triangles << " triangles (" << n.set_up << " set up with bounds), " << n.accepted << " accepted pixels, "
                   << n.missed << " others, of them " << n.rejected_pixels << " rejected by the pixel test and "
                   << n.rejected_tiles << " by the tile test");
  CHECK(n.pixel_fail == 0);
  CHECK(n.tile_fail == 0);
  CHECK(n.bin_fail == 0);
  CHECK(n.depth_fail == 0);
  CHECK(n.tile_depth_fail == 0);
  CHECK(n.accepted > 10000);
  // The depth plane's bound is the tighter one for many accepted pixels (triangles seen at an angle)
  INFO(n.tile_depth_tighter << " accepted pixels whose tile's depth-plane bound is 1 % or more above t_lo");
  CHECK(n.tile_depth_tighter >= n.accepted / 10);
  // The gather's box holds every pixel the test accepts, hits within the near plane included
  // where the edge functions give the box; the near-eye families reach such hits
  CHECK(n.box_fail == 0);
  {
    const Counts& e = near_eye;
    INFO("near the eye: " << e.triangles << " triangles, " << e.frustum_boxes << " boxed by the frustum, " << e.accepted
                          << " accepted pixels, " << e.within_near << " with the hit nearer than the near plane, "
                          << e.within_near_boxed << " of them in the box; " << e.bound_needed
                          << " beyond it outside the frustum box without its rounding bound; " << e.within_near_edge
                          << " nearer than the near plane held by an edge box");
    CHECK(e.pixel_fail + e.tile_fail + e.bin_fail + e.depth_fail + e.tile_depth_fail == 0);
    CHECK(e.box_fail == 0);
    CHECK(e.accepted > 10000);
    CHECK(e.within_near_boxed >= 100);
    CHECK(e.bound_needed > 0);       // the families reach where the bound is needed
    CHECK(e.within_near_edge >= 50);  // and hits nearer than the near plane, which edge boxes hold
  }
  // The bounds exist for most triangles and reject most pixels the test misses
  CHECK(n.set_up >= n.triangles * 8 / 10);
  CHECK(n.rejected_pixels >= n.missed * 3 / 4);
  CHECK(n.rejected_tiles >= n.missed / 2);
  // Degenerate set-ups keep everything (the fallback): no bounds where none are guaranteed
  glm::vec3 e0, e1, e2;
  float t_lo = 1.0f;
  const shared::CameraParams c = camera_params(Camera{}, 64, 48);
  glm::vec4 depth(1.0f);
  CHECK_FALSE(shared::raster_setup_depth(c, shared::raster_camera(c), glm::vec3(0.0f), glm::vec3(1.0f, 0.0f, 0.0f), glm::vec3(NAN, 0.0f, 0.0f), e0, e1,
                                         e2, t_lo, depth));
  CHECK(shared::raster_pixel_may_hit(e0, e1, e2, 3, 4));
  CHECK(t_lo == 0.0f);
  CHECK(shared::raster_tile_t_lo(depth, t_lo, 0, 0, 7, 7) == 0.0f);
  // the eye in the triangle's plane
  CHECK_FALSE(shared::raster_setup(c, shared::raster_camera(c), c.eye + glm::vec3(-1, 0, -1), c.eye + glm::vec3(1, 0, -1), c.eye + glm::vec3(0, 0, -3),
                                   e0, e1, e2, t_lo));
}

// An outside sweep's cameras: up within about 1e-6 and 1e-4 rad of the view direction. The float
// frame's right was 0.057 and 5e-4 off the perpendicular, so the screen box (which projects with
// the frame as if orthonormal) lay up to 29 pixels beside the pixels the test accepts, and the
// depth plane's |d| >= 1 failed (its tile bound above the winning triangle's t): the GPU gather
// lost those pixels. camera_frame now makes such a frame's right in double, perpendicular.
TEST_CASE("Gather rasterizer: a camera whose up nearly follows its view keeps every accepted pixel in its bounds",
          "[unit][gather]") {
  struct Case {
    Camera camera;
    uint32_t w, h;
    std::vector<glm::vec3> v;  // triangles, three vertices each
  };
  Camera skew;
  skew.eye = glm::vec3(0.0f);
  skew.target = glm::vec3(0.785459936f, -0.722745419f, 0.783881724f);
  skew.up = glm::vec3(0.93749404f, -0.862640262f, 0.935608327f);
  skew.vfov_degrees = 4.0f;
  Camera mild;
  mild.eye = glm::vec3(0.0f);
  mild.target = glm::vec3(-0.760544777f, -0.660571456f, 0.761186421f);
  mild.up = glm::vec3(-0.965892434f, -0.839051783f, 0.966607451f);
  mild.vfov_degrees = 0.5f;
  const std::vector<Case> cases = {
      {skew, 129, 37,
       {{3.51678864f, -6.72757339f, 7.16742311f}, {7.19936248f, -6.70132019f, 3.5016407f}, {7.07720551f, -2.94376454f, 7.08854093f},
        {-35.4776313f, -49.436714f, -0.0969786288f}, {45.1094912f, 38.3439456f, 14.0547523f}, {6.53714901f, -6.66984167f, 4.1459999f},
        {5.90070037f, -5.53817993f, 5.87454664f}, {5.94858205f, -5.48022457f, 5.88060458f}, {5.88713946f, -5.48451723f, 5.93815289f}}},
      {mild, 97, 120,
       {{-6.02500585f, -5.23221769f, 6.02687337f}, {-6.02268471f, -5.2333095f, 6.02824523f}, {-6.02390486f, -5.23053796f, 6.02943139f}}}};
  for (const Case& k : cases) {
    const shared::CameraParams c = camera_params(k.camera, k.w, k.h);
    INFO("forward . right " << glm::dot(c.forward, c.right) << ", forward . up " << glm::dot(c.forward, c.up));
    CHECK(std::abs(glm::dot(c.forward, c.right)) < 1.0e-6f);
    Counts n;
    for (size_t t = 0; t + 2 < k.v.size(); t += 3) check_triangle(shared::kTriangleWatertight, c, k.v[t], k.v[t + 1], k.v[t + 2], n);
    INFO(n.accepted << " accepted pixels");
    CHECK(n.accepted > 0);
    CHECK(n.box_fail == 0);
    CHECK(n.depth_fail + n.tile_depth_fail == 0);
    CHECK(n.pixel_fail + n.tile_fail + n.bin_fail == 0);
  }
}

// gather_frustum_box projects a triangle inside every clip plane as it is, without clipping: the
// same box as clipping it (each clip keeps its vertices in order) on every triangle, inside the
// frustum, across its sides and the near plane, and wholly outside.
TEST_CASE("Gather frustum box: a triangle inside every plane gets the box its clipped polygon gives", "[unit][gather]") {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> u(-1.0f, 1.0f);
  size_t inside = 0, clipped = 0, boxed = 0;
  for (int cam = 0; cam < 16; ++cam) {
    Camera camera;
    camera.eye = 3.0f * glm::vec3(u(rng), u(rng), u(rng));
    camera.target = camera.eye + glm::vec3(u(rng), 0.3f * u(rng), u(rng)) + glm::vec3(0.0f, 0.0f, 0.01f);
    camera.vfov_degrees = 20.0f + 100.0f * (0.5f + 0.5f * u(rng));
    const shared::CameraParams c = camera_params(camera, cam % 2 ? 64u : 45u, cam % 2 ? 48u : 37u);
    for (int i = 0; i < 2000; ++i) {
      // Camera-space vertices: mostly in front, some spread wide of the frustum or behind the eye
      const float spread = i % 3 == 0 ? 4.0f : 0.5f;
      auto vertex = [&] {
        const float z = std::exp2(3.0f * u(rng)) * (i % 7 == 0 ? u(rng) : 1.0f);
        return glm::vec3(spread * z * u(rng), spread * z * u(rng), z);
      };
      const glm::vec3 q0 = vertex(), q1 = vertex(), q2 = vertex();
      glm::uvec4 box(0u);
      const bool got = shared::gather_frustum_box(c, shared::raster_camera(c), kNear, q0, q1, q2, shared::kGatherFrustumRounding, box);
      // The polygon path, every plane clipped
      const float tx = c.tan_half_fov * c.aspect;
      const float kx = tx * (1.0f + shared::sh_div(4.0f, float(c.width)));
      const float ky = c.tan_half_fov * (1.0f + shared::sh_div(4.0f, float(c.height)));
      shared::GatherPolygon poly = shared::gather_polygon_empty();
      poly.v[0] = q0;
      poly.v[1] = q1;
      poly.v[2] = q2;
      poly.n = 3u;
      const glm::vec4 planes[5] = {{0.0f, 0.0f, 1.0f, -kNear}, {1.0f, 0.0f, kx, 0.0f}, {-1.0f, 0.0f, kx, 0.0f},
                                   {0.0f, 1.0f, ky, 0.0f}, {0.0f, -1.0f, ky, 0.0f}};
      bool all_in = true;
      for (const glm::vec4& p : planes)
        for (const glm::vec3& q : {q0, q1, q2}) all_in = all_in && shared::gather_plane_side(p, q) >= 0.0f;
      inside += all_in;
      for (const glm::vec4& p : planes)
        if (poly.n >= 3u) poly = shared::gather_clip(poly, p);
      clipped += !all_in;
      glm::uvec4 box0(0u);
      bool got0 = false;
      if (poly.n >= 3u) {
        const float m = std::max({shared::raster_norm1(q0), shared::raster_norm1(q1), shared::raster_norm1(q2)});
        const float px = shared::sh_div(0.5f * float(c.width), tx), py = shared::sh_div(0.5f * float(c.height), c.tan_half_fov);
        const float cx = 0.5f * float(c.width) - 0.5f, cy = 0.5f * float(c.height) - 0.5f;
        glm::vec2 lo(3.0e38f), hi(-3.0e38f);
        for (uint32_t k = 0; k < poly.n; ++k)
          shared::gather_frustum_extend(poly.v[k], kNear, shared::kGatherFrustumRounding, m, px, py, cx, cy, lo, hi);
        got0 = shared::gather_box_of(c, lo, hi, box0);
      }
      INFO("camera " << cam << ", triangle " << i);
      REQUIRE(got == got0);
      if (got) REQUIRE(box == box0);
      boxed += got;
    }
  }
  // Both paths taken, and most triangles give a box
  CHECK(inside > 5000);
  CHECK(clipped > 5000);
  CHECK(boxed > 10000);
}
