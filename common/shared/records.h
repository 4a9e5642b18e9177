// records.h: rays and hit records as both sides lay them out (std430 on the GPU).
#ifndef GRIDRT_SHARED_RECORDS_H
#define GRIDRT_SHARED_RECORDS_H

#include "compat.h"

SH_BEGIN

SH_CONST uint kNoInstance = 0xFFFFFFFFu;  // HitRecord::instance of a miss
SH_CONST uint kNoRef = 0xFFFFFFFFu;       // RayRecord::launch_ref when the ray has no surface

// Hit flags
SH_CONST uint kHitGapFill = 1u;      // a gap-fill voxel, not a triangle (paper, 2.3)
SH_CONST uint kHitBackFace = 2u;     // the triangle's geometric normal faces along the ray
SH_CONST uint kHitRejected = 4u;     // the ray was rejected (NaN/inf origin or direction)

struct RayRecord {
  vec3 org;            // world-space origin
  float tmin;          // hits need t > tmin (parametric, in units of |dir|)
  vec3 dir;            // world-space direction (any length > 0)
  float tmax;          // hits need t < tmax
  vec3 launch_normal;  // geometric normal of the launch surface (0 if none), for gap-fill
  uint launch_ref;     // (instance << 16 | triangle) the ray leaves, kNoRef if none
};

struct HitRecord {
  float t;         // parametric distance along RayRecord::dir
  uint instance;   // kNoInstance on a miss
  uint triangle;   // triangle index within the instance's mesh
  float u;         // barycentric weight of vertex 1
  float v;         // barycentric weight of vertex 2
  uint flags;      // kHit* bits
  uint cells;      // cells visited (statistics)
  uint tests;      // triangle tests made (statistics)
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::RayRecord) == 48, "std430 layout of RayRecord");
static_assert(sizeof(gridrt::shared::HitRecord) == 32, "std430 layout of HitRecord");
#endif

#endif
