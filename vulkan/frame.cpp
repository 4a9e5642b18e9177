// frame.cpp: VulkanFrame, the paper's frame on the GPU (see frame.h): the tables shading reads,
// the raster gather's render pass and pipeline, the compute passes, one submission per frame.
#include "gridrt/vulkan/frame.h"
#include "gridrt/common/util.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <map>
#include <set>

#include "gridrt/common/camera.h"
#include "gridrt/vulkan/pipeline.h"

namespace gridrt::vulkan {

namespace {

// The descriptor set's bindings: frame_input.h.

// A 2D image with its memory and view: the gather's attachments.
struct Image2D {
  VkDevice device = VK_NULL_HANDLE;
  VkImage image = VK_NULL_HANDLE;
  VkDeviceMemory memory = VK_NULL_HANDLE;
  VkImageView view = VK_NULL_HANDLE;
  Image2D() = default;
  Image2D(const Image2D&) = delete;
  Image2D& operator=(const Image2D&) = delete;
  ~Image2D() {
    if (view) vkDestroyImageView(device, view, nullptr);
    if (image) vkDestroyImage(device, image, nullptr);
    if (memory) vkFreeMemory(device, memory, nullptr);
  }
};

void create_image2d(Context& ctx, Image2D& img, VkFormat format, uint32_t width, uint32_t height,
                    VkImageUsageFlags usage, VkImageAspectFlags aspect) {
  img.device = ctx.device();
  VkImageCreateInfo ci{VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO};
  ci.imageType = VK_IMAGE_TYPE_2D;
  ci.format = format;
  ci.extent = {width, height, 1};
  ci.mipLevels = 1;
  ci.arrayLayers = 1;
  ci.samples = VK_SAMPLE_COUNT_1_BIT;
  ci.tiling = VK_IMAGE_TILING_OPTIMAL;
  ci.usage = usage;
  ci.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  ci.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  GRIDRT_VK_CHECK(vkCreateImage(ctx.device(), &ci, nullptr, &img.image));
  VkMemoryRequirements req;
  vkGetImageMemoryRequirements(ctx.device(), img.image, &req);
  ctx.require_allocation(req.size, "a gather attachment");
  VkMemoryAllocateInfo ai{VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO};
  ai.allocationSize = req.size;
  ai.memoryTypeIndex = ctx.memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
  if (ai.memoryTypeIndex == ~0u) ai.memoryTypeIndex = ctx.memory_type(req.memoryTypeBits, 0);
  GRIDRT_VK_CHECK(vkAllocateMemory(ctx.device(), &ai, nullptr, &img.memory));
  GRIDRT_VK_CHECK(vkBindImageMemory(ctx.device(), img.image, img.memory, 0));
  VkImageViewCreateInfo vi{VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO};
  vi.image = img.image;
  vi.viewType = VK_IMAGE_VIEW_TYPE_2D;
  vi.format = format;
  vi.subresourceRange = {aspect, 0, 1, 0, 1};
  GRIDRT_VK_CHECK(vkCreateImageView(ctx.device(), &vi, nullptr, &img.view));
}

// Between the compute gather's passes: shader (and the fills' transfer) writes made visible to
// the next compute pass's reads and writes and to its indirect dispatch's arguments; narrower
// than barrier()'s every stage to every stage.
void gather_barrier(VkCommandBuffer cb) {
  VkMemoryBarrier mb{VK_STRUCTURE_TYPE_MEMORY_BARRIER};
  mb.srcAccessMask = VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT;
  mb.dstAccessMask = VK_ACCESS_SHADER_READ_BIT | VK_ACCESS_SHADER_WRITE_BIT | VK_ACCESS_INDIRECT_COMMAND_READ_BIT;
  vkCmdPipelineBarrier(cb, VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_TRANSFER_BIT,
                       VK_PIPELINE_STAGE_COMPUTE_SHADER_BIT | VK_PIPELINE_STAGE_DRAW_INDIRECT_BIT, 0, 1, &mb, 0, nullptr,
                       0, nullptr);
}

template <class T>
Buffer make_buffer(Context& ctx, const std::vector<T>& data) {
  Buffer b = ctx.create_buffer(std::max<size_t>(data.size() * sizeof(T), 16), VK_BUFFER_USAGE_STORAGE_BUFFER_BIT);
  if (!data.empty()) ctx.upload(b, data.data(), data.size() * sizeof(T));
  return b;
}

}  // namespace

struct VulkanFrame::Gpu {
  Context* ctx = nullptr;
  Buffer params, visibility, gather, materials, texels, lights, rays, hits, image, ray_list, keys, tiles, tile_depth, pixel_dirs;
  Buffer tile_bins;  // the rasterizer's tile lists (GatherFineHeader, counts, starts, pairs)
  uint32_t screen_tiles = 0, pair_capacity = 0, past_capacity = 0;
  Image2D color, depth;
  std::unique_ptr<Descriptors> set, ray_list_set;
  // The sorted rays (ray_sort.comp): keys A and B, B's values (A's are the ray list's), the counts
  Buffer sort_keys_a, sort_keys_b, sort_values_b, sort_counts;
  std::unique_ptr<Descriptors> sort_set;
  std::unique_ptr<Pipeline> sort_count, sort_scan, sort_scatter;
  shared::RaySortPush sort_push{};
  std::unique_ptr<Pipeline> resolve, bounce, shade, bin, tile_pass, ray_list_dispatch, dirs;
  std::unique_ptr<Pipeline> pairs, scan, past, fine;  // the rasterizer's tile lists and fine pass
  std::unique_ptr<Timestamps> timestamps;
  // The raster gather
  VkPipelineLayout layout = VK_NULL_HANDLE;
  VkPipeline raster = VK_NULL_HANDLE;
  VkRenderPass pass = VK_NULL_HANDLE;
  VkFramebuffer framebuffer = VK_NULL_HANDLE;
  std::vector<VkShaderModule> modules;
  shared::CameraParams camera{};

  ~Gpu() {
    VkDevice d = ctx->device();
    if (raster) vkDestroyPipeline(d, raster, nullptr);
    if (layout) vkDestroyPipelineLayout(d, layout, nullptr);
    if (framebuffer) vkDestroyFramebuffer(d, framebuffer, nullptr);
    if (pass) vkDestroyRenderPass(d, pass, nullptr);
    for (VkShaderModule m : modules) vkDestroyShaderModule(d, m, nullptr);
  }

  VkShaderModule module(std::string_view name) {
    const std::vector<uint32_t> words =
        patch_float_controls(shader_spirv(name), FloatControls::for_device(ctx->info()));
    VkShaderModuleCreateInfo ci{VK_STRUCTURE_TYPE_SHADER_MODULE_CREATE_INFO};
    ci.codeSize = words.size() * 4;
    ci.pCode = words.data();
    VkShaderModule m;
    GRIDRT_VK_CHECK(vkCreateShaderModule(ctx->device(), &ci, nullptr, &m));
    modules.push_back(m);
    return m;
  }

  void create_raster(uint32_t width, uint32_t height, const VkSpecializationInfo* spec);
};

// The gather's render pass (an R32_UINT colour attachment cleared to kNoRef, a D32 depth
// attachment cleared to 0: reversed depth) and its pipeline.
void VulkanFrame::Gpu::create_raster(uint32_t width, uint32_t height, const VkSpecializationInfo* spec) {
  VkDevice d = ctx->device();
  VkAttachmentDescription att[2]{};
  att[0].format = VK_FORMAT_R32_UINT;
  att[0].samples = VK_SAMPLE_COUNT_1_BIT;
  att[0].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
  att[0].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
  att[0].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
  att[0].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[0].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  att[0].finalLayout = VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL;
  att[1] = att[0];
  att[1].format = VK_FORMAT_D32_SFLOAT;
  att[1].storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
  att[1].finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;
  VkAttachmentReference color_ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
  VkAttachmentReference depth_ref{1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
  VkSubpassDescription sub{};
  sub.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
  sub.colorAttachmentCount = 1;
  sub.pColorAttachments = &color_ref;
  sub.pDepthStencilAttachment = &depth_ref;
  const VkPipelineStageFlags attach_stages = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT |
                                             VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                                             VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT;
  const VkAccessFlags attach_access = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_COLOR_ATTACHMENT_READ_BIT |
                                      VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                                      VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT;
  VkSubpassDependency deps[2]{};
  deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
  deps[0].dstSubpass = 0;
  deps[0].srcStageMask = VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  deps[0].dstStageMask = attach_stages | VK_PIPELINE_STAGE_VERTEX_SHADER_BIT;
  deps[0].srcAccessMask = VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  deps[0].dstAccessMask = attach_access | VK_ACCESS_SHADER_READ_BIT;
  deps[1].srcSubpass = 0;
  deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
  deps[1].srcStageMask = attach_stages;
  deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT | VK_PIPELINE_STAGE_ALL_COMMANDS_BIT;
  deps[1].srcAccessMask = attach_access;
  deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT | VK_ACCESS_MEMORY_READ_BIT | VK_ACCESS_MEMORY_WRITE_BIT;
  VkRenderPassCreateInfo rp{VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO};
  rp.attachmentCount = 2;
  rp.pAttachments = att;
  rp.subpassCount = 1;
  rp.pSubpasses = &sub;
  rp.dependencyCount = 2;
  rp.pDependencies = deps;
  GRIDRT_VK_CHECK(vkCreateRenderPass(d, &rp, nullptr, &pass));

  const VkImageView views[2] = {color.view, depth.view};
  VkFramebufferCreateInfo fb{VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO};
  fb.renderPass = pass;
  fb.attachmentCount = 2;
  fb.pAttachments = views;
  fb.width = width;
  fb.height = height;
  fb.layers = 1;
  GRIDRT_VK_CHECK(vkCreateFramebuffer(d, &fb, nullptr, &framebuffer));

  const VkDescriptorSetLayout set_layout = set->layout();
  VkPipelineLayoutCreateInfo li{VK_STRUCTURE_TYPE_PIPELINE_LAYOUT_CREATE_INFO};
  li.setLayoutCount = 1;
  li.pSetLayouts = &set_layout;
  GRIDRT_VK_CHECK(vkCreatePipelineLayout(d, &li, nullptr, &layout));

  VkPipelineShaderStageCreateInfo stages[2]{};
  stages[0] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[0].stage = VK_SHADER_STAGE_VERTEX_BIT;
  stages[0].module = module("gather.vert");
  stages[0].pName = "main";
  stages[0].pSpecializationInfo = spec;
  stages[1] = {VK_STRUCTURE_TYPE_PIPELINE_SHADER_STAGE_CREATE_INFO};
  stages[1].stage = VK_SHADER_STAGE_FRAGMENT_BIT;
  stages[1].module = module("gather.frag");
  stages[1].pName = "main";
  stages[1].pSpecializationInfo = spec;
  VkPipelineVertexInputStateCreateInfo vin{VK_STRUCTURE_TYPE_PIPELINE_VERTEX_INPUT_STATE_CREATE_INFO};
  VkPipelineInputAssemblyStateCreateInfo ia{VK_STRUCTURE_TYPE_PIPELINE_INPUT_ASSEMBLY_STATE_CREATE_INFO};
  ia.topology = VK_PRIMITIVE_TOPOLOGY_TRIANGLE_LIST;
  VkViewport viewport{0.0f, 0.0f, float(width), float(height), 0.0f, 1.0f};
  VkRect2D scissor{{0, 0}, {width, height}};
  VkPipelineViewportStateCreateInfo vp{VK_STRUCTURE_TYPE_PIPELINE_VIEWPORT_STATE_CREATE_INFO};
  vp.viewportCount = 1;
  vp.pViewports = &viewport;
  vp.scissorCount = 1;
  vp.pScissors = &scissor;
  VkPipelineRasterizationStateCreateInfo rs{VK_STRUCTURE_TYPE_PIPELINE_RASTERIZATION_STATE_CREATE_INFO};
  rs.polygonMode = VK_POLYGON_MODE_FILL;
  rs.cullMode = VK_CULL_MODE_NONE;  // both faces, as the rays see them
  rs.frontFace = VK_FRONT_FACE_COUNTER_CLOCKWISE;
  rs.lineWidth = 1.0f;
  VkPipelineMultisampleStateCreateInfo ms{VK_STRUCTURE_TYPE_PIPELINE_MULTISAMPLE_STATE_CREATE_INFO};
  ms.rasterizationSamples = VK_SAMPLE_COUNT_1_BIT;
  VkPipelineDepthStencilStateCreateInfo ds{VK_STRUCTURE_TYPE_PIPELINE_DEPTH_STENCIL_STATE_CREATE_INFO};
  ds.depthTestEnable = VK_TRUE;
  ds.depthWriteEnable = VK_TRUE;
  ds.depthCompareOp = VK_COMPARE_OP_GREATER;  // reversed depth: nearer is larger
  VkPipelineColorBlendAttachmentState blend{};
  blend.colorWriteMask = VK_COLOR_COMPONENT_R_BIT;
  VkPipelineColorBlendStateCreateInfo cb{VK_STRUCTURE_TYPE_PIPELINE_COLOR_BLEND_STATE_CREATE_INFO};
  cb.attachmentCount = 1;
  cb.pAttachments = &blend;
  VkGraphicsPipelineCreateInfo gi{VK_STRUCTURE_TYPE_GRAPHICS_PIPELINE_CREATE_INFO};
  gi.stageCount = 2;
  gi.pStages = stages;
  gi.pVertexInputState = &vin;
  gi.pInputAssemblyState = &ia;
  gi.pViewportState = &vp;
  gi.pRasterizationState = &rs;
  gi.pMultisampleState = &ms;
  gi.pDepthStencilState = &ds;
  gi.pColorBlendState = &cb;
  gi.layout = layout;
  gi.renderPass = pass;
  GRIDRT_VK_CHECK(vkCreateGraphicsPipelines(d, VK_NULL_HANDLE, 1, &gi, nullptr, &raster));
}

float frame_near_plane(const Scene& scene) {
  const Bounds b = scene.bounds(0.0f);
  const float extent = b.empty() ? 1.0f : glm::length(b.extent());
  return std::max(extent, 1e-6f) * 1e-6f;
}

namespace {

// The frame's parameters: the camera of the CPU's primary rays; a near plane far inside the
// scene's scale (frame_near_plane).
shared::FrameParams frame_params(const Scene& scene, const shared::CameraParams& camera, const FrameOptions& options) {
  shared::FrameParams fp{};
  fp.camera = camera;
  fp.background = scene.background;
  fp.light_count = uint32_t(scene.lights.size());
  fp.ambient = options.ambient;
  fp.exposure = options.exposure;
  fp.near_plane = frame_near_plane(scene);
  fp.frame = 0;
  fp.material_count = uint32_t(scene.materials.size());
  fp.raster = shared::raster_camera(camera);
  return fp;
}

// The materials as shading reads them, and their textures' texels.
struct FrameMaterials {
  std::vector<shared::FrameMaterial> materials;
  std::vector<uint32_t> texels;
  bool textured = false;  // some material has a diffuse texture
  bool alpha = false;     // some material has an alpha mask (with alpha_keying)
};

// Materials and their diffuse textures (halved until the texel buffer fits the device's
// maxStorageBufferRange; then shading reads coarser textures than the CPU's); with
// `alpha_keying` (the grid keys them) the alpha masks at full resolution, as the grid's trace
// reads them.
FrameMaterials pack_materials(const Scene& scene, bool alpha_keying, uint64_t max_storage_buffer_range) {
  FrameMaterials out;
  std::vector<shared::FrameMaterial>& materials = out.materials;
  std::vector<uint32_t>& texels = out.texels;
  bool& textured = out.textured;
  bool& alpha = out.alpha;
  // Each texture once, however many materials use it: the distinct masks and diffuse textures
  std::map<int32_t, uint32_t> mask_offsets, diffuse_offsets;
  std::set<int32_t> masks, diffuse;
  for (const Material& m : scene.materials) {
    if (m.alpha_keyed() && alpha_keying) masks.insert(m.alpha_texture);
    if (m.diffuse_texture >= 0) diffuse.insert(m.diffuse_texture);
  }
  uint64_t texel_budget = max_storage_buffer_range / 4;
  for (int32_t k : masks) {
    const Texture& t = scene.textures[size_t(k)];
    texel_budget -= std::min<uint64_t>(texel_budget, uint64_t(t.width) * t.height);
  }
  uint32_t shrink = 0;
  uint64_t whole = 0;
  for (;; ++shrink) {
    uint64_t total = 0;
    for (int32_t k : diffuse) {
      const Texture& t = scene.textures[size_t(k)];
      total += uint64_t(std::max(1u, t.width >> shrink)) * std::max(1u, t.height >> shrink);
    }
    if (shrink == 0) whole = total;
    if (total <= texel_budget || shrink > 12) break;
  }
  if (shrink > 0)
    std::fprintf(stderr,
                 "warning: vulkan frame: the diffuse textures' %llu texels are more than the texel buffer holds beside "
                 "the alpha masks (maxStorageBufferRange %llu bytes): shading reads them at 1/%u of their width and height, the "
                 "CPU's whole, so the shaded pictures differ (the hits do not)\n",
                 static_cast<unsigned long long>(whole), static_cast<unsigned long long>(max_storage_buffer_range),
                 1u << shrink);
  for (const Material& m : scene.materials) {
    shared::FrameMaterial fm{};
    fm.diffuse = m.diffuse;
    fm.glossiness = m.glossiness;
    fm.cos_max = cone_cos_max(m.glossiness);
    if (m.diffuse_texture >= 0) {
      const Texture& t = scene.textures[size_t(m.diffuse_texture)];
      if (t.width > 0 && t.height > 0) {
        const uint32_t tw = std::max(1u, t.width >> shrink), th = std::max(1u, t.height >> shrink);
        auto [it, added] = diffuse_offsets.emplace(m.diffuse_texture, uint32_t(texels.size()));
        if (added)
          for (uint32_t y = 0; y < th; ++y)
            for (uint32_t x = 0; x < tw; ++x) {
              const glm::u8vec4 c = t.texel(std::min(x << shrink, t.width - 1), std::min(y << shrink, t.height - 1));
              texels.push_back(uint32_t(c.r) | uint32_t(c.g) << 8 | uint32_t(c.b) << 16 | uint32_t(c.a) << 24);
            }
        fm.texture_offset = it->second;
        fm.texture_width = tw;
        fm.texture_height = th;
        textured = true;
      }
    }
    if (m.alpha_keyed() && alpha_keying) {
      // The mask at full resolution, as the grid's trace reads it
      const Texture& t = scene.textures[size_t(m.alpha_texture)];
      auto [it, added] = mask_offsets.emplace(m.alpha_texture, uint32_t(texels.size()));
      if (added) plan::append_rgba8(t, texels);
      fm.alpha_offset = it->second;
      fm.alpha_width = t.width;
      fm.alpha_height = t.height;
      alpha = true;
    }
    if (texels.size() > UINT32_MAX)
      throw Error("vulkan frame: the scene's textures hold more than 2^32 texels (32-bit offsets): use smaller textures");
    materials.push_back(fm);
  }
  return out;
}

}  // namespace

// The GPU's gathers test each pixel's primary ray from the eye (gather_visibility.glsl,
// gather.frag); the CPU's gather, the exact traversal, moves a far origin to just before the grid
// box first (docs/SPEC.md "Far origins"), where 64 ulps of the eye's largest coordinate exceed a
// cell. There the two would not agree (from the eye, Moller-Trumbore's `v - eye` rounds by more than
// a cell: phantom hits on small triangles), so such an eye is refused, not rendered wrong.
static void check_gather_eye(const glm::vec3& eye, const shared::GridParams& g) {
  const float reach = std::max(std::max(std::abs(eye.x), std::abs(eye.y)), std::abs(eye.z)) * shared::kFarOriginRatio;
  if (!(reach > g.cell_size)) return;
  char msg[640];
  std::snprintf(msg, sizeof msg,
                "vulkan frame: the eye (%.9g, %.9g, %.9g) is far for this grid: 64 ulps of its coordinates (%.9g) exceed "
                "a cell (%.9g). The CPU's gather moves such a primary ray's origin to the grid before testing "
                "(docs/SPEC.md \"Far origins\"); the GPU's gather tests from the eye and would differ from it. "
                "Move the camera closer, take cells of at least %g (--cell-size), or use --backend cpu",
                double(eye.x), double(eye.y), double(eye.z), double(reach), double(g.cell_size), double(reach));
  throw Error(msg);
}

VulkanFrame::VulkanFrame(VulkanGridTracer& grid, const Scene& scene, FrameOptions options)
    : grid_(grid), grid_generation_(grid.build_generation()), scene_(scene), options_(options) {
  Context& ctx = grid.context();
  const uint32_t w = options_.width, h = options_.height;
  if (!grid.built()) throw Error("vulkan frame: its grid is not built (build it from the scene first)");
  if (w == 0 || h == 0) throw Error("vulkan frame: image size must be at least 1 x 1");
  // Each side within 65,536 pixels before the host makes its per-column and per-row steps (a width
  // of 2^32 - 1 died of std::bad_alloc); the device's limits then bound the rest, named
  if (w > 65536u || h > 65536u)
    throw Error("vulkan frame: " + std::to_string(w) + " x " + std::to_string(h) +
                " pixels: a side of more than 65536 pixels");
  bounce_ = options_.bounce && scene.has_glossy();
  shadows_ = options_.shadows && !scene.lights.empty();
  if (shadows_) check_shadow_lights(scene);
  gather_ = options_.gather;
  if (gather_ != GatherMode::raster &&
      !(ctx.info().buffer_int64_atomics && ctx.info().subgroup_arithmetic_ballot))
    gather_ = GatherMode::raster;
  const bool compact = bounce_ && options_.compact_rays;
  if (options_.sort_bits != 0u && (options_.compact_rays || (options_.sort_bits != 16u && options_.sort_bits != 24u &&
                                                              options_.sort_bits != 32u)))
    throw Error("vulkan frame: the bounce rays are sorted by 16, 24 or 32 bits of their keys, and not with the "
                "compacted ray list (asked: " + std::to_string(options_.sort_bits) + " bits" +
                (options_.compact_rays ? ", with compact_rays)" : ")"));
  const bool sorted = bounce_ && options_.sort_bits != 0u;
  gpu_ = std::make_unique<Gpu>();
  Gpu& gpu = *gpu_;
  gpu.ctx = &ctx;

  // Parameters: the camera of the CPU's primary rays
  gpu.camera = camera_params(scene.frame_camera(), w, h);
  check_gather_eye(gpu.camera.eye, grid.params());
  // The CPU's gather runs on a grid of its own (plan::gather_options: the exact traversal), whose
  // cells may be finer than the frame's (the paper traversal's): checked on it too where the eye
  // comes near (the paper traversal's frame rendered such an eye, and differed from the CPU's on
  // 24 pixels: an outside sweep). The eye's reach is far below a cell everywhere else.
  {
    const glm::vec3 e = gpu.camera.eye;
    const float reach = std::max(std::max(std::abs(e.x), std::abs(e.y)), std::abs(e.z)) * shared::kFarOriginRatio;
    if (reach * 16.0f > grid.params().cell_size)
      check_gather_eye(e, plan::choose_grid(scene, grid.build_time(), plan::gather_options(grid.options())));
  }
  const shared::FrameParams fp = frame_params(scene, gpu.camera, options_);
  const FrameMaterials fmat = pack_materials(scene, (grid.params().flags & shared::kGridAlphaKeying) != 0u,
                                             ctx.info().limits.maxStorageBufferRange);
  const std::vector<shared::FrameMaterial>& materials = fmat.materials;
  const std::vector<uint32_t>& texels = fmat.texels;
  const bool textured = fmat.textured, alpha = fmat.alpha;
  std::vector<shared::FrameLight> lights;
  for (const Light& l : scene.lights)
    lights.push_back({l.position, l.directional ? 1.0f : 0.0f, l.color * l.intensity, 0.0f});

  // Buffers
  const size_t pixels = size_t(w) * h;
  const VkBufferUsageFlags sb = VK_BUFFER_USAGE_STORAGE_BUFFER_BIT;
  {
    // The parameters, then the camera's steps per column and per row (frame_common.glsl)
    std::vector<float> steps(size_t(w) + h);
    for (uint32_t x = 0; x < w; ++x) steps[x] = shared::camera_step_x(fp.camera, x);
    for (uint32_t y = 0; y < h; ++y) steps[w + y] = shared::camera_step_y(fp.camera, y);
    std::vector<uint8_t> bytes(sizeof fp + steps.size() * sizeof(float));
    std::memcpy(bytes.data(), &fp, sizeof fp);
    std::memcpy(bytes.data() + sizeof fp, steps.data(), steps.size() * sizeof(float));
    gpu.params = make_buffer(ctx, bytes);
  }
  gpu.materials = make_buffer(ctx, materials);
  gpu.texels = make_buffer(ctx, texels);
  gpu.lights = make_buffer(ctx, lights);
  gpu.visibility = ctx.create_buffer(pixels * 4, sb);
  gpu.gather = ctx.create_buffer(pixels * sizeof(shared::GatherTexel), sb);
  // The bounce rays, then (with shadows) the shadow rays, light-major
  const size_t rays = pixels * (1 + (shadows_ ? scene.lights.size() : 0));
  if (rays > UINT32_MAX) throw Error("vulkan frame: too many rays for one frame (pixels times lights)");
  gpu.rays = ctx.create_buffer(rays * sizeof(Ray), sb);
  gpu.hits = ctx.create_buffer(rays * sizeof(Hit), sb);
  gpu.image = ctx.create_buffer(pixels * 4, sb);
  const VkBufferUsageFlags list_usage = sb | VK_BUFFER_USAGE_INDIRECT_BUFFER_BIT;
  const size_t header = sizeof(shared::WorkListHeader);
  gpu.ray_list = ctx.create_buffer(compact || sorted ? header + pixels * 4 : header, list_usage);
  if (sorted) {
    if (pixels > UINT32_MAX - shared::kRaySortBlock) throw Error("vulkan frame: too many pixels to sort");
    const uint32_t blocks = uint32_t((pixels + shared::kRaySortBlock - 1) / shared::kRaySortBlock);
    // llvmpipe ends a shader's loops after 65,535 iterations in all (vulkan/grid.h): the sort's
    // only loops of a length that grows with the image are the scan's two over its share of the
    // blocks, 2 * ceil(blocks / 256) <= 16,384 iterations at 2^32 pixels, so no image is refused
    gpu.sort_keys_a = ctx.create_buffer(pixels * 4, sb);
    gpu.sort_keys_b = ctx.create_buffer(pixels * 4, sb);
    gpu.sort_values_b = ctx.create_buffer(pixels * 4, sb);
    gpu.sort_counts = ctx.create_buffer((size_t(blocks) + 1) * shared::kRaySortBuckets * 4, sb);
    // The origin lattice over the grid's box
    const shared::GridParams& g = grid.params();
    const glm::vec3 extent = glm::max(glm::vec3(g.cells) * g.cell_size, glm::vec3(1e-30f));
    const glm::uvec3 sg = shared::work_list_groups(blocks, 1u, ctx.info().limits.maxComputeWorkGroupCount[0]);
    gpu.sort_push.lattice_lo = g.origin;
    gpu.sort_push.count = uint32_t(pixels);
    gpu.sort_push.lattice_scale = float(shared::kRaySortLattice) / extent;
    gpu.sort_push.blocks = blocks;
    gpu.sort_push.groups_x = sg.x;
    gpu.sort_push.max_groups_x = ctx.info().limits.maxComputeWorkGroupCount[0];
  }
  const bool compute = gather_ != GatherMode::raster;
  if (compute) {
    // The large triangles: a set-up record for every triangle of the geometry buffer at most
    const std::vector<shared::GridInstance>& gi = grid.instances();
    const uint64_t tris = gi.empty() ? 0 : gi.back().tri_offset + gi.back().tri_count;
    gpu.keys = ctx.create_buffer(pixels * 8, sb);
    gpu.tiles = ctx.create_buffer(
        sizeof(shared::GatherTileHeader) + std::max<uint64_t>(tris, 1) * sizeof(shared::GatherRasterTriangle), list_usage);
    const uint32_t ts = shared::kGatherTileSize;
    const uint64_t screen_tiles = uint64_t((w + ts - 1) / ts) * ((h + ts - 1) / ts);
    gpu.tile_depth = ctx.create_buffer(screen_tiles * 4, sb);
    gpu.pixel_dirs = ctx.create_buffer(gather_ == GatherMode::compute ? pixels * 16 : 16, sb);
    // The tile lists: room for options.gather_pair_capacity pairs (more: the frame's item pass
    // runs instead of the fine pass), within the device's buffer range
    gpu.screen_tiles = uint32_t(screen_tiles);
    uint64_t capacity = 0, words = 0;
    if (gather_ == GatherMode::compute) {
      const uint64_t range = ctx.info().limits.maxStorageBufferRange;
      if (options_.gather_lists == GatherLists::buckets) {
        // Counts, a bucket per tile, then the list of pairs past their buckets (two words each)
        const uint64_t fixed = sizeof(shared::GatherFineHeader) + screen_tiles * 4;
        capacity = options_.gather_bucket_capacity.value_or(kGatherBucketDefault);
        uint64_t past = options_.gather_past_capacity.value_or(kGatherPastPerTile * screen_tiles);
        const uint64_t room = range > fixed ? (range - fixed) / 4 : 0;
        capacity = std::min<uint64_t>(capacity, room / 2 / screen_tiles);
        past = std::min<uint64_t>({past, (room - capacity * screen_tiles) / 2, UINT32_MAX});
        gpu.past_capacity = uint32_t(past);
        words = screen_tiles + screen_tiles * capacity + 2 * past;
      } else {
        const uint64_t fixed = sizeof(shared::GatherFineHeader) + 2 * screen_tiles * 4;
        capacity = options_.gather_pair_capacity.value_or(64 * screen_tiles + 4 * tris);
        capacity = std::min<uint64_t>(capacity, range > fixed ? (range - fixed) / 4 : 0);
        capacity = std::min<uint64_t>(capacity, UINT32_MAX);
        words = 2 * screen_tiles + capacity;
      }
    }
    gpu.pair_capacity = uint32_t(capacity);
    gpu.tile_bins = ctx.create_buffer(sizeof(shared::GatherFineHeader) + words * 4, list_usage);
  } else {
    gpu.tile_bins = ctx.create_buffer(sizeof(shared::GatherFineHeader), list_usage);
    gpu.pixel_dirs = ctx.create_buffer(16, sb);
    gpu.keys = ctx.create_buffer(16, sb);
    gpu.tile_depth = ctx.create_buffer(16, sb);
    gpu.tiles = ctx.create_buffer(header, list_usage);
    create_image2d(ctx, gpu.color, VK_FORMAT_R32_UINT, w, h,
                   VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT, VK_IMAGE_ASPECT_COLOR_BIT);
    create_image2d(ctx, gpu.depth, VK_FORMAT_D32_SFLOAT, w, h, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                   VK_IMAGE_ASPECT_DEPTH_BIT);
  }
  // The work lists start empty
  ctx.submit([&](VkCommandBuffer cb) {
    vkCmdFillBuffer(cb, gpu.ray_list.buffer, 0, VK_WHOLE_SIZE, 0u);
    vkCmdFillBuffer(cb, gpu.tiles.buffer, 0, header, 0u);
  });
  // The descriptor set, the pipelines (specialized: bounce, textures)
  const VkDescriptorType t = VK_DESCRIPTOR_TYPE_STORAGE_BUFFER;
  gpu.set = std::make_unique<Descriptors>(
      ctx, std::vector<VkDescriptorType>(shared::kFrameBindingCount, t),
      VK_SHADER_STAGE_COMPUTE_BIT | VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT);
  Descriptors& set = *gpu.set;
  set.bind(shared::kFrameBindParams, gpu.params);
  set.bind(shared::kFrameBindInstances, grid.instance_buffer());
  set.bind(shared::kFrameBindTriangles, grid.triangle_buffer());
  set.bind(shared::kFrameBindPlanes, grid.plane_buffer());
  set.bind(shared::kFrameBindUvs, grid.uv_buffer());
  set.bind(shared::kFrameBindVisibility, gpu.visibility);
  set.bind(shared::kFrameBindGather, gpu.gather);
  set.bind(shared::kFrameBindMaterials, gpu.materials);
  set.bind(shared::kFrameBindDiffuseTexels, gpu.texels);
  set.bind(shared::kFrameBindLights, gpu.lights);
  set.bind(shared::kFrameBindRays, gpu.rays);
  set.bind(shared::kFrameBindHits, gpu.hits);
  set.bind(shared::kFrameBindImage, gpu.image);
  set.bind(shared::kFrameBindRayList, gpu.ray_list);
  set.bind(shared::kFrameBindGatherKeys, gpu.keys);
  set.bind(shared::kFrameBindTileList, gpu.tiles);
  set.bind(shared::kFrameBindTileDepth, gpu.tile_depth);
  set.bind(shared::kFrameBindPixelDirs, gpu.pixel_dirs);
  set.bind(shared::kFrameBindTileBins, gpu.tile_bins);
  const uint32_t flags = (bounce_ ? shared::kFrameBounce : 0u) | (textured ? shared::kFrameTextures : 0u) |
                         (alpha ? shared::kFrameAlpha : 0u) | (compact ? shared::kFrameCompact : 0u) |
                         (compute ? shared::kFrameComputeGather : 0u) |
                         (gather_ == GatherMode::boxes ? shared::kFrameGatherBoxes : 0u) |
                         (shadows_ ? shared::kFrameShadows : 0u);
  auto spec = [&] {
    SpecConstants s;
    s.add(shared::kFrameSpecFlags, flags);
    return s;
  };
  gpu.resolve = std::make_unique<Pipeline>(ctx, "gather_resolve.comp", set.layout(), 0, spec());
  // The bounce pass of its own only for the compacted or sorted rays (else the trace makes each
  // pixel's ray)
  if (compact || sorted) gpu.bounce = std::make_unique<Pipeline>(ctx, "bounce.comp", set.layout(), 0, spec());
  gpu.shade = std::make_unique<Pipeline>(ctx, "shade.comp", set.layout(), 0, spec());
  const uint32_t list_push = 3 * sizeof(uint32_t);
  if (compact) {
    gpu.ray_list_set = std::make_unique<Descriptors>(ctx, std::initializer_list<VkDescriptorType>{t});
    gpu.ray_list_set->bind(0, gpu.ray_list);
    gpu.ray_list_dispatch = std::make_unique<Pipeline>(ctx, "work_list_dispatch.comp", gpu.ray_list_set->layout(), list_push);
  }
  if (sorted) {
    gpu.sort_set = std::make_unique<Descriptors>(
        ctx, std::vector<VkDescriptorType>(shared::kRaySortBindingCount, t), VK_SHADER_STAGE_COMPUTE_BIT);
    gpu.sort_set->bind(shared::kRaySortBindRays, gpu.rays);
    gpu.sort_set->bind(shared::kRaySortBindKeysA, gpu.sort_keys_a);
    gpu.sort_set->bind(shared::kRaySortBindKeysB, gpu.sort_keys_b);
    gpu.sort_set->bind(shared::kRaySortBindListA, gpu.ray_list);
    gpu.sort_set->bind(shared::kRaySortBindValuesB, gpu.sort_values_b);
    gpu.sort_set->bind(shared::kRaySortBindCounts, gpu.sort_counts);
    const uint32_t push = uint32_t(sizeof(shared::RaySortPush));
    gpu.sort_count = std::make_unique<Pipeline>(ctx, "ray_sort.comp", gpu.sort_set->layout(), push,
                                                SpecConstants().add(shared::kRaySortSpecStage, 0u));
    gpu.sort_scan = std::make_unique<Pipeline>(ctx, "ray_sort.comp", gpu.sort_set->layout(), push,
                                               SpecConstants().add(shared::kRaySortSpecStage, 1u));
    gpu.sort_scatter = std::make_unique<Pipeline>(ctx, "ray_sort.comp", gpu.sort_set->layout(), push,
                                                  SpecConstants().add(shared::kRaySortSpecStage, 2u));
  }
  if (compute) {
    gpu.bin = std::make_unique<Pipeline>(ctx, "gather_bin.comp", set.layout(), uint32_t(sizeof(shared::GatherBinPush)), spec());
    if (gather_ == GatherMode::compute) gpu.dirs = std::make_unique<Pipeline>(ctx, "gather_dirs.comp", set.layout(), 0, spec());
    gpu.tile_pass = std::make_unique<Pipeline>(
        ctx, gather_ == GatherMode::boxes ? "gather_tiles.comp" : "gather_raster.comp", set.layout(), 0, spec());
    if (gather_ == GatherMode::compute) {
      const uint32_t fine_push = uint32_t(sizeof(shared::GatherFinePush));
      gpu.pairs = std::make_unique<Pipeline>(ctx, "gather_pairs.comp", set.layout(), fine_push, spec());
      gpu.scan = std::make_unique<Pipeline>(ctx, "gather_scan.comp", set.layout(), fine_push, spec());
      gpu.past = std::make_unique<Pipeline>(ctx, "gather_past.comp", set.layout(), fine_push, spec());
      gpu.fine = std::make_unique<Pipeline>(ctx, "gather_fine.comp", set.layout(), fine_push, spec());
    }
  } else {
    SpecConstants raster_spec = spec();
    gpu.create_raster(w, h, raster_spec.info());
  }
  if (ctx.info().timestamp_valid_bits) gpu.timestamps = std::make_unique<Timestamps>(ctx, 17);
}

VulkanFrame::~VulkanFrame() { gpu_.reset(); }

bool VulkanFrame::traces_together() const {
  return options_.traces_together && bounce_ && shadows_ && !options_.compact_rays && options_.sort_bits == 0u;
}

void VulkanFrame::render(uint32_t frame, uint32_t repeats, bool traces_apart) {
  if (!grid_.built())
    throw Error("vulkan frame: its grid is not built now (a build or an update of it failed): build it again and make "
                "a new frame");
  if (grid_.build_generation() != grid_generation_)
    throw Error("vulkan frame: its grid was built again after this frame was made (the frame holds the old build's "
                "buffers): make a new frame");
  Context& ctx = grid_.context();
  Gpu& gpu = *gpu_;
  const uint32_t w = options_.width, h = options_.height;
  const bool compact = bool(gpu.ray_list_dispatch), sorted = bool(gpu.sort_count);
  const bool together = traces_together() && !traces_apart;
  const uint32_t max_groups_x = ctx.info().limits.maxComputeWorkGroupCount[0];
  repeats = std::max(repeats, 1u);
  ctx.upload(gpu.params, &frame, sizeof frame, offsetof(shared::FrameParams, frame));
  if (bounce_ || shadows_) grid_.bind_ray_buffers(gpu.rays, gpu.hits, compact || sorted ? &gpu.ray_list : nullptr);
  if (bounce_ || shadows_) grid_.bind_frame(gpu.gather, gpu.params, gpu.materials);
  const std::vector<shared::GridInstance>& instances = grid_.instances();
  const uint32_t triangles = instances.empty() ? 0u : instances.back().tri_offset + instances.back().tri_count;
  const auto t0 = std::chrono::steady_clock::now();
  ctx.submit([&](VkCommandBuffer cb) {
    barrier(cb);  // the grid's update and the parameters, before anything reads them
    if (gpu.timestamps) gpu.timestamps->reset(cb);
    for (uint32_t rep = 0; rep < repeats; ++rep) {
      // Timestamps bracket the last repetition only (the earlier ones keep the GPU busy)
      const bool timed = gpu.timestamps && rep + 1 == repeats;
      if (rep > 0) barrier(cb);
      if (timed) gpu.timestamps->write(cb, 0, VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT);
      const VkDescriptorSet s = gpu.set->set();
      if (gather_ != GatherMode::raster) {
        // Gather, compute: every key "nothing" (all ones), every tile's depth bound unknown (all
        // ones), the tile lists' counts 0, and the pixels' ray directions, once (the rasterizer:
        // one pass writes all of them); then the triangles' set-up and work items, their pixels
        if (gpu.dirs) {
          gpu.dirs->bind(cb, s);
          vkCmdDispatch(cb, groups(w, shared::kGatherTileSize), groups(h, shared::kGatherTileSize), 1);
        } else {
          vkCmdFillBuffer(cb, gpu.keys.buffer, 0, VK_WHOLE_SIZE, 0xFFFFFFFFu);
          vkCmdFillBuffer(cb, gpu.tile_depth.buffer, 0, VK_WHOLE_SIZE, 0xFFFFFFFFu);
        }
        gather_barrier(cb);
        if (timed) gpu.timestamps->write(cb, 9);
        {
          // The bin pass (a workgroup even without triangles: its last workgroup writes the
          // dispatches of the passes after it)
          const glm::uvec3 g = shared::work_list_groups(std::max(triangles, 1u), 64u, max_groups_x);
          const shared::GatherBinPush push{triangles, uint32_t(instances.size()), max_groups_x, 0u};
          gpu.bin->bind(cb, s);
          gpu.bin->push(cb, push);
          vkCmdDispatch(cb, g.x, g.y, 1);
        }
        gather_barrier(cb);
        if (timed) gpu.timestamps->write(cb, 1);
        if (gpu.fine) {
          // The rasterizer: each bin's screen tiles counted, the counts scanned, the pairs
          // written, then one workgroup per screen tile; where the pairs overflowed, the item
          // pass instead (the scan chose which of the two indirect dispatches has workgroups)
          shared::GatherFinePush fine_push{gpu.screen_tiles, gpu.pair_capacity, 0u, 0u};
          if (options_.gather_lists == GatherLists::buckets) {
            // Buckets: the pairs written in one pass (those past a tile's bucket rasterized there),
            // then the fine pass; no scan, no item pass
            fine_push.scatter = 2u;
            fine_push.past_capacity = gpu.past_capacity;
            gpu.pairs->bind(cb, s);
            gpu.pairs->push(cb, fine_push);
            vkCmdDispatchIndirect(cb, gpu.tile_bins.buffer, offsetof(shared::GatherFineHeader, items_x));
            gather_barrier(cb);
            if (timed) gpu.timestamps->write(cb, 10);
            // The pairs past their buckets: a fixed number of workgroups takes the list in turns
            if (gpu.past_capacity > 0) {
              gpu.past->bind(cb, s);
              gpu.past->push(cb, fine_push);
              vkCmdDispatch(cb, std::clamp(std::min(gpu.past_capacity, kGatherPastGroups), 1u, max_groups_x), 1, 1);
              gather_barrier(cb);
            }
            if (timed)
              for (uint32_t q : {11u, 12u}) gpu.timestamps->write(cb, q);
          } else {
          gpu.pairs->bind(cb, s);
          gpu.pairs->push(cb, fine_push);
          vkCmdDispatchIndirect(cb, gpu.tile_bins.buffer, offsetof(shared::GatherFineHeader, items_x));
          gather_barrier(cb);
          if (timed) gpu.timestamps->write(cb, 10);
          gpu.scan->bind(cb, s);
          gpu.scan->push(cb, fine_push);
          const uint32_t scan_groups =
              options_.gather_scan_groups.value_or(std::min(groups(gpu.screen_tiles, shared::kGatherScanBlock), shared::kGatherScanMaxGroups));
          vkCmdDispatch(cb, std::clamp(scan_groups, 1u, max_groups_x), 1, 1);
          gather_barrier(cb);
          if (timed) gpu.timestamps->write(cb, 11);
          // The scatter, and beside it the item pass (no barrier between: the scan gave the item
          // pass workgroups only where the pairs overflowed, and then the scatter writes nothing)
          fine_push.scatter = 1u;
          gpu.pairs->bind(cb, s);
          gpu.pairs->push(cb, fine_push);
          vkCmdDispatchIndirect(cb, gpu.tile_bins.buffer, offsetof(shared::GatherFineHeader, items_x));
          gpu.tile_pass->bind(cb, s);
          vkCmdDispatchIndirect(cb, gpu.tiles.buffer, 0);
          gather_barrier(cb);
          if (timed) gpu.timestamps->write(cb, 12);
          }
          // Then one workgroup per tile: its list, and the resolve of its pixels
          const glm::uvec3 tile_groups = shared::work_list_groups(gpu.screen_tiles, 1u, max_groups_x);
          gpu.fine->bind(cb, s);
          gpu.fine->push(cb, fine_push);
          vkCmdDispatch(cb, tile_groups.x, tile_groups.y, tile_groups.z);
          gather_barrier(cb);
        } else {
          if (timed)
            for (uint32_t q : {10u, 11u, 12u}) gpu.timestamps->write(cb, q);
          gpu.tile_pass->bind(cb, s);
          vkCmdDispatchIndirect(cb, gpu.tiles.buffer, 0);
          gather_barrier(cb);
        }
        if (timed) gpu.timestamps->write(cb, 2);
      } else {
        // Gather, raster: one draw per instance (firstInstance = its id), then the copy
        VkClearValue clear[2]{};
        clear[0].color.uint32[0] = shared::kNoRef;
        clear[1].depthStencil = {0.0f, 0};
        VkRenderPassBeginInfo bi{VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO};
        bi.renderPass = gpu.pass;
        bi.framebuffer = gpu.framebuffer;
        bi.renderArea = {{0, 0}, {w, h}};
        bi.clearValueCount = 2;
        bi.pClearValues = clear;
        vkCmdBeginRenderPass(cb, &bi, VK_SUBPASS_CONTENTS_INLINE);
        vkCmdBindPipeline(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, gpu.raster);
        vkCmdBindDescriptorSets(cb, VK_PIPELINE_BIND_POINT_GRAPHICS, gpu.layout, 0, 1, &s, 0, nullptr);
        for (uint32_t i = 0; i < instances.size(); ++i)
          if (instances[i].tri_count) vkCmdDraw(cb, 3 * instances[i].tri_count, 1, 0, i);
        vkCmdEndRenderPass(cb);
        if (timed)
          for (uint32_t q : {9u, 1u, 10u, 11u, 12u}) gpu.timestamps->write(cb, q);
        VkBufferImageCopy region{};
        region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
        region.imageExtent = {w, h, 1};
        vkCmdCopyImageToBuffer(cb, gpu.color.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, gpu.visibility.buffer, 1,
                               &region);
        barrier(cb);
        if (timed) gpu.timestamps->write(cb, 2);
      }
      // Gather: position, normal, material, uv from the visible triangle (the rasterizer's fine
      // pass did this)
      if (!gpu.fine) {
        gpu.resolve->bind(cb, s);
        vkCmdDispatch(cb, groups(w, 8), groups(h, 8), 1);
      }
      barrier(cb);
      if (timed) gpu.timestamps->write(cb, 3);
      if (bounce_) {
        // Bounce rays, then their trace through the grid: the listed rays (the list's dispatch
        // step first), or every pixel, its ray made by the trace (no pass of its own: the bounce
        // time is 0)
        if (compact) {
          gpu.bounce->bind(cb, s);
          vkCmdDispatch(cb, groups(w, 8), groups(h, 8), 1);
          barrier(cb);
          if (timed) gpu.timestamps->write(cb, 4);
          const shared::WorkListDispatchPush list_push{64u, max_groups_x, w * h};
          gpu.ray_list_dispatch->bind(cb, gpu.ray_list_set->set());
          gpu.ray_list_dispatch->push(cb, list_push);
          vkCmdDispatch(cb, 1, 1, 1);
          barrier(cb);
          grid_.record_trace_list(cb);
        } else if (sorted) {
          // The pixels sorted by their rays' keys (ray_sort.comp), then traced in that order
          gpu.bounce->bind(cb, s);
          vkCmdDispatch(cb, groups(w, 8), groups(h, 8), 1);
          barrier(cb);
          if (timed) gpu.timestamps->write(cb, 4);
          const uint32_t passes = options_.sort_bits / 4u;
          const glm::uvec3 sg = shared::work_list_groups(gpu.sort_push.blocks, 1u, max_groups_x);
          for (uint32_t p = 0; p < passes; ++p) {
            shared::RaySortPush push = gpu.sort_push;
            push.shift = 32u - options_.sort_bits + 4u * p;
            push.parity = p & 1u;
            push.first_pass = p == 0 ? 1u : 0u;
            gpu.sort_count->bind(cb, gpu.sort_set->set());
            gpu.sort_count->push(cb, push);
            vkCmdDispatch(cb, sg.x, sg.y, 1);
            gather_barrier(cb);  // compute to compute
            if (timed && p == 0) gpu.timestamps->write(cb, 14);  // the first pass's split
            gpu.sort_scan->bind(cb, gpu.sort_set->set());
            gpu.sort_scan->push(cb, push);
            vkCmdDispatch(cb, shared::kRaySortBuckets, 1, 1);
            gather_barrier(cb);  // compute to compute
            if (timed && p == 0) gpu.timestamps->write(cb, 15);
            gpu.sort_scatter->bind(cb, gpu.sort_set->set());
            gpu.sort_scatter->push(cb, push);
            vkCmdDispatch(cb, sg.x, sg.y, 1);
            gather_barrier(cb);  // compute to compute
            if (timed && p == 0) gpu.timestamps->write(cb, 16);
          }
          if (timed) gpu.timestamps->write(cb, 13);
          grid_.record_trace_list(cb);
        } else if (together) {
          // The bounce trace and the first light's shadow trace in one dispatch (an 8x8 pixel
          // tile a workgroup, the bounce tiles first): the shadow tiles fill the device while the
          // bounce trace's last workgroups run, where a barrier between two passes left it idle
          if (timed) gpu.timestamps->write(cb, 4);
          grid_.record_bounce_and_shadow_trace_image(cb, w, h, w * h, scene_.lights[0].position,
                                                     scene_.lights[0].directional);
        } else {
          if (timed) gpu.timestamps->write(cb, 4);
          grid_.record_bounce_trace_image(cb, w, h);  // an 8x8 pixel tile a workgroup
        }
        barrier(cb);
        if (timed) gpu.timestamps->write(cb, 5);
      } else if (timed) {
        gpu.timestamps->write(cb, 4);
        gpu.timestamps->write(cb, 5);
      }
      if (timed && !(bounce_ && sorted))
        for (uint32_t q : {13u, 14u, 15u, 16u}) gpu.timestamps->write(cb, q);  // the sort's: none
      // Shadow rays to every light, their trace
      if (shadows_) {
        // The trace makes each pixel's shadow ray from the gather itself (no pass of its own:
        // the "rays" part of the shadow pass's time is 0)
        if (timed) gpu.timestamps->write(cb, 6);
        for (uint32_t l = together ? 1u : 0u; l < uint32_t(scene_.lights.size()); ++l) {
          // One light's rays and hits after another's: disjoint ranges of the same bindings, which
          // a barrier orders as the synchronization validation reads the whole binding
          if (l > (together ? 1u : 0u)) barrier(cb);
          grid_.record_shadow_trace_image(cb, w, h, (1 + l) * w * h, scene_.lights[l].position,
                                          scene_.lights[l].directional);
        }
        barrier(cb);
        if (timed) gpu.timestamps->write(cb, 7);
      } else if (timed) {
        gpu.timestamps->write(cb, 6);
        gpu.timestamps->write(cb, 7);
      }
      // Shade
      gpu.shade->bind(cb, s);
      vkCmdDispatch(cb, groups(w, 8), groups(h, 8), 1);
      if (timed) gpu.timestamps->write(cb, 8);
    }
  });
  timings_.host_ms = ms_since(t0);
  timings_.traces_together = together;
  if (gpu.timestamps) {
    const std::vector<double> ns = gpu.timestamps->read_ns();
    const bool compute = gather_ != GatherMode::raster;
    timings_.visibility_ms = ((compute ? ns[2] : ns[1]) - ns[0]) * 1e-6;
    timings_.bin_ms = compute ? (ns[1] - ns[0]) * 1e-6 : 0.0;
    timings_.tiles_ms = compute ? (ns[2] - ns[1]) * 1e-6 : 0.0;
    timings_.dirs_ms = compute ? (ns[9] - ns[0]) * 1e-6 : 0.0;
    timings_.count_ms = gpu.fine ? (ns[10] - ns[1]) * 1e-6 : 0.0;
    timings_.scan_ms = gpu.fine ? (ns[11] - ns[10]) * 1e-6 : 0.0;
    timings_.scatter_ms = gpu.fine ? (ns[12] - ns[11]) * 1e-6 : 0.0;
    timings_.fine_ms = gpu.fine ? (ns[2] - ns[12]) * 1e-6 : 0.0;
    timings_.copy_ms = compute ? 0.0 : (ns[2] - ns[1]) * 1e-6;
    timings_.resolve_ms = (ns[3] - ns[2]) * 1e-6;
    timings_.gather_ms = (ns[3] - ns[0]) * 1e-6;
    timings_.bounce_ms = (ns[4] - ns[3]) * 1e-6;
    timings_.trace_ms = (ns[5] - ns[4]) * 1e-6;
    if (gpu.sort_count && bounce_) {
      timings_.sort_ms = (ns[13] - ns[4]) * 1e-6;
      timings_.sort_first_pass_ms[0] = (ns[14] - ns[4]) * 1e-6;
      timings_.sort_first_pass_ms[1] = (ns[15] - ns[14]) * 1e-6;
      timings_.sort_first_pass_ms[2] = (ns[16] - ns[15]) * 1e-6;
    }
    timings_.shadow_ms = shadows_ ? (ns[7] - ns[5]) * 1e-6 : 0.0;
    timings_.shadow_trace_ms = shadows_ ? (ns[7] - ns[6]) * 1e-6 : 0.0;
    timings_.shade_ms = (ns[8] - ns[7]) * 1e-6;
    timings_.total_ms = (ns[8] - ns[0]) * 1e-6;
  }
  // llvmpipe's loop limit (vulkan/grid.h): the frame's traces' records checked there; and the
  // gather's fine pass, whose workgroup walks its screen tile's list of triangles (a tile listing
  // about 64,000 was cut short, pixels left without their triangle: refused from
  // kLlvmpipeTilePairLimit, read from the lists' starts)
  if (ctx.info().driver_id == VK_DRIVER_ID_MESA_LLVMPIPE) {
    if (bounce_) check_loop_limit(ctx, grid_.params(), download_hits(), "the frame's bounce rays");
    if (shadows_) check_loop_limit(ctx, grid_.params(), download_shadow_hits(), "the frame's shadow rays");
    if (gpu_->fine) {
      const size_t header = sizeof(shared::GatherFineHeader) / 4, tiles = gpu_->screen_tiles;
      const bool buckets = options_.gather_lists == GatherLists::buckets;
      const std::vector<uint32_t> words = ctx.download<uint32_t>(gpu_->tile_bins, header + (buckets ? 1 : 2) * tiles);
      const auto head = ctx.download<shared::GatherFineHeader>(gpu_->tile_bins, 1)[0];
      uint32_t most = 0;
      if (buckets) {
        // The counts: a tile's list is its bucket, up to its capacity
        for (size_t t = 0; t < tiles; ++t) most = std::max(most, std::min(words[header + t], gpu_->pair_capacity));
      }
      for (size_t t = 0; !buckets && head.overflow == 0u && t < tiles; ++t) {
        const uint32_t begin = words[header + tiles + t];
        const uint32_t end = t + 1 < tiles ? words[header + tiles + t + 1] : head.pairs;
        most = std::max(most, end >= begin ? end - begin : 0u);
      }
      if (most >= kLlvmpipeTilePairLimit)
        throw Error("vulkan-frame: a screen tile lists " + std::to_string(most) +
                    " triangles; llvmpipe (a CPU Vulkan driver) ends a shader's loops after 65,535 iterations in "
                    "all, which cuts the gather's fine pass short (refused from " +
                    std::to_string(kLlvmpipeTilePairLimit) +
                    "): its gather cannot be trusted (run on a GPU, or with --backend cpu)");
    }
  }
}

GatherBuffer VulkanFrame::download_gather() const {
  Context& ctx = grid_.context();
  const uint32_t w = options_.width, h = options_.height;
  const std::vector<shared::GatherTexel> texels = ctx.download<shared::GatherTexel>(gpu_->gather, size_t(w) * h);
  GatherBuffer g;
  g.width = w;
  g.height = h;
  const size_t n = g.size();
  g.valid.assign(n, 0);
  g.position.assign(n, glm::vec3(0.0f));
  g.normal.assign(n, glm::vec3(0.0f));
  g.incident.resize(n);
  g.material.assign(n, kNoMaterial);
  g.uv.assign(n, glm::vec2(0.0f));
  g.launch_ref.assign(n, shared::kNoRef);
  g.hit.assign(n, Hit{0.0f, shared::kNoInstance, 0, 0.0f, 0.0f, 0, 0, 0});
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) {
      const size_t p = size_t(y) * w + x;
      const shared::GatherTexel& t = texels[p];
      g.incident[p] = shared::camera_direction(gpu_->camera, x, y);
      if (t.launch_ref == shared::kNoRef) continue;
      g.valid[p] = 1;
      g.position[p] = t.position;
      g.normal[p] = t.normal;
      g.material[p] = t.material;
      g.uv[p] = t.uv;
      g.launch_ref[p] = t.launch_ref;
      g.hit[p].t = t.t;
      g.hit[p].instance = shared::ref_instance(t.launch_ref);
      g.hit[p].triangle = shared::ref_triangle(t.launch_ref);
    }
  return g;
}

std::vector<Ray> VulkanFrame::download_rays() const {
  return grid_.context().download<Ray>(gpu_->rays, size_t(options_.width) * options_.height);
}

std::string ray_order_problem(const std::vector<uint32_t>& order, const std::vector<uint32_t>& keys,
                              const std::vector<Ray>& rays, uint32_t sort_bits) {
  const size_t n = rays.size();
  const size_t used = size_t(std::count_if(rays.begin(), rays.end(), [](const Ray& r) { return r.tmax > 0.0f; }));
  if (order.size() != used || keys.size() != used)
    return "the order holds " + std::to_string(order.size()) + " pixels and " + std::to_string(keys.size()) +
           " keys for " + std::to_string(used) + " rays (of " + std::to_string(n) + " pixels)";
  if (sort_bits == 0u || sort_bits > 32u) return "sorted by " + std::to_string(sort_bits) + " bits";
  const uint32_t shift = 32u - sort_bits;
  std::vector<uint8_t> seen(n, 0);
  for (size_t k = 0; k < used; ++k) {
    const uint32_t p = order[k];
    if (p >= n) return "place " + std::to_string(k) + " holds pixel " + std::to_string(p) + ", past the image";
    if (seen[p]++) return "pixel " + std::to_string(p) + " comes twice (again at place " + std::to_string(k) + ")";
    if (!(rays[p].tmax > 0.0f)) return "place " + std::to_string(k) + ": pixel " + std::to_string(p) + " has no ray";
    if (keys[k] == 0xFFFFFFFFu)
      return "place " + std::to_string(k) + ": pixel " + std::to_string(p) + " has a ray and the no-ray key";
    if (k > 0) {
      const uint64_t a = uint64_t(keys[k - 1]) >> shift, b = uint64_t(keys[k]) >> shift;
      if (a > b || (a == b && order[k - 1] > p))
        return "places " + std::to_string(k - 1) + " and " + std::to_string(k) + " out of order: keys " +
               std::to_string(keys[k - 1]) + ", " + std::to_string(keys[k]) + " of pixels " +
               std::to_string(order[k - 1]) + ", " + std::to_string(p);
    }
  }
  return "";
}

std::vector<uint32_t> VulkanFrame::download_ray_order() const {
  if (!gpu_->sort_count || !bounce_) return {};
  const size_t n = size_t(options_.width) * options_.height;
  const std::vector<uint32_t> words = grid_.context().download<uint32_t>(gpu_->ray_list, shared::kWorkListHeaderWords + n);
  const size_t size = std::min<size_t>(words[shared::kWorkListSizeWord], n);  // the rays, first
  return std::vector<uint32_t>(words.begin() + shared::kWorkListHeaderWords,
                               words.begin() + shared::kWorkListHeaderWords + ptrdiff_t(size));
}

std::vector<uint32_t> VulkanFrame::download_ray_order_keys() const {
  if (!gpu_->sort_count || !bounce_) return {};
  const size_t n = size_t(options_.width) * options_.height;
  std::vector<uint32_t> keys = grid_.context().download<uint32_t>(gpu_->sort_keys_a, n);
  const std::vector<uint32_t> head = grid_.context().download<uint32_t>(gpu_->ray_list, shared::kWorkListHeaderWords);
  keys.resize(std::min<size_t>(head[shared::kWorkListSizeWord], n));  // the rays' keys, first
  return keys;
}

std::vector<Hit> VulkanFrame::download_hits() const {
  return grid_.context().download<Hit>(gpu_->hits, size_t(options_.width) * options_.height);
}

std::vector<Ray> VulkanFrame::download_shadow_rays() const {
  if (!shadows_) return {};
  const size_t pixels = size_t(options_.width) * options_.height;
  return grid_.context().download<Ray>(gpu_->rays, pixels * scene_.lights.size(), pixels * sizeof(Ray));
}

std::vector<Hit> VulkanFrame::download_shadow_hits() const {
  if (!shadows_) return {};
  const size_t pixels = size_t(options_.width) * options_.height;
  return grid_.context().download<Hit>(gpu_->hits, pixels * scene_.lights.size(), pixels * sizeof(Hit));
}

std::vector<uint8_t> VulkanFrame::download_rgba() const {
  return grid_.context().download<uint8_t>(gpu_->image, size_t(options_.width) * options_.height * 4);
}

std::vector<uint32_t> VulkanFrame::download_visibility() const {
  return grid_.context().download<uint32_t>(gpu_->visibility, size_t(options_.width) * options_.height);
}

GatherPairs VulkanFrame::download_gather_pairs() const {
  if (!gpu_->fine) return {};
  if (options_.gather_lists == GatherLists::buckets) {
    // The counts after the header: the pairs each tile was offered
    const size_t words = (sizeof(shared::GatherFineHeader) / 4) + gpu_->screen_tiles;
    const std::vector<uint32_t> w = grid_.context().download<uint32_t>(gpu_->tile_bins, words);
    GatherPairs p;
    p.buckets = true;
    p.bucket = gpu_->pair_capacity;
    p.capacity = uint64_t(gpu_->pair_capacity) * gpu_->screen_tiles;
    for (size_t t = sizeof(shared::GatherFineHeader) / 4; t < words; ++t) {
      p.pairs += w[t];
      p.past += w[t] > gpu_->pair_capacity ? w[t] - gpu_->pair_capacity : 0u;
    }
    p.overflow = p.past > 0;
    p.past_counted = w[0 + offsetof(shared::GatherFineHeader, pairs) / 4];
    p.past_in_place = p.past_counted > gpu_->past_capacity ? p.past_counted - gpu_->past_capacity : 0;
    return p;
  }
  const auto h = grid_.context().download<shared::GatherFineHeader>(gpu_->tile_bins, 1)[0];
  GatherPairs p;
  p.pairs = h.pairs;
  p.capacity = gpu_->pair_capacity;
  p.overflow = h.overflow != 0;
  return p;
}

uint32_t VulkanFrame::download_gather_tiles() const {
  if (gather_ == GatherMode::raster) return 0;
  return grid_.context().download<shared::GatherTileHeader>(gpu_->tiles, 1)[0].tiles;
}

const Buffer& VulkanFrame::ray_buffer() const { return gpu_->rays; }
const Buffer& VulkanFrame::hit_buffer() const { return gpu_->hits; }

}  // namespace gridrt::vulkan
