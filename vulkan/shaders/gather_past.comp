#version 460
// gather_past.comp: the compute gather's pairs past their tile's bucket (gather_pairs.comp with
// buckets listed them), between the pairs pass and the fine pass: a fixed number of workgroups of
// 64 invocations, each subgroup taking the list's pairs in turn, its invocations the 64 pixels of
// the pair's 8x8-pixel tile (two each on a subgroup of 32: a workgroup takes two pairs at once, and
// each pair's chain of loads, its words, its triangle's record, is waited for half as often).
// Per pair, over the tile's pixels within the triangle's screen box, gather_raster.comp's pixel
// step: the edge functions at the pixel (raster_pixel_may_hit), then the gather's ray test along
// the pixel's camera_direction; an accepted hit takes the pixel's key by a 64-bit atomic min. The
// fine pass then reads the keys these left, its bucket holding the tile's other pairs: a tile
// listing more triangles than its bucket holds is not one workgroup's long loop (docs/SPEC.md "The
// gather as a rasterizer": the keys are a minimum, whichever pass takes a pair).
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_basic : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(push_constant) uniform Push { GatherFinePush pc; };

void main() {
  const CameraParams c = fp.camera;
  const uint tiles_x = (c.width + kGatherTileSize - 1u) / kGatherTileSize;
  // The list after the counts and the buckets: (tile, triangle) word pairs, up to past_capacity
  const uint list = pc.tiles + pc.tiles * pc.capacity;
  const uint n = min(fine_header.pairs, pc.past_capacity);
  // The subgroups of every workgroup, in turns: subgroup s of workgroup w takes pairs
  // w * subgroups + s, then that plus every subgroup's count
  const uint slots = gl_NumWorkGroups.x * gl_NumSubgroups;
  for (uint i = gl_WorkGroupID.x * gl_NumSubgroups + gl_SubgroupID; i < n; i += slots) {
    const uint tile = tile_words[list + 2u * i];
    const GatherRasterTriangle g = tile_tris[tile_words[list + 2u * i + 1u]];
    // The tile's pixels within the triangle's box
    const uint sx0 = (tile % tiles_x) * kGatherTileSize, sy0 = (tile / tiles_x) * kGatherTileSize;
    const uint qx0 = max(g.box_lo & 0xFFFFu, sx0), qy0 = max(g.box_lo >> 16u, sy0);
    const uint qx1 = min(g.box_hi & 0xFFFFu, sx0 + kGatherTileSize - 1u);
    const uint qy1 = min(g.box_hi >> 16u, sy0 + kGatherTileSize - 1u);
    for (uint q = gl_SubgroupInvocationID; q < kGatherTileSize * kGatherTileSize; q += gl_SubgroupSize) {
      const uvec2 px = uvec2(sx0 + q % kGatherTileSize, sy0 + q / kGatherTileSize);
      if (px.x < qx0 || px.y < qy0 || px.x > qx1 || px.y > qy1) continue;
      if (!raster_pixel_may_hit(g.edge0, g.edge1, g.edge2, px.x, px.y)) continue;
      const vec4 dir = pixel_dirs[px.y * c.width + px.x];
      uvec2 key;
      if (gather_key_along(g.ref, g.index, triangles[g.index], dir.xyz, dir.w, key))
        atomicMin(gather_keys64[px.y * c.width + px.x], packUint2x32(key));
    }
  }
}
