#version 460
// gather_fine.comp: the compute gather's fine rasterizer (gather_visibility.glsl; Laine and Karras,
// "High-Performance Software Rasterization on GPUs"): one workgroup per 8x8-pixel screen tile,
// dispatched directly, one invocation per pixel, which keeps its key in a register: the key the
// bin pass left (small triangles' atomics), then the minimum over the tile's list of large
// triangles (gather_pairs.comp; no list when the pairs overflowed: the item pass, gather_raster.comp,
// left the large triangles' keys too; with buckets, the pairs pass rasterized the pairs past a
// tile's bucket); then the pixel's gather texel from it (gather_texel_at, at the key's t, as
// gather_resolve.comp would). The list is taken in batches of 64 pairs, each
// batch ranked by its triangles' lower t bounds over the tile, nearest first (the keys fall early
// and the depth test below culls more). Per triangle:
//   depth  the batch's rest is skipped by a whole subgroup when the triangle's lower t bound over
//          the tile (raster_tile_t_lo: its depth plane's at the tile, at least its t_lo) exceeds
//          the largest t of the subgroup's keys: it would have a larger t than every one, and so
//          would every triangle after it in the batch
//   pixel  within the triangle's screen box, the edge functions at the pixel (raster_pixel_may_hit),
//          then the gather's ray test along
//          the pixel's camera_direction (gather_dirs.comp); an accepted hit lowers the key
// The skips only leave out pairs the ray test rejects or that cannot win, and the minimum does not
// depend on the order: the keys end as gather_tiles.comp leaves them (docs/SPEC.md "The
// gather as a rasterizer").
#extension GL_GOOGLE_include_directive : require
#extension GL_KHR_shader_subgroup_arithmetic : require
#extension GL_KHR_shader_subgroup_ballot : require
#extension GL_EXT_shader_explicit_arithmetic_types_int64 : require
#include "gather_visibility.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = kFrameBindGatherKeys) buffer GatherKeys64 { uint64_t gather_keys64[]; };
layout(push_constant) uniform Push { GatherFinePush pc; };

// A tile's list is taken in batches of one pair per invocation
const uint kFineBatch = 64u;
shared uint s_bound[kFineBatch];   // the batch's depth bounds over the tile (t bits)
shared uint s_order[kFineBatch];   // the batch's triangles, nearest bound first
shared uint s_sorted[kFineBatch];  // their bounds, in that order

void main() {
  const CameraParams c = fp.camera;
  const uint tile = work_list_index(gl_WorkGroupID, gl_NumWorkGroups.x, 1u, 0u);
  if (tile >= pc.tiles) return;
  const uint tiles_x = (c.width + kGatherTileSize - 1u) / kGatherTileSize;
  const uvec2 px = uvec2(tile % tiles_x, tile / tiles_x) * kGatherTileSize + gl_LocalInvocationID.xy;
  const bool on = px.x < c.width && px.y < c.height;
  const uint p = px.y * c.width + px.x;
  // The tile's pixels within the screen (the depth bounds' rectangle)
  const uvec2 t0 = uvec2(tile % tiles_x, tile / tiles_x) * kGatherTileSize;
  const uvec2 t1 = min(t0 + (kGatherTileSize - 1u), uvec2(c.width, c.height) - 1u);
  uint64_t key = on ? gather_keys64[p] : 0ul;  // off the screen: t 0, never raises the depth
  const vec4 dir = on ? pixel_dirs[p] : vec4(0.0f);
  // The tile's list, as words of tile_words: with buckets (pc.scatter 2) its bucket up to its
  // count or capacity (the pairs past it were rasterized by the pairs pass); else from its start to
  // the next tile's (none when the pairs overflowed: the item pass, before, left the keys)
  uint begin = 0u, end = 0u;
  if (pc.scatter == 2u) {
    begin = pc.tiles + tile * pc.capacity;
    end = begin + min(tile_words[tile], pc.capacity);
  } else if (fine_header.overflow == 0u) {
    begin = 2u * pc.tiles + tile_words[pc.tiles + tile];
    end = 2u * pc.tiles + (tile + 1u < pc.tiles ? tile_words[pc.tiles + tile + 1u] : fine_header.pairs);
  }
  const uint lid = gl_LocalInvocationIndex;
  // The subgroup's largest t (keys only decrease: a bound of every later key), taken again only
  // after a triangle that lowered some lane's key: the same value as taking it before every
  // triangle, without the reduction where nothing changed
  uint depth = subgroupMax(unpackUint2x32(key).y);
  for (uint base = begin; base < end; base += kFineBatch) {
    // The batch's pairs in the order of their triangles' depth bounds (nearest first: the keys
    // fall early and the depth test culls more); the order changes no key, only the work
    const uint n = min(kFineBatch, end - base);
    uint index = 0u, bound = 0u;
    if (lid < n) {
      index = tile_words[base + lid];
      bound = floatBitsToUint(raster_tile_t_lo_fast(tile_tris[index].depth, tile_tris[index].t_lo, t0.x, t0.y, t1.x, t1.y));
      s_bound[lid] = bound;
    }
    barrier();
    if (lid < n) {
      uint rank = 0u;
      for (uint j = 0u; j < n; ++j) {
        const uint other = s_bound[j];
        rank += other < bound || (other == bound && j < lid) ? 1u : 0u;
      }
      s_order[rank] = index;
      s_sorted[rank] = bound;
    }
    barrier();
    for (uint j = 0u; j < n; ++j) {
      // Depth: a triangle whose bound exceeds the subgroup's largest t wins no pixel of the
      // subgroup, and neither does any after it in the batch (their bounds are no smaller, the
      // depth no larger): the subgroup leaves the batch together (it stays converged)
      if (s_sorted[j] > depth) break;
      const GatherRasterTriangle g = tile_tris[s_order[j]];
      bool lowered = false;
      // Within the triangle's screen box only, as every other pass: a triangle crossing the near
      // plane without bounds has edge functions that accept pixels outside its box, whose hits lie
      // nearer than the near plane (an outside sweep: 16 pixels of a listed tile took them)
      const bool in_box = px.x >= (g.box_lo & 0xFFFFu) && px.x <= (g.box_hi & 0xFFFFu) &&
                          px.y >= (g.box_lo >> 16u) && px.y <= (g.box_hi >> 16u);
      if (on && in_box && raster_pixel_may_hit(g.edge0, g.edge1, g.edge2, px.x, px.y)) {
        uvec2 k;
        if (gather_key_along(g.ref, g.index, triangles[g.index], dir.xyz, dir.w, k) && packUint2x32(k) < key) {
          key = packUint2x32(k);
          lowered = true;
        }
      }
      if (subgroupBallot(lowered) != uvec4(0u)) depth = subgroupMax(unpackUint2x32(key).y);
    }
    barrier();  // the batch's order is read before the next batch rewrites it
  }
  // The resolve, here: the gather texel along the same direction at the key's t (gather_resolve.comp
  // does not run with the rasterizer)
  if (on) {
    const uvec2 k = unpackUint2x32(key);
    visibility[p] = k.x;
    store_gather(p, gather_texel_at(k.x, dir.xyz, uintBitsToFloat(k.y)));
  }
}
