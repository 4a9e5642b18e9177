#version 460
// gather_raster.comp: the compute gather's second pass (gather_visibility.glsl), the rasterizer's
// coarse and fine stages (Laine and Karras, "High-Performance Software Rasterization on GPUs"):
// one workgroup per work item (a large triangle's 32x32-pixel screen bin), dispatched indirectly,
// one invocation per pixel of an 8x8-pixel tile. The item's triangle by binary search over the
// triangles' first items and its set-up record (gather_bin.comp, common/shared/raster.h); then
//   bin    the bin's pixels within the triangle's box, rejected as a whole when an edge function
//          is negative on all of them (raster_rect_may_hit)
//   tile   per 8x8 tile of those, the same rejection; then depth culling: the tile is skipped when
//          the triangle's lower t bound over the tile's pixels it tests (raster_tile_t_lo: its
//          depth plane's there, at least its t_lo) exceeds the tile's depth bound (no pixel holds
//          a key with a larger t, so the triangle wins none of them)
//   pixel  the edge functions at the pixel (raster_pixel_may_hit), then the gather's ray test
//          along the pixel's camera_direction (computed once per frame by gather_dirs.comp), an
//          accepted hit takes the pixel's key by a 64-bit atomic min
// A tile the triangle's box covers whole, and whose every pixel the test accepted, lowers the
// tile's depth bound to the largest t of its keys after the atomics (the atomics' old values and
// the new keys). The rejections only skip pairs the ray test rejects, the culling only pairs that
// cannot win: the keys end as gather_tiles.comp leaves them (docs/SPEC.md "The gather as a
// rasterizer").
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"
#include "gridrt/common/shared/raster.h"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };

shared uint s_depth;  // the tile's depth bound, read once per tile
shared uint s_max;    // the largest t bits of the tile's keys after this triangle's atomics

void main() {
  const CameraParams c = fp.camera;
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 1u, 0u);
  if (item >= tile_header.tiles) return;
  // The triangle whose items hold this one: the last whose first item is <= item
  uint lo = 0u;
  uint hi = tile_header.triangles;
  while (hi - lo > 1u) {
    const uint mid = (lo + hi) / 2u;
    if (tile_tris[mid].first <= item) lo = mid;
    else hi = mid;
  }
  const GatherRasterTriangle g = tile_tris[lo];
  const uint x0 = g.box_lo & 0xFFFFu, y0 = g.box_lo >> 16u, x1 = g.box_hi & 0xFFFFu, y1 = g.box_hi >> 16u;
  const uint across = x1 / kGatherBinSize - x0 / kGatherBinSize + 1u;
  const uint b = item - g.first;
  const uint bx = x0 / kGatherBinSize + b % across, by = y0 / kGatherBinSize + b / across;
  // Bin: its pixels within the box
  const uint rx0 = max(x0, bx * kGatherBinSize), ry0 = max(y0, by * kGatherBinSize);
  const uint rx1 = min(x1, bx * kGatherBinSize + kGatherBinSize - 1u), ry1 = min(y1, by * kGatherBinSize + kGatherBinSize - 1u);
  if (!raster_rect_may_hit(g.edge0, g.edge1, g.edge2, rx0, ry0, rx1, ry1)) return;
  const uint k = g.index;
  const GridTriangle tri = triangles[k];
  const uint tiles_x = (c.width + kGatherTileSize - 1u) / kGatherTileSize;
  const uint lid = gl_LocalInvocationIndex;
  for (uint ty = ry0 / kGatherTileSize; ty <= ry1 / kGatherTileSize; ++ty)
    for (uint tx = rx0 / kGatherTileSize; tx <= rx1 / kGatherTileSize; ++tx) {
      // Tile: its pixels within the bin's rectangle (the same for every invocation)
      const uint sx0 = tx * kGatherTileSize, sy0 = ty * kGatherTileSize;
      const uint sx1 = min(sx0 + kGatherTileSize - 1u, c.width - 1u), sy1 = min(sy0 + kGatherTileSize - 1u, c.height - 1u);
      const uint qx0 = max(rx0, sx0), qy0 = max(ry0, sy0), qx1 = min(rx1, sx1), qy1 = min(ry1, sy1);
      if (!raster_rect_may_hit(g.edge0, g.edge1, g.edge2, qx0, qy0, qx1, qy1)) continue;
      const uint tile = ty * tiles_x + tx;
      if (lid == 0u) {
        s_depth = tile_depth[tile];
        s_max = 0u;
      }
      barrier();
      const uint depth = s_depth;
      if (floatBitsToUint(raster_tile_t_lo_fast(g.depth, g.t_lo, qx0, qy0, qx1, qy1)) <= depth) {
        // The whole tile (within the screen) is in the box: its depth bound may be lowered
        const bool whole = qx0 == sx0 && qy0 == sy0 && qx1 == sx1 && qy1 == sy1;
        const uvec2 px = uvec2(sx0, sy0) + gl_LocalInvocationID.xy;
        uint v = 0xFFFFFFFFu;  // the pixel's t bits after the atomic: unknown
        if (px.x > sx1 || px.y > sy1) {
          v = 0u;  // off the screen: no key
        } else if (px.x >= qx0 && px.y >= qy0 && px.x <= qx1 && px.y <= qy1 &&
                   raster_pixel_may_hit(g.edge0, g.edge1, g.edge2, px.x, px.y)) {
          uvec2 key;
          if (gather_key_along(g.ref, k, tri, pixel_dirs[px.y * c.width + px.x].xyz, pixel_dirs[px.y * c.width + px.x].w, key)) {
            const uint64_t old = atomicMin(gather_keys64[px.y * c.width + px.x], packUint2x32(key));
            v = min(unpackUint2x32(old).y, key.y);
          }
        }
        if (whole) {
          const uint m = subgroupMax(v);
          if (subgroupElect()) atomicMax(s_max, m);
        }
        barrier();
        if (whole && lid == 0u && s_max < depth) atomicMin(tile_depth[tile], s_max);
      }
      barrier();  // s_depth and s_max are read before the next tile rewrites them
    }
}
