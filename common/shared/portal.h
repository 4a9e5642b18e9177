// portal.h: the per-ray math of the portal ("div") tracer ("A Novel Raytracing Algorithm for GPU", docs/PORTAL.md), written
// once for the CPU reference and the Vulkan port. Texture fetches are not here: each side fetches
// the div info, the atlas texel and the start map its own way and hands the values to these
// functions.
//
// Space: voxel space, voxel (i, j, k) is the unit cube [i, i+1] x [j, j+1] x [k, k+1]. A ray is
// org + t * dir in voxel space (t is the caller's parameter: world -> voxel space maps org and dir
// by one affine map, so t does not change).
//
// Decisions (which face a ray leaves a box by, which voxel of that face it crosses, whether a wall
// lies before tmax) use only + - * and comparisons. Every plane crossing is compared through
// portal_first(): plane A (axis a, numerator na = signed distance ahead, ad_a = |dir[a]|) is
// crossed first iff na * ad_b < nb * ad_a, ties to the lower axis. The voxel DDA uses the same
// predicate, which is what keeps the two tracers' discrete answers identical.
#ifndef GRIDRT_SHARED_PORTAL_H
#define GRIDRT_SHARED_PORTAL_H

#include "compat.h"
#include "rounding.h"

SH_BEGIN

#ifdef __cplusplus
using glm::abs;
using glm::floor;
using glm::max;
using glm::min;
#endif

// Faces of a voxel or div, by outward normal: 2 * axis + (1 if positive).
SH_CONST uint kPortalFaceNegX = 0u;
SH_CONST uint kPortalFacePosX = 1u;
SH_CONST uint kPortalFaceNegY = 2u;
SH_CONST uint kPortalFacePosY = 3u;
SH_CONST uint kPortalFaceNegZ = 4u;
SH_CONST uint kPortalFacePosZ = 5u;
SH_CONST uint kPortalFaceInside = 6u;  // the ray started inside a solid voxel

// Atlas texels (16 bits): a neighbour div, a wall of a material, or outside the world.
SH_CONST uint kPortalWallBit = 0x8000u;     // texel >= this: a wall, material = texel - kPortalWallBit
SH_CONST uint kPortalOutside = 0xFFFFu;     // the world's boundary: the ray leaves the world (a miss)
SH_CONST uint kPortalMaxDivs = 0x8000u;     // div indices 0 .. 0x7FFF
SH_CONST uint kPortalMaxMaterial = 0x7FFEu; // wall materials 0 .. 0x7FFE
SH_CONST uint kPortalExteriorDiv = 0u;      // div 0 is the exterior div: the world box, surfaced outside

// Div types (the type byte of div info texel 7).
SH_CONST uint kPortalDivAir = 0u;       // interior div of empty space
SH_CONST uint kPortalDivExterior = 1u;  // the world box seen from outside
SH_CONST uint kPortalDivGlass = 2u;     // interior div of a glass medium (material in texel 6 .w)

// Hit records of the portal tracer and the voxel DDA (common/shared/records.h):
//   t         parametric distance to the wall face (division once, at the end)
//   instance  wall material (kNoInstance on a miss: the ray left the world or reached tmax)
//   triangle  (voxel << 3) | face, voxel = x + X * (y + Y * z) of the solid voxel hit, face =
//             its face the ray hit (kPortalFace*), kPortalFaceInside if the ray started inside it
//   u, v      sub-texel coordinates on that face, in [0, 1]: the lower and the higher of the two
//             tangent axes (x,y for z faces, x,z for y faces, y,z for x faces)
//   cells     divs (portal) or voxels (DDA) visited;  tests: atlas texels read (portal) or
//             voxels tested (DDA)
SH_CONST uint kPortalFaceBits = 3u;

// The voxel-space direction the portal tracer steps with: a subnormal component is taken as +0
// (normal_or_zero), as the grid's traced_direction takes it. Left subnormal it was a hit at
// t = inf or below 0 with NaN u, v, and the CPU's and a device's records differed where the device
// flushes it (an outside sweep).
SH_INLINE vec3 portal_direction(SH_IN(vec3) d) { return normal_or_zero3(d); }

// Signed distance ahead of `o` to the plane `p` along an axis with direction component `d`
// (positive: the plane is ahead). Its ratio to |d| is the parametric distance.
SH_INLINE float portal_ahead(float p, float o, float d) {
  SH_PRECISE float n = (d >= 0.0f) ? (p - o) : (o - p);
  return n;
}

// Whether plane A (axis a, ahead na, |d_a| = ada) is crossed before plane B (axis b, nb, adb):
// na / ada < nb / adb without dividing; equal: the lower axis first.
SH_INLINE bool portal_first(uint a, float na, float ada, uint b, float nb, float adb) {
  SH_PRECISE float lhs = na * adb;
  SH_PRECISE float rhs = nb * ada;
  return lhs < rhs || (lhs == rhs && a < b);
}

// The axis of the face a ray leaves the box [lo, hi] by (only the face each direction component
// points to: three slab tests), or 3 if dir is zero. `num` gets that plane's distance ahead.
SH_INLINE uint portal_exit_axis(SH_IN(vec3) lo, SH_IN(vec3) hi, SH_IN(vec3) org, SH_IN(vec3) dir,
                               SH_OUT(float) num) {
  uint best = 3u;
  float bn = 0.0f;
  float bd = 0.0f;
  for (uint a = 0u; a < 3u; a++) {
    if (dir[a] == 0.0f) continue;
    float n = portal_ahead(dir[a] > 0.0f ? hi[a] : lo[a], org[a], dir[a]);
    float ad = abs(dir[a]);
    if (best == 3u || portal_first(a, n, ad, best, bn, bd)) {
      best = a;
      bn = n;
      bd = ad;
    }
  }
  num = bn;
  return best;
}

// The axis of the face a ray enters the box [lo, hi] by from outside (the latest of the near
// planes), or 3 if it misses the box or dir is zero. `num` gets that plane's distance ahead.
// Missing: some far plane comes before the entry plane, or the box lies behind (far plane behind).
SH_INLINE uint portal_entry_axis(SH_IN(vec3) lo, SH_IN(vec3) hi, SH_IN(vec3) org, SH_IN(vec3) dir,
                                SH_OUT(float) num) {
  uint best = 3u;
  float bn = 0.0f;
  float bd = 0.0f;
  for (uint a = 0u; a < 3u; a++) {
    if (dir[a] == 0.0f) {
      // In the box's slab of this axis: a point on its upper plane belongs to the voxel above (the
      // start voxel's rule: floor for dir >= 0), outside the box
      if (org[a] < lo[a] || org[a] >= hi[a]) { num = 0.0f; return 3u; }
      continue;
    }
    float n = portal_ahead(dir[a] > 0.0f ? lo[a] : hi[a], org[a], dir[a]);
    float ad = abs(dir[a]);
    // The latest near plane; ties to the lower axis.
    if (best == 3u || portal_first(best, bn, bd, a, n, ad)) {
      best = a;
      bn = n;
      bd = ad;
    }
  }
  if (best == 3u) { num = 0.0f; return 3u; }
  // Every far plane must come after the entry plane.
  for (uint a = 0u; a < 3u; a++) {
    if (dir[a] == 0.0f || a == best) continue;
    float fn = portal_ahead(dir[a] > 0.0f ? hi[a] : lo[a], org[a], dir[a]);
    if (portal_first(a, fn, abs(dir[a]), best, bn, bd)) { num = 0.0f; return 3u; }
  }
  if (bn < 0.0f) { num = 0.0f; return 3u; }  // the whole box lies behind the origin
  num = bn;
  return best;
}

// The voxel index along axis b (b != a) at the moment the ray crosses plane A (axis a, ahead na,
// |d_a| = ada), within the voxel range [lo, hi) of a box: the voxel the DDA would be in, found by
// binary search over the planes of axis b with the same predicate (no division).
SH_INLINE uint portal_cross_index(uint a, float na, float ada, uint b, float ob, float db, uint lo, uint hi) {
  if (db == 0.0f) {
    float f = floor(ob);
    float c = min(max(f, float(lo)), float(hi - 1u));
    return uint(c);
  }
  float adb = abs(db);
  if (db > 0.0f) {
    // Largest plane q in (lo, hi) crossed before A: the voxel is q (else lo).
    uint l = lo;          // invariant: plane l counts as crossed (or l == lo)
    uint h = hi;          // invariant: plane h is not crossed before A (or h == hi)
    while (h - l > 1u) {
      uint m = (l + h) / 2u;
      if (portal_first(b, portal_ahead(float(m), ob, db), adb, a, na, ada)) l = m; else h = m;
    }
    return l;
  }
  // db < 0: smallest plane q in (lo, hi) crossed before A: the voxel is q - 1 (else hi - 1).
  uint l = lo;            // invariant: plane l not crossed before A (or l == lo)
  uint h = hi;            // invariant: plane h crossed (or h == hi)
  while (h - l > 1u) {
    uint m = (l + h) / 2u;
    if (portal_first(b, portal_ahead(float(m), ob, db), adb, a, na, ada)) h = m; else l = m;
  }
  return h - 1u;
}

// The renderer's bound on one pixel's loop iterations (its primary ray's segments between glass
// interfaces and its two shadow rays): a straight ray visits a box once, so a segment takes at most
// about the divs' count, 4x that plus a walk across the fine voxels is far more than any ray needs.
// Past it the pixel's rays are cycling (an origin ~1e7 voxels away rounds its crossings
// inconsistently, and three divs handed a ray round at one t, forever: an outside sweep's hang)
// and the pixel ends as background, counted (RenderStats::cut_pixels). `fine_dims`: the world's
// voxels (an instanced world's fine ones). Clamped so that the product fits 32 bits.
SH_INLINE uint portal_pixel_iteration_limit(uint div_count, SH_IN(uvec3) fine_dims, uint max_interfaces) {
  const uint per_ray = 4u * min(div_count, 65536u) + 16u +
                       4u * (min(fine_dims.x, 65536u) + min(fine_dims.y, 65536u) + min(fine_dims.z, 65536u));
  return per_ray * (min(max_interfaces, 1024u) + 3u);
}

// The two tangent axes of axis a, lower first.
SH_INLINE uint portal_tangent0(uint a) { return a == 0u ? 1u : 0u; }
SH_INLINE uint portal_tangent1(uint a) { return a == 2u ? 1u : 2u; }

// Sub-texel coordinate on a face: the crossing coordinate along axis b minus its voxel index,
// clamped to [0, 1] (a reported value: one division, t = na / ada, here).
SH_INLINE float portal_subtexel(float na, float ada, float ob, float db, uint index) {
  SH_PRECISE float t = sh_div(na, ada);
  SH_PRECISE float c = ob + t * db;
  SH_PRECISE float f = c - float(index);
  return min(max(f, 0.0f), 1.0f);
}

// Whether a plane crossing at distance ahead `na` (|d_a| = ada) lies before tmax: na < tmax * ada.
SH_INLINE bool portal_before_tmax(float na, float ada, float tmax) {
  SH_PRECISE float lim = tmax * ada;
  return na < lim;
}

// Face of the solid voxel a ray hits when it crosses a plane of axis a moving along dir[a].
SH_INLINE uint portal_hit_face(uint a, float da) { return 2u * a + (da > 0.0f ? 0u : 1u); }

// Decode an atlas texel.
SH_INLINE bool portal_texel_is_wall(uint texel) { return texel >= kPortalWallBit; }


// ---- Mip-mapped space (docs/PORTAL.md, "Mip-mapped space") ----
// Level l is a voxelization of the same space at 2^l fine voxels per coarse voxel. Its divs and
// its start map live in the same textures as level 0's; the div's level is the high nibble of
// its type byte. A ray in a level-l div is traced in level-l voxel space: org and dir times 2^-l,
// exact in floating point, so every plane predicate there is the level-0 predicate on the same
// plane and t is unchanged.
SH_CONST uint kPortalMaxLevels = 4u;     // levels 0 .. 3
SH_CONST uint kPortalTypeMask = 15u;     // the div type in the low nibble of the type byte
SH_CONST uint kPortalLevelShift = 4u;    // the div's level in the high nibble

// 2^-level, by halving (exact).
SH_INLINE float portal_level_scale(uint level) {
  float s = 1.0f;
  for (uint k = 0u; k < level; k++) s = s * 0.5f;
  return s;
}

// Voxels per axis of level `level` of a world of `dims` fine voxels: ceil(dims / 2^level).
SH_INLINE uvec3 portal_level_dims(uvec3 dims, uint level) {
  const uint f = (1u << level) - 1u;
  return uvec3((dims.x + f) >> level, (dims.y + f) >> level, (dims.z + f) >> level);
}

// The level a ray should be in where it crosses a plane at distance ahead `num` (|d_a| = `ad`,
// in any level's space: the ratio is t) with `maxad` = max |dir| in level-0 voxel space: the
// Chebyshev distance from the origin in fine voxels is d = t * maxad, and the level is the
// largest l < levels with d >= distance * 2^l (0 when none). No division.
SH_INLINE uint portal_mip_level(float num, float ad, float maxad, float distance, uint levels) {
  uint l = 0u;
  SH_PRECISE float lhs = num * maxad;
  for (uint k = 1u; k < levels; k++) {
    SH_PRECISE float thr = distance * float(1u << k);  // exact: a power of two
    SH_PRECISE float rhs = thr * ad;
    if (lhs >= rhs) l = k;
  }
  return l;
}

// A ray in a level-`lc` div may move to a coarser level `l` (> lc) only at a plane that is also a
// plane of level l: plane index `plane` (level-lc units) a multiple of 2^(l - lc). The coarsest
// such level not above `target`, or lc when there is none.
SH_INLINE uint portal_mip_aligned_level(uint plane, uint lc, uint target) {
  uint l = target;
  while (l > lc && (plane & ((1u << (l - lc)) - 1u)) != 0u) l = l - 1u;
  return l;
}

// ---- Instanced subspaces (docs/PORTAL.md, "Instanced subspaces") ----
// Tiles of 2^scale_log2 fine voxels per axis; the top level is traced in tile space (the ray times
// 2^-scale_log2, exact, as a mip level), block divs in fine space offset by their tile's corner.

// Whether wall material m is an instance (of block m - base).
SH_INLINE bool portal_is_instance(uint m, uint scale_log2, uint base, uint blocks) {
  return scale_log2 != 0u && m >= base && m < base + blocks;
}

// The fine voxel a ray meets entering tile `tile` across the plane of axis a (num, ad in fine
// space): along a the tile's first fine layer in the direction of travel, along the tangents the
// voxel the DDA would be in at the crossing (the same binary search as every crossing).
SH_INLINE ivec3 portal_instance_fine_voxel(uint a, float num, float ad, SH_IN(vec3) org, SH_IN(vec3) dir, ivec3 tile,
                                           uint scale_log2) {
  const int S = 1 << scale_log2;
  ivec3 f = ivec3(0);
  f[a] = dir[a] > 0.0f ? tile[a] * S : tile[a] * S + S - 1;
  const uint b0 = portal_tangent0(a);
  const uint b1 = portal_tangent1(a);
  f[b0] = int(portal_cross_index(a, num, ad, b0, org[b0], dir[b0], uint(tile[b0] * S), uint(tile[b0] * S + S)));
  f[b1] = int(portal_cross_index(a, num, ad, b1, org[b1], dir[b1], uint(tile[b1] * S), uint(tile[b1] * S + S)));
  return f;
}

// The atlas texel index (row-major) of fine voxel `fine` in the start map of `block` at `tile`.
SH_INLINE uint portal_block_start_index(uint block_start, uint block, uint scale_log2, ivec3 tile, ivec3 fine) {
  const uint S = 1u << scale_log2;
  const uvec3 l = uvec3(fine - tile * int(S));
  return block_start + block * S * S * S + l.x + S * (l.y + S * l.z);
}

SH_END

#endif
