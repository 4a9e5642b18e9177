// portal.h: the Vulkan port of the portal ("div") tracer ("A Novel Raytracing Algorithm for GPU", docs/PORTAL.md), behind the
// same interface as reference/portal's PortalTracer and held to it bit for bit on lavapipe. The
// CPU builds the divs (reference::portal::build_portal); the GPU traces them from the packed
// textures exactly as the paper stores them:
//   atlas     R16_UINT 2D image (neighbour div, wall + material, or outside), texelFetch
//   div info  RGBA8_UINT 2D image, 8 texels per div, lexicographically packed, texelFetch
//   start map R16_UINT 3D image, one texel per voxel (not in the paper; docs/PORTAL.md)
// Passes: portal_trace.comp (one invocation per ray, hit records as PortalTracer's) and
// portal_render.comp (primary + two shadow rays per pixel, non-forking refraction) as the
// single-loop state machine or as three separate loops (three dispatches).
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "gridrt/common/scene.h"
#include "gridrt/common/tracer.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/vulkan/context.h"
#include "gridrt/vulkan/pipeline.h"
#include "gridrt/vulkan/shaders/portal_input.h"

namespace gridrt::vulkan {

// Milliseconds of the last trace and render: device (timestamps; 0 without) and host (submit to
// fence, the passes only). lavapipe's timestamps do not bracket dispatches (docs/VULKAN.md).
struct PortalTimings {
  double trace_ms = 0.0, trace_host_ms = 0.0;
  double render_ms = 0.0, render_host_ms = 0.0;
};

// The shader's own record of one ray: the start, then one event per div visited.
struct PortalExplainRecord {
  Ray ray{};
  std::vector<shared::PortalExplainEvent> events;
  Hit hit{};
};

class PortalVulkanTracer final : public Tracer {
 public:
  // On its own context (ContextOptions::from_env(); no geometry shader needed).
  explicit PortalVulkanTracer(uint32_t resolution = 64, portal::PortalOptions options = {});
  explicit PortalVulkanTracer(portal::World world, portal::PortalOptions options = {});
  explicit PortalVulkanTracer(portal::PortalBuild build, portal::PortalOptions options = {});
  // On a context the caller keeps alive.
  PortalVulkanTracer(Context& ctx, portal::PortalBuild build);
  ~PortalVulkanTracer() override;

  std::string name() const override { return "portal-vulkan"; }
  void build_scene(const Scene& scene, float time) override;  // voxelize at `resolution`, build, upload
  void update_to(float) override {}
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override;
  AccelDump dump() const override;  // kind "portal": the atlas texels read back from the device

  // Renders as reference/portal's render() does (options.threads is ignored). Linear RGB, row 0
  // at the top.
  std::vector<glm::vec3> render(const Camera& camera, const portal::RenderOptions& options = {},
                                portal::RenderStats* stats = nullptr);
  // Every pixel's final state (colour, steps, refractions) of the last render.
  const std::vector<shared::PortalPixel>& last_pixels() const { return pixels_; }

  // Traces `ray` with the explain pass: the shader's own record.
  PortalExplainRecord explain_ray(const Ray& ray);
  // The shader's record of `ray` as text beside the reference's (trace_portal on the CPU), the
  // first event where they part marked.
  std::string explain(const Ray& ray);

  const portal::PortalBuild& portal() const;
  const PortalTimings& timings() const { return timings_; }
  Context& context() const { return *ctx_; }

 private:
  struct Gpu;
  void upload();
  void run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t explain_index);

  std::unique_ptr<Context> owned_;
  Context* ctx_ = nullptr;
  uint32_t resolution_ = 64;
  portal::PortalOptions options_;
  std::unique_ptr<portal::PortalBuild> build_;
  std::unique_ptr<Gpu> gpu_;
  std::vector<shared::PortalPixel> pixels_;
  PortalTimings timings_;
};

// Text of one explain record, line per event, in the reference's words.
std::string to_text(const PortalExplainRecord& record, const portal::PortalBuild& build);

}  // namespace gridrt::vulkan
