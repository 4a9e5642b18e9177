// portal.cpp: PortalVulkanTracer, the host side of the Vulkan portal tracer (see portal.h). The
// CPU builds the divs; this file uploads the packed textures as the paper stores them, records the
// trace and render passes (vulkan/shaders/portal_*.comp) and reads the results back.
#include "gridrt/vulkan/portal.h"
#include "gridrt/vulkan/ray_pass.h"
#include "gridrt/common/util.h"

#include <algorithm>
#include <chrono>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <sstream>

#include "gridrt/common/camera.h"

namespace gridrt::vulkan {

namespace sh = gridrt::shared;
using portal::face_name;
using portal::texel_text;

namespace {

// The descriptor set's bindings: portal_input.h.

// Push constants and the specialization constant: portal_input.h.
using shared::kPortalNoExplain;
using shared::PortalTracePush;
constexpr uint32_t kExplainCapacity = 1u << 14;
constexpr VkDeviceSize kExplainHeader = 16;  // count + padding before the events

ContextOptions context_options() {
  ContextOptions o = ContextOptions::from_env();
  o.raster_build = false;  // compute passes only
  return o;
}

template <class T>
Buffer make_buffer(Context& ctx, const std::vector<T>& data) {
  Buffer b = ctx.create_buffer(std::max<size_t>(data.size() * sizeof(T), 16), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  if (!data.empty()) ctx.upload(b, data.data(), data.size() * sizeof(T));
  return b;
}

void image_barrier(VkCommandBuffer cb, VkImage image, VkImageLayout from, VkImageLayout to, VkAccessFlags src_access,
                   VkAccessFlags dst_access, VkPipelineStageFlags src, VkPipelineStageFlags dst) {
  VkImageMemoryBarrier b{VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER};
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(cb, src, dst, 0, 0, nullptr, 0, nullptr, 1, &b);
}

// A sampled texture of `format` (2D when extent.z == 1 and !three_d, else 3D) holding `bytes`,
// left in SHADER_READ_ONLY_OPTIMAL.
Image3D make_texture(Context& ctx, VkFormat format, bool three_d, glm::uvec3 extent, const void* bytes, size_t size,
                     const char* what) {
  const VkPhysicalDeviceLimits& lim = ctx.info().limits;
  const uint32_t max_dim = three_d ? lim.maxImageDimension3D : lim.maxImageDimension2D;
  if (std::max({extent.x, extent.y, extent.z}) > max_dim) {
    // The remedy the texture allows: the atlas's rows trade against its width (a narrower atlas is
    // taller: the advice was "narrower" for a too tall one, an outside sweep); the others follow
    // the world's size alone
    const bool atlas = std::string(what) == "atlas";
    const std::string remedy =
        !atlas ? "use a smaller world"
        : extent.y > max_dim
            ? (uint64_t(extent.x) * extent.y <= uint64_t(max_dim) * max_dim
                   ? "give a wider atlas (--atlas-width " +
                         std::to_string(std::min<uint64_t>(max_dim, (uint64_t(extent.x) * extent.y + max_dim - 1) / max_dim)) +
                         " or more, at most " + std::to_string(max_dim) + ") or use a smaller world"
                   : std::string("use a smaller world (its atlas holds more texels than a square image of that side)"))
            : "give a narrower atlas (--atlas-width " + std::to_string(max_dim) + " or less) or use a smaller world";
    throw Error(std::string("the portal's ") + what + " (" + std::to_string(extent.x) + " x " + std::to_string(extent.y) +
                (three_d ? " x " + std::to_string(extent.z) : std::string()) + ") exceeds " +
                (three_d ? "maxImageDimension3D" : "maxImageDimension2D") + " (" + std::to_string(max_dim) + ") on " +
                ctx.info().name + ": " + remedy + ", or --backend portal-cpu");
  }
  ctx.require_allocation(size, what);
  Image3D img = ctx.create_image(three_d ? VK_IMAGE_TYPE_3D : VK_IMAGE_TYPE_2D, format, extent,
                                 VK_IMAGE_USAGE_SAMPLED_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT | VK_IMAGE_USAGE_TRANSFER_DST_BIT);

  // Upload through a staging buffer; the texture then stays in SHADER_READ_ONLY_OPTIMAL.
  Buffer staging = ctx.create_buffer(std::max<size_t>(size, 16), VK_BUFFER_USAGE_TRANSFER_SRC_BIT, Memory::Host);
  ctx.upload(staging, bytes, size);
  ctx.submit([&](VkCommandBuffer cb) {
    image_barrier(cb, img.image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {extent.x, extent.y, extent.z};
    vkCmdCopyBufferToImage(cb, staging.buffer, img.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1, &region);
    image_barrier(cb, img.image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                  VK_ACCESS_TRANSFER_WRITE_BIT, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  });
  return img;
}

std::string fmt(const char* f, ...) __attribute__((format(printf, 1, 2)));
std::string fmt(const char* f, ...) {
  char buf[512];
  va_list ap;
  va_start(ap, f);
  std::vsnprintf(buf, sizeof buf, f, ap);
  va_end(ap);
  return buf;
}


std::vector<std::string> lines_of(const std::string& s) {
  std::vector<std::string> out;
  std::istringstream in(s);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// The portal tracer's own context: a failure's way out names the portal verbs' CPU backend
// (the grid's advice, "use --backend cpu", is a backend they do not take)
std::unique_ptr<Context> portal_context() {
  try {
    return std::make_unique<Context>(context_options());
  } catch (const Error& e) {
    std::string what = e.what();
    const std::string grid_way = "--backend cpu";
    for (size_t at = what.find(grid_way); at != std::string::npos; at = what.find(grid_way, at + 1))
      what.replace(at, grid_way.size(), "--backend portal-cpu (portal render and explain; portal diff and bench compare with the device and need it)");
    throw Error(what);
  }
}

}  // namespace

struct PortalVulkanTracer::Gpu {
  Image3D atlas, info, start;
  Buffer params, materials, rays, hits, explain, render_params, pixels;
  size_t ray_capacity = 0, pixel_capacity = 0;
  std::unique_ptr<Descriptors> set;
  std::unique_ptr<Pipeline> trace, trace_explain, render;
  std::unique_ptr<Timestamps> timestamps;
};

PortalVulkanTracer::PortalVulkanTracer(uint32_t resolution, portal::PortalOptions options)
    : owned_(portal_context()), ctx_(owned_.get()), resolution_(resolution),
      options_(options) {}

PortalVulkanTracer::PortalVulkanTracer(portal::World world, portal::PortalOptions options)
    : PortalVulkanTracer(portal::build_portal(std::move(world), options), options) {}

PortalVulkanTracer::PortalVulkanTracer(portal::PortalBuild build, portal::PortalOptions options)
    : owned_(portal_context()), ctx_(owned_.get()), resolution_(0), options_(options),
      build_(std::make_unique<portal::PortalBuild>(std::move(build))) {
  upload();
  set_built();
}

PortalVulkanTracer::PortalVulkanTracer(Context& ctx, portal::PortalBuild build)
    : ctx_(&ctx), resolution_(0), build_(std::make_unique<portal::PortalBuild>(std::move(build))) {
  upload();
  set_built();
}

PortalVulkanTracer::~PortalVulkanTracer() {
  gpu_.reset();  // before an owned context goes
}

const portal::PortalBuild& PortalVulkanTracer::portal() const {
  if (!build_) throw Error("portal-vulkan: not built");
  return *build_;
}

void PortalVulkanTracer::build_scene(const Scene& scene, float) {
  build_.reset();
  gpu_.reset();
  try {
    build_ = std::make_unique<portal::PortalBuild>(
        portal::build_portal(portal::voxelize(scene, resolution_ ? resolution_ : 64), options_));
    upload();
  } catch (...) {
    build_.reset();  // as before any build (Tracer::build)
    gpu_.reset();
    throw;
  }
}

// The packed textures, as the reference holds them (PackedPortal), to the device.
void PortalVulkanTracer::upload() {
  Context& ctx = *ctx_;
  const portal::PackedPortal& p = portal().packed;
  gpu_.reset();
  gpu_ = std::make_unique<Gpu>();
  Gpu& gpu = *gpu_;

  // The three textures: atlas, div info, start map
  gpu.atlas = make_texture(ctx, VK_FORMAT_R16_UINT, false, {p.atlas_width, p.atlas_height, 1}, p.atlas.data(),
                           p.atlas.size() * sizeof(uint16_t), "atlas");
  gpu.info = make_texture(ctx, VK_FORMAT_R8G8B8A8_UINT, false, {p.info_width, p.info_height, 1}, p.info.data(),
                          p.info.size(), "div info");
  // The start map: level 0's voxels, then (mip-mapped space) each coarser level's block below.
  gpu.start = make_texture(ctx, VK_FORMAT_R16_UINT, true, {p.dims.x, p.dims.y, p.start_depth ? p.start_depth : p.dims.z},
                           p.start.data(), p.start.size() * sizeof(uint16_t), "start map");

  // Scalars and the renderer's materials
  sh::PortalParams params{};
  params.origin = p.origin;
  params.inv_voxel_size = 1.0f / p.voxel_size;  // as to_voxel_ray computes it
  params.dims = p.dims;
  params.div_count = p.div_count;
  params.atlas_width = p.atlas_width;
  params.info_width = p.info_width;
  params.levels = p.levels;
  params.mip_distance = p.mip_distance;
  params.scale_log2 = p.scale_log2;
  params.instance_base = p.instance_base;
  params.blocks = p.blocks;
  params.top_divs = p.scale_log2 ? p.top_divs : p.div_count;  // no instancing: every div is the top level's
  params.block_start = p.block_start;
  gpu.params = make_buffer(ctx, std::vector<sh::PortalParams>{params});
  std::vector<sh::PortalMaterial> materials;
  for (const portal::WallMaterial& m : portal().world.materials)
    materials.push_back({m.color, m.ior, m.filter, m.glass ? 1u : 0u, m.coverage, m.resolve ? 1u : 0u, 0u, 0u});
  gpu.materials = make_buffer(ctx, materials);
  gpu.rays = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.hits = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.explain = ctx.create_buffer(kExplainHeader + VkDeviceSize(kExplainCapacity) * sizeof(sh::PortalExplainEvent),
                                  VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.render_params = ctx.create_buffer(sizeof(sh::PortalRenderParams), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  gpu.pixels = ctx.create_buffer(16, VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);

  // The descriptor set and the pipelines
  const VkDescriptorType si = VK_DESCRIPTOR_TYPE_SAMPLED_IMAGE, sb = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  gpu.set = std::make_unique<Descriptors>(ctx, std::initializer_list<VkDescriptorType>{si, si, si, sb, sb, sb, sb, sb, sb, sb},
                                          VK_SHADER_STAGE_COMPUTE_BIT);
  Descriptors& set = *gpu.set;
  set.bind(shared::kPortalBindAtlas, gpu.atlas.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  set.bind(shared::kPortalBindInfo, gpu.info.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  set.bind(shared::kPortalBindStart, gpu.start.view, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL);
  set.bind(shared::kPortalBindParams, gpu.params);
  set.bind(shared::kPortalBindRays, gpu.rays);
  set.bind(shared::kPortalBindHits, gpu.hits);
  set.bind(shared::kPortalBindExplain, gpu.explain);
  set.bind(shared::kPortalBindRenderParams, gpu.render_params);
  set.bind(shared::kPortalBindMaterials, gpu.materials);
  set.bind(shared::kPortalBindPixels, gpu.pixels);
  gpu.trace = std::make_unique<Pipeline>(ctx, "portal_trace.comp", set.layout(), uint32_t(sizeof(PortalTracePush)),
                                         SpecConstants().add(shared::kPortalSpecExplain, false));
  gpu.render = std::make_unique<Pipeline>(ctx, "portal_render.comp", set.layout(),
                                          uint32_t(sizeof(shared::PortalRenderPush)));
  if (ctx.info().timestamp_valid_bits) gpu.timestamps = std::make_unique<Timestamps>(ctx, 2);
}

void PortalVulkanTracer::run_trace(std::span<const Ray> rays, std::span<Hit> hits, uint32_t explain_index) {
  if (hits.size() != rays.size()) throw Error("portal-vulkan: rays and hits differ in size");
  if (!gpu_) throw Error("portal-vulkan: not built");
  if (rays.empty()) return;
  Context& ctx = *ctx_;
  Gpu& gpu = *gpu_;
  // Ray and hit buffers, grown as needed
  if (grow_ray_buffers(ctx, rays.size(), gpu.rays, gpu.hits, gpu.ray_capacity)) {
    gpu.set->bind(shared::kPortalBindRays, gpu.rays);
    gpu.set->bind(shared::kPortalBindHits, gpu.hits);
  }
  ctx.upload(gpu.rays, rays.data(), rays.size_bytes());
  const bool explain = explain_index != kPortalNoExplain;
  if (explain && !gpu.trace_explain)
    gpu.trace_explain = std::make_unique<Pipeline>(ctx, "portal_trace.comp", gpu.set->layout(),
                                                   uint32_t(sizeof(PortalTracePush)), SpecConstants().add(shared::kPortalSpecExplain, true));
  const Pipeline& pipe = explain ? *gpu.trace_explain : *gpu.trace;
  const PassTimes t = submit_ray_chunks<PortalTracePush>(ctx, pipe, gpu.set->set(), uint32_t(rays.size()),
                                                        explain_index, kExplainCapacity,
                                                        explain ? &gpu.explain : nullptr, kExplainHeader,
                                                        gpu.timestamps.get());
  timings_.trace_host_ms = t.host_ms;
  timings_.trace_ms = t.device_ms;
  ctx.download(gpu.hits, hits.data(), hits.size_bytes());
}

void PortalVulkanTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) { run_trace(rays, hits, kPortalNoExplain); }

AccelDump PortalVulkanTracer::dump() const {
  if (!gpu_) return {};
  Context& ctx = *ctx_;
  const Image3D& atlas = gpu_->atlas;
  const size_t n = size_t(atlas.extent.x) * atlas.extent.y;
  Buffer b = ctx.create_buffer(std::max<size_t>(n * 2, 16), VK_BUFFER_USAGE_TRANSFER_DST_BIT, Memory::Host);
  ctx.submit([&](VkCommandBuffer cb) {
    image_barrier(cb, atlas.image, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                  VK_ACCESS_SHADER_READ_BIT, VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {atlas.extent.x, atlas.extent.y, 1};
    vkCmdCopyImageToBuffer(cb, atlas.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, b.buffer, 1, &region);
    image_barrier(cb, atlas.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, VK_IMAGE_LAYOUT_SHADER_READ_ONLY_OPTIMAL,
                  VK_ACCESS_TRANSFER_READ_BIT, VK_ACCESS_SHADER_READ_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT,
                  VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
  });
  std::vector<uint16_t> texels(n);
  ctx.download(b, texels.data(), n * 2);
  AccelDump d;
  d.kind = "portal";
  d.extent = glm::uvec3(atlas.extent.x, atlas.extent.y, 1);
  d.texels.assign(texels.begin(), texels.end());
  return d;
}

// ---- Rendering (reference/portal/render.cpp) ----

std::vector<glm::vec3> PortalVulkanTracer::render(const Camera& camera, const portal::RenderOptions& opt,
                                                  portal::RenderStats* stats) {
  if (opt.width == 0 || opt.height == 0) throw Error("portal render: image size must be at least 1 x 1");
  if (!gpu_) throw Error("portal-vulkan: not built");
  Context& ctx = *ctx_;
  Gpu& gpu = *gpu_;
  const portal::World& w = portal().world;
  const uint32_t* max_groups = ctx.info().limits.maxComputeWorkGroupCount;
  if (groups(opt.width, 8) > max_groups[0] || groups(opt.height, 8) > max_groups[1])
    throw Error("portal-vulkan: " + std::to_string(opt.width) + " x " + std::to_string(opt.height) +
                " needs more workgroups than maxComputeWorkGroupCount on " + ctx.info().name);
  const CameraFrame f = camera_frame(camera);  // throws for a degenerate camera
  sh::PortalRenderParams rp{};
  rp.eye = camera.eye;
  rp.tan_half_fov = f.tan_half_fov;
  rp.right = f.right;
  rp.up = f.up;
  rp.forward = f.forward;
  rp.width = opt.width;
  rp.height = opt.height;
  rp.ambient = opt.ambient;
  rp.light0 = w.to_voxel(w.lights.size() > 0 ? w.lights[0] : camera.eye);
  rp.light1 = w.to_voxel(w.lights.size() > 1 ? w.lights[1] : camera.eye);
  if (portal().packed.scale_log2) {  // instanced: fine voxel space (render_instanced)
    const portal::PackedPortal& p = portal().packed;
    rp.light0 = ((w.lights.size() > 0 ? w.lights[0] : camera.eye) - p.origin) * (1.0f / p.voxel_size);
    rp.light1 = ((w.lights.size() > 1 ? w.lights[1] : camera.eye) - p.origin) * (1.0f / p.voxel_size);
  }
  rp.max_interfaces = opt.max_interfaces;
  rp.refraction = opt.refraction ? 1u : 0u;
  rp.background = portal::background_of(opt, w);
  rp.open_outside = w.open_outside && !portal().packed.scale_log2 ? 1u : 0u;
  ctx.upload(gpu.render_params, &rp, sizeof rp);
  const size_t n = size_t(opt.width) * opt.height;
  if (n > gpu.pixel_capacity) {
    gpu.pixels = ctx.create_buffer(n * sizeof(sh::PortalPixel), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
    gpu.pixel_capacity = n;
    gpu.set->bind(shared::kPortalBindPixels, gpu.pixels);
  }
  const auto t0 = std::chrono::steady_clock::now();
  ctx.submit([&](VkCommandBuffer cb) {
    if (gpu.timestamps) gpu.timestamps->reset(cb), gpu.timestamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
    gpu.render->bind(cb, gpu.set->set());
    if (opt.state_machine) {
      // One loop: the same step for every kind of ray, transitions at the end of each iteration.
      gpu.render->push(cb, shared::PortalRenderPush{0u});
      vkCmdDispatch(cb, groups(opt.width, 8), groups(opt.height, 8), 1);
    } else {
      // Three loops: every pixel's primary ray, then every first shadow ray, then every second.
      for (uint32_t pass = 1; pass <= 3; ++pass) {
        if (pass > 1) barrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT);
        gpu.render->push(cb, shared::PortalRenderPush{pass});
        vkCmdDispatch(cb, groups(opt.width, 8), groups(opt.height, 8), 1);
      }
    }
    if (gpu.timestamps) gpu.timestamps->write(cb, 1, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT);
  });
  timings_.render_host_ms = ms_since(t0);
  timings_.render_ms = gpu.timestamps ? gpu.timestamps->elapsed_ms(0, 1) : 0.0;
  pixels_ = ctx.download<sh::PortalPixel>(gpu.pixels, n);
  std::vector<glm::vec3> image(n);
  portal::RenderStats s;
  for (size_t i = 0; i < n; ++i) {
    const sh::PortalPixel& p = pixels_[i];
    image[i] = p.color;
    s.primary_rays += 1;
    s.shadow_rays += p.shadow_rays;
    s.primary_steps += p.steps_primary;
    s.shadow_steps += p.steps_shadow;
    s.loop_iterations += p.iterations;
    s.refractions += p.refractions;
    s.cut_pixels += p.cut;
    s.reflections += p.reflections;
  }
  s.seconds = timings_.render_host_ms / 1000.0;
  if (stats) *stats = s;
  return image;
}

// ---- Explain ----

PortalExplainRecord PortalVulkanTracer::explain_ray(const Ray& ray) {
  Hit hit{};
  run_trace(std::span<const Ray>(&ray, 1), std::span<Hit>(&hit, 1), 0);
  uint32_t count = 0;
  ctx_->download(gpu_->explain, &count, sizeof count);
  if (count > kExplainCapacity)
    throw Error("portal-vulkan: the explained ray left " + std::to_string(count) + " events, over the buffer's " +
                std::to_string(kExplainCapacity));
  PortalExplainRecord rec;
  rec.ray = ray;
  rec.events = ctx_->download<sh::PortalExplainEvent>(gpu_->explain, count, kExplainHeader);
  rec.hit = hit;
  return rec;
}

// The shader's record in the words of the reference's log (reference/portal/trace.cpp,
// trace_portal), so that the two compare line by line.
std::string to_text_instanced(const PortalExplainRecord& rec, const portal::PortalBuild& build) {
  const portal::PackedPortal& p = build.packed;
  const int S = 1 << p.scale_log2;
  std::string s;
  glm::ivec3 tile(0);
  for (const sh::PortalExplainEvent& e : rec.events) {
    if (e.kind == 0) {
      tile = glm::ivec3(glm::uvec3(e.voxel) >> p.scale_log2);
      if (e.step == 2) s += "start: the ray never enters the world box: miss\n";
      else if (e.step == 1)
        s += fmt("start: fine voxel (%d, %d, %d) of tile (%d, %d, %d): inside a wall of material %u\n", e.voxel.x,
                 e.voxel.y, e.voxel.z, tile.x, tile.y, tile.z, e.div);
      else if (e.div == sh::kPortalExteriorDiv) s += "start: outside the world box: exterior div 0\n";
      else
        s += fmt("start: fine voxel (%d, %d, %d) of tile (%d, %d, %d): div %u%s\n", e.voxel.x, e.voxel.y, e.voxel.z,
                 tile.x, tile.y, tile.z, e.div, e.div >= p.top_divs ? " (in the instance)" : "");
      continue;
    }
    if (e.kind == 4) {
      tile = glm::ivec3(int(e.face & 255u), int((e.face >> 8) & 255u), int(e.face >> 16));
      s += fmt("enter instance: block %u at tile (%d, %d, %d), fine voxel (%d, %d, %d), block start texel %s\n", e.div,
               tile.x, tile.y, tile.z, e.voxel.x, e.voxel.y, e.voxel.z, texel_text(e.texel).c_str());
      continue;
    }
    if (e.kind == 5) {
      if (e.step == 1) s += "leave instance: beyond the world: miss\n";
      else
        s += fmt("leave instance: tile (%d, %d, %d) beyond, top-level start texel %s\n", e.voxel.x, e.voxel.y, e.voxel.z,
                 texel_text(e.texel).c_str());
      continue;
    }
    const auto kind = portal::StepKind(e.step);
    if (kind == portal::StepKind::kNoDirection) {
      s += fmt("div %u: no face ahead (zero direction or missed box): miss\n", e.div);
      continue;
    }
    const bool in_block = e.div >= p.top_divs;
    portal::DivInfo d = portal::read_div_info(p, e.div);
    if (in_block) d.lo += tile * S;
    s += fmt("div %u [%d,%d,%d .. %d,%d,%d) %s%s: %s face %s at t = %.7g, %s (%d, %d, %d)", e.div, d.lo.x, d.lo.y, d.lo.z,
             d.lo.x + d.size.x, d.lo.y + d.size.y, d.lo.z + d.size.z, in_block ? "fine voxels" : "tiles",
             e.div == sh::kPortalExteriorDiv ? " (exterior)" : in_block ? " (block div)" : "",
             e.div == sh::kPortalExteriorDiv ? "enters by" : "exits by", face_name(e.face), double(e.num / e.ad),
             in_block ? "fine voxel" : "tile", e.voxel.x, e.voxel.y, e.voxel.z);
    if (kind == portal::StepKind::kTmax) {
      s += ": beyond tmax, miss\n";
      continue;
    }
    s += fmt(", atlas texel (%u, %u) = %s\n", e.texel_uv.x, e.texel_uv.y, texel_text(e.texel).c_str());
  }
  const Hit& h = rec.hit;
  if (!is_miss(h) && (h.triangle & 7u) != sh::kPortalFaceInside) {
    const glm::uvec3 f = p.fine_dims();
    const uint32_t i = h.triangle >> 3;
    s += fmt("hit: fine voxel (%u, %u, %u) face %s, material %u, t = %.9g, uv = (%.6g, %.6g)\n", i % f.x, (i / f.x) % f.y,
             i / (f.x * f.y), face_name(h.triangle & 7u), h.instance, double(h.t), double(h.u), double(h.v));
  }
  return s;
}

std::string to_text(const PortalExplainRecord& rec, const portal::PortalBuild& build) {
  const portal::PackedPortal& p = build.packed;
  if (p.scale_log2) return to_text_instanced(rec, build);
  std::string s;
  for (const sh::PortalExplainEvent& e : rec.events) {
    if (e.kind == 0) {
      if (e.step == 2) s += "start: the ray never enters the world box: miss\n";
      else if (e.step == 1)
        s += fmt("start: voxel (%d, %d, %d), start texel %s: the ray starts inside a wall\n", e.voxel.x, e.voxel.y,
                 e.voxel.z, texel_text(e.texel).c_str());
      else if (e.div == sh::kPortalExteriorDiv) s += "start: outside the world box: exterior div 0\n";
      else s += fmt("start: voxel (%d, %d, %d), start texel %s\n", e.voxel.x, e.voxel.y, e.voxel.z, texel_text(e.texel).c_str());
      continue;
    }
    if (e.kind == 2) {
      s += fmt("mip: level %u from here, coarse voxel (%d, %d, %d), start texel %s\n", e.div, e.voxel.x, e.voxel.y,
               e.voxel.z, texel_text(e.texel).c_str());
      continue;
    }
    if (e.kind == 3) {
      const Hit& h = rec.hit;
      const glm::ivec3 v = portal::hit_voxel(build.world, h);
      const uint32_t m = e.texel;
      s += fmt("hit: coarse voxel (%d, %d, %d) of level %u, material %u (coverage %g)%s: voxel (%d, %d, %d) face %s, "
               "material %u, t = %.9g\n", e.voxel.x, e.voxel.y, e.voxel.z, e.div, m, double(p.coverage[m]),
               p.resolve[m] ? ", opaque: back to full resolution" : ", translucent", v.x, v.y, v.z,
               face_name(h.triangle & 7u), h.instance, double(h.t));
      continue;
    }
    const auto kind = portal::StepKind(e.step);
    if (kind == portal::StepKind::kNoDirection) {
      s += fmt("div %u: no face ahead (zero direction or missed box): miss\n", e.div);
      continue;
    }
    const portal::DivInfo d = portal::read_div_info(p, e.div);
    s += fmt("div %u [%d,%d,%d .. %d,%d,%d)%s%s: %s face %s at t = %.7g, voxel (%d, %d, %d)", e.div, d.lo.x, d.lo.y,
             d.lo.z, d.lo.x + d.size.x, d.lo.y + d.size.y, d.lo.z + d.size.z,
             d.type == sh::kPortalDivExterior ? " (exterior)" : d.type == sh::kPortalDivGlass ? " (glass)" : "",
             d.level ? fmt(" level %u", d.level).c_str() : "",
             d.type == sh::kPortalDivExterior ? "enters by" : "exits by", face_name(e.face), double(e.num / e.ad),
             e.voxel.x, e.voxel.y, e.voxel.z);
    if (kind == portal::StepKind::kTmax) {
      s += ": beyond tmax, miss\n";
      continue;
    }
    s += fmt(", atlas texel (%u, %u) = %s\n", e.texel_uv.x, e.texel_uv.y, texel_text(e.texel).c_str());
  }
  const Hit& h = rec.hit;
  if (!is_miss(h) && (h.triangle & 7u) != sh::kPortalFaceInside && !rec.events.empty() && rec.events.back().kind != 3) {
    const glm::ivec3 v = portal::hit_voxel(build.world, h);
    if (portal::StepKind(rec.events.back().step) == portal::StepKind::kWall)
      s += fmt("hit: voxel (%d, %d, %d) face %s, material %u, t = %.9g, uv = (%.6g, %.6g)\n", v.x, v.y, v.z,
               face_name(h.triangle & 7u), h.instance, double(h.t), double(h.u), double(h.v));
    else
      s += fmt("hit: glass surface, voxel (%d, %d, %d) face %s, material %u, t = %.9g\n", v.x, v.y, v.z,
               face_name(h.triangle & 7u), h.instance, double(h.t));
  }
  return s;
}

std::string PortalVulkanTracer::explain(const Ray& ray) {
  const portal::PortalBuild& b = portal();
  const PortalExplainRecord rec = explain_ray(ray);
  std::string cpu_log;
  const Hit cpu = portal::trace_portal(b.packed, ray, &cpu_log);
  std::vector<std::string> cpu_lines = lines_of(cpu_log);
  if (!cpu_lines.empty()) cpu_lines.erase(cpu_lines.begin());  // the voxel-space ray: the host's, not the shader's
  const std::vector<std::string> gpu_lines = lines_of(to_text(rec, b));
  std::string s = fmt("portal-vulkan: world '%s' %u x %u x %u voxels, %u divs, atlas %u x %u, on %s\n",
                      b.world.name.c_str(), b.packed.dims.x, b.packed.dims.y, b.packed.dims.z, b.packed.div_count,
                      b.packed.atlas_width, b.packed.atlas_height, ctx_->info().name.c_str());
  s += fmt("ray: org (%.6g, %.6g, %.6g) dir (%.6g, %.6g, %.6g)\n", ray.org.x, ray.org.y, ray.org.z, ray.dir.x, ray.dir.y,
           ray.dir.z);
  s += "the shader's own record (gpu) beside the reference's (cpu); '=' where they agree:\n";
  bool parted = false;
  for (size_t i = 0; i < std::max(cpu_lines.size(), gpu_lines.size()); ++i) {
    const std::string c = i < cpu_lines.size() ? cpu_lines[i] : "(nothing)";
    const std::string g = i < gpu_lines.size() ? gpu_lines[i] : "(nothing)";
    if (c == g) {
      s += "  =   " + c + "\n";
      continue;
    }
    s += "  cpu " + c + "\n  gpu " + g + (parted ? "\n" : "   <-- they part here\n");
    parted = true;
  }
  const bool same = std::memcmp(&cpu, &rec.hit, sizeof(Hit)) == 0;
  s += fmt("hit record (t, instance, triangle, u, v, flags, cells, tests): %s\n",
           same ? "identical in bits" : "DIFFERS");
  if (!same) {
    auto rec_text = [](const Hit& h) {
      uint32_t t, u, v;
      std::memcpy(&t, &h.t, 4), std::memcpy(&u, &h.u, 4), std::memcpy(&v, &h.v, 4);
      return fmt("t 0x%08x instance %u triangle 0x%08x u 0x%08x v 0x%08x flags %u cells %u tests %u", t, h.instance,
                 h.triangle, u, v, h.flags, h.cells, h.tests);
    };
    s += "  cpu " + rec_text(cpu) + "\n  gpu " + rec_text(rec.hit) + "\n";
  }
  return s;
}

}  // namespace gridrt::vulkan
