// frame.h: the paper's frame on the GPU, after the grid's update, in one submission:
//   gather   the visible triangle per pixel, by one of two passes:
//            compute (default where the device has 64-bit buffer atomics): gather_bin.comp clips
//              each triangle to the view frustum and tests a small screen box itself or sets the
//              triangle up (edge functions, a depth bound) and lists it with its 32x32-pixel
//              screen bins; gather_pairs.comp and gather_scan.comp list per 8x8 screen tile
//              the large triangles that may cover it; gather_fine.comp, a workgroup per tile,
//              rejects pixels by the edge functions, culls triangles by depth per subgroup,
//              tests the rest's pixel rays with the shared ray test and keeps the smallest
//              (t, reference) (gather_visibility.glsl): the CPU gather's own rule; it writes
//              the gather texels itself. Where the tile lists overflow their room,
//              gather_raster.comp instead (per bin: rejects bins, tiles and pixels, culls tiles
//              by depth, takes the keys by 64-bit atomic min), then gather_resolve.comp
//            boxes: the same without the rasterizer's rejections (gather_tiles.comp: every pixel
//              of the box's 8x8 tiles), kept to be measured against it
//            raster (the paper's): gather.vert + gather.frag, the geometry buffer's world-space
//              triangles, depth test, the reference into an R32_UINT attachment copied to a buffer
//            then gather_resolve.comp turns it into the gather buffer (position, normal, material,
//            uv, launch reference) with the same shared math as make_gather
//   bounce   (compacted rays only, an option) bounce.comp: one glossy bounce ray per pixel, as
//            bounce_rays (common/shared/bounce.h); the pixels with a ray are appended to a work
//            list, the others get their (miss) hit at once
//   sort     (sorted rays only, an option) ray_sort.comp: the pixels ordered by their bounce
//            ray's direction and origin, a radix sort's passes into the ray list
//   trace    the grid's trace pipeline: every pixel, the trace making the pixel's bounce ray
//            itself as bounce.comp would and writing it to the ray buffer
//            (VulkanGridTracer::record_bounce_trace_image), or the work list's rays
//            (record_trace_list, an indirect dispatch)
//   shadow   (a scene with lights only: kFrameShadows) the grid's trace per light, which makes
//            each pixel's shadow ray from the gather itself, as shadow_rays (common/shared/
//            shadow.h), writes it after the bounce rays in the ray buffer and traces it for any
//            hit (VulkanGridTracer::record_shadow_trace_image)
//   shade    shade.comp: as shade() into RGBA8, sRGB-encoded (with shadows: by their hits)
// Each phase is bracketed by timestamp queries. Nothing goes through the host between phases.
//
// The compute gather decides each pixel as the CPU's primary ray does (closest accepted t past
// the origin epsilon, then the smaller reference), on every pixel; only where the eye lies within
// a hair of a triangle's plane (common/shared/raster.h, raster_setup without bounds) does it leave
// out that triangle's hits within the near plane (scene extent * 1e-6).
// The tie rule of the raster gather: the rasterizer covers a pixel centre by Vulkan's rules (the
// top-left rule on shared edges) and keeps the nearest interpolated depth; the CPU gather keeps the
// ray's closest accepted hit (ties: the smaller reference). They pick different triangles only
// where two candidates meet at the pixel centre (a shared edge, a silhouette, an intersection, or
// depths within the rasterizer's precision); tests/test_vulkan_frame.cpp counts and bounds those.
#pragma once

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "gridrt/common/gather.h"
#include "gridrt/common/shade.h"
#include "gridrt/vulkan/grid.h"
#include "gridrt/vulkan/shaders/frame_input.h"

namespace gridrt::vulkan {

// Device milliseconds of the phases of the last render() (0 without timestamps), and the host's
// submit-to-fence time of the whole (on lavapipe the one to read: docs/VULKAN.md).
struct FrameTimings {
  double gather_ms = 0.0, bounce_ms = 0.0, trace_ms = 0.0, shade_ms = 0.0;
  // The shadow pass (0 without): its rays, then their trace (shadow_trace_ms of shadow_ms)
  double shadow_ms = 0.0, shadow_trace_ms = 0.0;
  // The sorted rays (FrameOptions::sort_bits): the sort's passes, of trace_ms (0 without)
  double sort_ms = 0.0;
  double sort_first_pass_ms[3] = {0.0, 0.0, 0.0};  // its first pass: count (the keys made), scan, scatter
  // The gather's parts: the visibility (raster pass, or the compute passes with the key buffer's
  // fill) and its compute passes (bin with the fill, tiles with their dispatch step), the raster
  // attachment's copy to a buffer, the resolve pass
  double visibility_ms = 0.0, bin_ms = 0.0, tiles_ms = 0.0, copy_ms = 0.0, resolve_ms = 0.0;
  // The compute gather's passes within bin_ms and tiles_ms: the fills with the pixel directions
  // (of bin_ms); with the fine pass (of tiles_ms) the dispatch step with the count, the scan, the
  // scatter, and the fine pass with its resolve (and the item pass, which has no workgroup unless
  // the pairs overflowed)
  double dirs_ms = 0.0, count_ms = 0.0, scan_ms = 0.0, scatter_ms = 0.0, fine_ms = 0.0;
  double total_ms = 0.0;  // gather + bounce + trace + shadow + shade
  // The bounce trace and the first light's shadow trace ran as one dispatch
  // (FrameOptions::traces_together): trace_ms holds both, shadow_ms the other lights' passes only
  bool traces_together = false;
  double host_ms = 0.0;
};

enum class GatherMode {
  compute,  // gather_bin/gather_raster.comp: the CPU gather's ray test (needs 64-bit buffer atomics)
  boxes,    // gather_bin/gather_tiles.comp: the same test on every pixel of the triangles' boxes
  raster,   // the paper's raster pass
};

// The compute gather's tile lists (FrameOptions::gather_lists)
enum class GatherLists { buckets, scan };
// Buckets: a tile's room by default (pairs), the list of pairs past their buckets' room by default
// (pairs per tile), and the workgroups that take that list in turns (gather_past.comp)
inline constexpr uint32_t kGatherBucketDefault = 64, kGatherPastPerTile = 16, kGatherPastGroups = 4096;

// The frame's near plane, the scene's extent (its bounds' diagonal at time 0) x 1e-6: the raster
// gather's clip plane, and the compute gather's where a triangle's box needs it (the header comment).
float frame_near_plane(const Scene& scene);

struct FrameOptions {
  uint32_t width = 1920, height = 1080;
  float ambient = 0.2f, exposure = 1.0f;  // ShadeOptions
  bool bounce = true;   // false: no bounce rays (as a scene without glossy materials)
  // Shadow rays to the scene's lights (at most shared::kMaxShadowLights, more: an Error); a
  // scene without lights compiles no shadow pass either way (shadows_for, common/gather.h)
  bool shadows = true;
  GatherMode gather = GatherMode::compute;  // compute falls back to raster without int64 atomics
  // The tile lists' passes: buckets (each 8x8-pixel tile's pairs written in one pass to a bucket of
  // its own, gather_bucket_capacity words; a pair past it listed for the past pass, which
  // rasterizes it a workgroup a pair) or scan (counted, scanned, then scattered into one array of
  // gather_pair_capacity pairs; the item pass where they overflow). The keys are the same (tests
  // hold both to the box gather).
  GatherLists gather_lists = GatherLists::buckets;
  // The compute gather's tile lists: room for this many (tile, large triangle) pairs; automatic
  // (unset): 64 per 8x8-pixel screen tile and 4 per triangle, within the device's buffer range. A
  // frame with more runs the item pass instead of the fine pass, with the same keys (slower;
  // download_gather_pairs tells).
  std::optional<uint64_t> gather_pair_capacity;
  // Buckets: a tile's room in pairs (unset: kGatherBucketDefault, within the device's buffer
  // range); the pairs past their buckets the past pass takes (unset: kGatherPastPerTile a tile;
  // more are rasterized one by one by the pairs pass)
  std::optional<uint32_t> gather_bucket_capacity;
  std::optional<uint64_t> gather_past_capacity;
  // Workgroups of the tile lists' scan (gather_scan.comp; unset: one per 4096 tiles, at most 64),
  // each scanning a run of consecutive blocks; fewer make longer runs (tests set it).
  std::optional<uint32_t> gather_scan_groups;
  // Trace only the pixels with a bounce ray (a work list). Off: measured slower on the H200
  // (docs/BENCHMARKS.md): the empty rays cost nothing measurable, the list loses coherence.
  bool compact_rays = false;
  // The bounce rays sorted before their trace (ray_sort.comp): 0, off (the trace takes every
  // pixel in 8x8 tiles and makes its ray itself); 16, 24 or 32, bounce.comp makes the rays, a
  // radix sort orders the pixels by the top sort_bits bits of each ray's key (its direction's
  // cell, then its origin's, as coherent_ray_order keys a list), and the trace takes them in that
  // order through the ray list. The same rays and hits either way. Not with compact_rays.
  uint32_t sort_bits = 0;
  // The bounce trace and the first light's shadow trace in one dispatch (the tiles' trace only:
  // not with compact_rays or sort_bits; the other lights' shadow traces follow as passes of their
  // own): the shadow tiles fill the device while the bounce trace's last workgroups run, where a
  // barrier between two passes left it idle (the frame 2-14 % faster on the H200,
  // docs/BENCHMARKS.md). The same rays and hits either way; off: two passes, each timed.
  bool traces_together = true;
};

// The compute gather's tile lists of the last render (GatherMode::compute; zeros otherwise).
struct GatherPairs {
  uint64_t pairs = 0;     // (8x8-pixel screen tile, large triangle) pairs
  uint64_t capacity = 0;  // pairs the lists hold (buckets: over all tiles)
  bool overflow = false;  // scan: pairs > capacity, the item pass ran instead of the fine pass;
                          // buckets: some tile's pairs past its bucket, rasterized by the pairs pass
  uint64_t past = 0;      // buckets: the pairs past their tiles' buckets (from the counts)
  uint64_t past_counted = 0;  // buckets: the same as the pairs pass counted them
  uint64_t past_in_place = 0; // buckets: those past the past pass's room, rasterized by the pairs pass
  bool buckets = false;
  uint32_t bucket = 0;    // buckets: a tile's room in pairs
};

// What is wrong with a sorted ray order (VulkanFrame::download_ray_order and _keys, the frame's
// bounce rays `rays`, a slot per pixel), "" where nothing is: the order must list every pixel
// with a ray (tmax above 0) once and no other, its keys in order by their top `sort_bits` bits,
// equal ones in the pixels' order (the radix sort is stable), and none the no-ray key 0xFFFFFFFF.
std::string ray_order_problem(const std::vector<uint32_t>& order, const std::vector<uint32_t>& keys,
                              const std::vector<Ray>& rays, uint32_t sort_bits);

class VulkanFrame {
 public:
  // `grid` must be built from `scene`; both outlive the frame. A frame renders only while its grid
  // stays built and is not built again (a new build makes new buffers: make a new frame then);
  // render() refuses, naming which, where the grid was built again or a build or update failed.
  VulkanFrame(VulkanGridTracer& grid, const Scene& scene, FrameOptions options = {});
  ~VulkanFrame();
  VulkanFrame(const VulkanFrame&) = delete;
  VulkanFrame& operator=(const VulkanFrame&) = delete;

  // Gather, bounce, trace and shade at the grid's current time (update the grid first);
  // `frame` selects the bounce's per-pixel random sequence (bounce_rays' frame). `repeats` > 1
  // records the passes that many times back to back in the one submission and times the last
  // (a GPU kept busy, as in a render loop, rather than idling while the host waits).
  // `traces_apart` records the bounce and shadow traces as two passes even where
  // traces_together() (the same rays and hits), so that their timings split them.
  void render(uint32_t frame, uint32_t repeats = 1, bool traces_apart = false);

  // Read-backs of the last render(), per pixel (index y * width + x).
  GatherBuffer download_gather() const;     // as make_gather fills it (hit: t, instance, triangle)
  std::vector<Ray> download_rays() const;   // the bounce rays
  std::vector<Hit> download_hits() const;   // their hits
  // The shadow rays and their hits, light-major as shadow_rays() orders them (empty: no shadows)
  std::vector<Ray> download_shadow_rays() const;
  std::vector<Hit> download_shadow_hits() const;
  std::vector<uint8_t> download_rgba() const;  // RGBA8, sRGB-encoded
  std::vector<uint32_t> download_visibility() const;  // the raster pass's reference per pixel
  // The compute gather's work items of the last render: 32x32-pixel bins (8x8-pixel tiles with
  // GatherMode::boxes; 0 for the raster gather).
  uint32_t download_gather_tiles() const;
  GatherPairs download_gather_pairs() const;

  // The sorted rays (FrameOptions::sort_bits) of the last render: the pixels with a ray in the
  // order the trace took them (the ray list), and their keys (ray_sort.comp) in the same order.
  // Empty without the sort.
  std::vector<uint32_t> download_ray_order() const;
  std::vector<uint32_t> download_ray_order_keys() const;

  // The device buffers of the bounce rays and hits (another tracer may trace the same rays).
  const Buffer& ray_buffer() const;
  const Buffer& hit_buffer() const;
  uint32_t ray_count() const { return options_.width * options_.height; }
  // Whether the bounce runs (the scene has glossy materials, and options.bounce).
  bool bounce() const { return bounce_; }
  // Whether the shadow pass runs (the scene has lights, and options.shadows).
  bool shadows() const { return shadows_; }
  // Whether render() traces the bounce rays and the first light's shadow rays in one dispatch
  // (options.traces_together, with both passes, in the tiles).
  bool traces_together() const;
  // The gather this frame runs (options.gather, unless the device lacks what compute needs).
  GatherMode gather_mode() const { return gather_; }

  const FrameTimings& timings() const { return timings_; }
  const FrameOptions& options() const { return options_; }

 private:
  struct Gpu;
  VulkanGridTracer& grid_;
  uint64_t grid_generation_ = 0;  // the grid's build this frame's buffers were bound to
  const Scene& scene_;
  FrameOptions options_;
  bool bounce_ = true;
  bool shadows_ = false;
  GatherMode gather_ = GatherMode::compute;
  std::unique_ptr<Gpu> gpu_;
  FrameTimings timings_;
};

}  // namespace gridrt::vulkan
