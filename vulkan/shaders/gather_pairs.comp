#version 460
// gather_pairs.comp: the compute gather's tile lists (gather_visibility.glsl), one invocation per
// work item (a large triangle's 32x32-pixel screen bin), dispatched indirectly; with buckets once,
// else twice with a scan between. The item's triangle by binary search over the triangles' first items (gather_bin.comp
// listed them), the bin's pixels within the triangle's box rejected as a whole when an edge
// function is negative on all of them (raster_rect_may_hit), then per 8x8 screen tile of the bin
// the same rejection; each tile left is a (tile, triangle) pair:
//   buckets  (pc.scatter 2) the tile's count += 1; the old count is the pair's place in the
//            tile's bucket of pc.capacity words; a pair past it goes to the list of pairs past
//            their buckets (fine_header.pairs counts them; gather_past.comp rasterizes them), and
//            past that list's pc.past_capacity it is rasterized here, over its rectangle of the
//            tile (gather_raster.comp's pixel step: the key by a 64-bit atomic min, before the
//            fine pass reads the keys). No scan, no item pass
//   count    (pc.scatter 0) the tile's count += 1
//   scatter  (pc.scatter 1, after gather_scan.comp wrote the starts) the tile's count -= 1, the
//            triangle's list index at the tile's start + the new count (the list filled from its
//            end); nothing when the pairs overflowed
// The pairs' order within a tile follows the atomics; the fine pass takes a minimum over them.
#extension GL_GOOGLE_include_directive : require
#extension GL_EXT_shader_atomic_int64 : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 64) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(push_constant) uniform Push { GatherFinePush pc; };

// A pair past its tile's bucket: the triangle over the pixels of rectangle (x0, y0)-(x1, y1)
void raster_pair_here(GatherRasterTriangle g, uint x0, uint y0, uint x1, uint y1) {
  const uint width = fp.camera.width;
  const GridTriangle tri = triangles[g.index];
  for (uint y = y0; y <= y1; ++y)
    for (uint x = x0; x <= x1; ++x) {
      if (!raster_pixel_may_hit(g.edge0, g.edge1, g.edge2, x, y)) continue;
      const vec4 dir = pixel_dirs[y * width + x];
      uvec2 key;
      if (gather_key_along(g.ref, g.index, tri, dir.xyz, dir.w, key)) atomicMin(gather_keys64[y * width + x], packUint2x32(key));
    }
}

void main() {
  const CameraParams c = fp.camera;
  const uint item = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 64u, gl_LocalInvocationID.x);
  if (item >= tile_header.tiles) return;
  if (pc.scatter == 1u && fine_header.overflow != 0u) return;
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
  const uint tiles_x = (c.width + kGatherTileSize - 1u) / kGatherTileSize;
  for (uint ty = ry0 / kGatherTileSize; ty <= ry1 / kGatherTileSize; ++ty)
    for (uint tx = rx0 / kGatherTileSize; tx <= rx1 / kGatherTileSize; ++tx) {
      // Tile: its pixels within the bin's rectangle
      const uint qx0 = max(rx0, tx * kGatherTileSize), qy0 = max(ry0, ty * kGatherTileSize);
      const uint qx1 = min(rx1, tx * kGatherTileSize + kGatherTileSize - 1u);
      const uint qy1 = min(ry1, ty * kGatherTileSize + kGatherTileSize - 1u);
      if (!raster_rect_may_hit(g.edge0, g.edge1, g.edge2, qx0, qy0, qx1, qy1)) continue;
      const uint tile = ty * tiles_x + tx;
      if (pc.scatter == 2u) {
        const uint at = atomicAdd(tile_words[tile], 1u);
        if (at < pc.capacity) {
          tile_words[pc.tiles + tile * pc.capacity + at] = lo;
        } else {
          // Past the bucket: listed for the past pass (gather_past.comp), or past that list's
          // room too, rasterized here
          const uint o = atomicAdd(fine_header.pairs, 1u);
          const uint list = pc.tiles + pc.tiles * pc.capacity;
          if (o < pc.past_capacity) {
            tile_words[list + 2u * o] = tile;
            tile_words[list + 2u * o + 1u] = lo;
          } else {
            raster_pair_here(g, qx0, qy0, qx1, qy1);
          }
        }
      } else if (pc.scatter == 0u) {
        atomicAdd(tile_words[tile], 1u);
      } else {
        const uint at = tile_words[pc.tiles + tile] + atomicAdd(tile_words[tile], 0xFFFFFFFFu) - 1u;
        if (at < pc.capacity) tile_words[2u * pc.tiles + at] = lo;  // always, unless overflowed
      }
    }
}
