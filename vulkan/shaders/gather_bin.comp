#version 460
// gather_bin.comp: the compute gather's first pass (gather_visibility.glsl), one invocation per
// triangle of the geometry buffer: its screen box (common/shared/raster.h gather_box); a box of at
// most 16 pixels is tested here, a larger one is set up once (raster_setup_depth: edge functions, a
// depth bound and a depth plane) and appended to the list of large triangles with its count of work items, the 32x32-pixel bins
// of the screen its box touches (with kFrameGatherBoxes: the 8x8-pixel tiles of its box). One
// 64-bit atomic per subgroup gives each its list index and its first item; the item pass finds an
// item's triangle by binary search, so no invocation writes its items one by one.
// The dispatch step, by the last workgroup to finish (a counter of finished workgroups): the
// item pass one workgroup per item, the tile lists' count and scatter (gather_pairs.comp) 64
// items per workgroup; the counters again at 0 for the next frame. (A pass of its own before,
// one dependent step more.)
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(std430, binding = kFrameBindTileList) buffer TileCounter {
  uint tile_counter_header[6];
  uint64_t tile_counter;  // GatherTileHeader::counter_lo, counter_hi
};
layout(push_constant) uniform Push { GatherBinPush pc; };

// The triangle of this invocation: its box, then its test here or its record in the list
void bin_triangle() {
  const CameraParams c = fp.camera;
  const RasterCamera rc = fp.raster;  // made once by the host (the same bits as raster_camera here)
  const bool boxes = (kFrameFlags & kFrameGatherBoxes) != 0u;
  const uint k = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  uint items = 0u;
  uint ref = kNoRef;
  uvec4 box = uvec4(0u);
  bool here = false;  // a small box, tested by this invocation
  GridTriangle tri;
  if (k < pc.triangle_count) {
    const uint instance = gather_instance_of(k, pc.instance_count);
    ref = ref_pack(instance, k - instances[instance].tri_offset);
    tri = triangles[k];
    // Zero-area triangles are never hit (the grid does not insert them)
    if (!triangle_zero_area(tri.v0, tri.v1, tri.v2) && gather_box(c, rc, fp.near_plane, tri.v0, tri.v1, tri.v2, box)) {
      here = (box.z - box.x + 1u) * (box.w - box.y + 1u) <= 16u;
      if (!here) {
        if (boxes)
          items = ((box.z - box.x) / kGatherTileSize + 1u) * ((box.w - box.y) / kGatherTileSize + 1u);
        else
          items = (box.z / kGatherBinSize - box.x / kGatherBinSize + 1u) * (box.w / kGatherBinSize - box.y / kGatherBinSize + 1u);
      }
    }
  }
  // Append the large triangles: one 64-bit atomic per subgroup (triangles high, items low)
  const uint large = items != 0u ? 1u : 0u;
  const uint total_items = subgroupAdd(items), total_large = subgroupAdd(large);
  const uint items_before = subgroupExclusiveAdd(items), large_before = subgroupExclusiveAdd(large);
  uvec2 base = uvec2(0u);
  if (subgroupElect() && total_large != 0u)
    base = unpackUint2x32(atomicAdd(tile_counter, packUint2x32(uvec2(total_items, total_large))));
  base = subgroupBroadcastFirst(base);
  if (large != 0u) {
    GatherRasterTriangle g;
    g.t_lo = 0.0f;
    g.edge0 = vec3(0.0f, 0.0f, 1.0f);
    g.edge1 = g.edge0;
    g.edge2 = g.edge0;
    g.depth = vec4(0.0f, 0.0f, 1.0f, 0.0f);
    if (!boxes) raster_setup_depth(c, rc, tri.v0, tri.v1, tri.v2, g.edge0, g.edge1, g.edge2, g.t_lo, g.depth);
    g.ref = ref;
    g.first = base.x + items_before;
    g.box_lo = box.x | (box.y << 16u);
    g.box_hi = box.z | (box.w << 16u);
    g.index = k;
    g.pad0 = 0u;
    tile_tris[base.y + large_before] = g;
    return;
  }
  if (!here) return;
  for (uint y = box.y; y <= box.w; ++y)
    for (uint x = box.x; x <= box.z; ++x) {
      uvec2 key;
      const bool hit = boxes ? gather_key(ref, k, tri, uvec2(x, y), key)
                             : gather_key_along(ref, k, tri, pixel_dirs[y * c.width + x].xyz, pixel_dirs[y * c.width + x].w, key);
      if (hit) atomicMin(gather_keys64[y * c.width + x], packUint2x32(key));
    }
}

shared bool s_last;  // this workgroup finished last

void main() {
  bin_triangle();
  // Every invocation's append is done before the workgroup counts itself finished
  memoryBarrierBuffer();
  barrier();
  if (gl_LocalInvocationIndex == 0u) {
    const uint groups = gl_NumWorkGroups.x * gl_NumWorkGroups.y * gl_NumWorkGroups.z;
    s_last = atomicAdd(tile_header.done, 1u) == groups - 1u;
  }
  barrier();
  if (!s_last || gl_LocalInvocationIndex != 0u) return;
  // The dispatch step: every workgroup's appends are in the counter (read and reset atomically)
  memoryBarrierBuffer();
  const uvec2 counted = unpackUint2x32(atomicExchange(tile_counter, 0ul));
  const uvec3 groups = work_list_groups(counted.x, 1u, pc.max_groups_x);
  tile_header.groups_x = groups.x;
  tile_header.groups_y = groups.y;
  tile_header.groups_z = groups.z;
  tile_header.tiles = counted.x;
  tile_header.triangles = counted.y;
  tile_header.done = 0u;
  const uvec3 items = work_list_groups(counted.x, 64u, pc.max_groups_x);
  fine_header.items_x = items.x;
  fine_header.items_y = items.y;
  fine_header.items_z = items.z;
}
