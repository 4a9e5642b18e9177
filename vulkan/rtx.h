// rtx.h: the device's own ray tracing (VK_KHR_ray_tracing_pipeline, VK_KHR_acceleration_structure)
// side by side with the grid, on the grid's device data (docs/VULKAN.md, "The RT pipeline side
// by side"):
//   acceleration structures  one BLAS per scene instance over the grid's world-space geometry
//                            buffer (the very triangles the grid tests: GridTriangle's three
//                            vertices at stride 16, not indexed), identity instance transforms,
//                            instanceCustomIndex = the scene instance, primitive index = the
//                            triangle. Static instances' BLASes are built once; dynamic ones
//                            (ALLOW_UPDATE) are refitted (or rebuilt) each frame after the
//                            grid's update rewrote their triangles; the TLAS is rebuilt each frame.
//                            Geometry is opaque unless the instance is alpha-keyed; the rays
//                            go through the any-hit shader regardless (RtxOptions::any_hit_all).
//   shaders                  rtx.rgen reads RayRecords and writes HitRecords in the grid's layout;
//                            rtx.rahit ignores the launch triangle and alpha-keyed cut-outs with
//                            the shared alpha test; rtx.rchit reports the closest hit.
// A device without ray tracing (lavapipe) is an Error naming the device and what it lacks.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "gridrt/common/tracer.h"
#include "gridrt/vulkan/grid.h"

namespace gridrt::vulkan {

struct RtxOptions {
  // Every triangle through the any-hit shader (ray flag NoOpaque, the default): the launch
  // triangle is then ignored exactly where the grid ignores it. false: the geometry as built,
  // opaque where the instance has no alpha mask, and a ray whose closest opaque hit is its launch
  // triangle traced again from just past that hit (rtx.rgen). Measured on the H200 the default is
  // the faster (0.56-0.66 against 0.83-1.00 ms on Sibenik and Sponza: about half the bounce rays
  // start on an opaque triangle and would need a second trace; docs/BENCHMARKS.md).
  bool any_hit_all = true;
  // Dynamic instances' BLASes rebuilt each frame instead of refitted.
  bool rebuild_dynamic = false;
};

// Device milliseconds (timestamp queries; 0 without timestamps).
struct RtxTimings {
  double static_build_ms = 0.0;  // the static instances' BLASes, once (in the constructor)
  double first_build_ms = 0.0;   // the constructor's whole build: static + dynamic BLASes + TLAS
  double update_ms = 0.0;        // the last update: dynamic BLASes refitted + TLAS rebuilt
  double refit_ms = 0.0;         // ... of which the dynamic BLASes
  double tlas_ms = 0.0;          // ... of which the TLAS
  double trace_ms = 0.0;         // the last trace
  double host_ms = 0.0;          // the last update_and_trace, submit to fence
};

// Memory of the acceleration structures, bytes.
struct RtxMemory {
  uint64_t static_blas = 0, dynamic_blas = 0, tlas = 0, scratch = 0;
};

// Why `ctx` cannot run the ray tracing side by side, "" if it can: the device name and what it
// lacks, or that the context was made without ContextOptions::ray_tracing.
std::string rtx_unsupported(const Context& ctx);

class VulkanRtxTracer {
 public:
  // Builds the acceleration structures over `grid`'s geometry buffer as it stands (build the grid
  // first; the grid's context must have been made with ContextOptions::ray_tracing). Throws Error
  // ("... ray tracing side by side needs ...") when the device lacks it. Valid until the grid's
  // next build(), which makes new buffers.
  explicit VulkanRtxTracer(VulkanGridTracer& grid, RtxOptions options = {});
  ~VulkanRtxTracer();
  VulkanRtxTracer(const VulkanRtxTracer&) = delete;
  VulkanRtxTracer& operator=(const VulkanRtxTracer&) = delete;

  // One submission: the dynamic BLASes refitted to the grid's geometry buffer (after the grid's
  // update), the TLAS rebuilt, then rays [0, count) of `rays` (RayRecord) traced into `hits`
  // (HitRecord), each part timestamped. `rays` and `hits` are storage buffers the caller keeps.
  void update_and_trace(const Buffer& rays, const Buffer& hits, uint32_t count);
  // The same for rays on the host: upload, update and trace, download.
  void update_and_trace(std::span<const Ray> rays, std::span<Hit> hits);

  const RtxTimings& timings() const { return timings_; }
  const RtxMemory& memory() const { return memory_; }
  const RtxOptions& options() const { return options_; }
  uint32_t dynamic_instance_count() const;

 private:
  struct Gpu;
  // The constructor's steps
  void describe_blases(bool alpha);
  Buffer create_structures(VkDeviceSize scratch_align);
  void first_build(const Buffer& first_scratch, VkDeviceSize scratch_align);
  void create_pipeline();
  void record_update(VkCommandBuffer cb);
  void record_trace(VkCommandBuffer cb, uint32_t count);

  VulkanGridTracer& grid_;
  Context& ctx_;
  RtxOptions options_;
  std::unique_ptr<Gpu> gpu_;
  RtxTimings timings_;
  RtxMemory memory_;
};

}  // namespace gridrt::vulkan
