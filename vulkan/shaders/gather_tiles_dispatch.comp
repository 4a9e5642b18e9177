#version 460
// gather_tiles_dispatch.comp: the dispatch step of the compute gather's item passes, one invocation:
// the work items and large triangles gather_bin.comp appended (GatherTileHeader); the item pass
// (gather_raster.comp, or gather_tiles.comp) one workgroup per item, the tile lists' count and
// scatter (gather_pairs.comp) 64 items per workgroup (GatherFineHeader); the append counter again
// at 0.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/worklist.h"
#include "gridrt/vulkan/shaders/frame_input.h"

layout(local_size_x = 1) in;
layout(std430, binding = 0) buffer TileList { GatherTileHeader header; };
layout(std430, binding = 1) buffer TileBins { GatherFineHeader fine_header; };
layout(push_constant) uniform Push { uint max_groups_x; } pc;

void main() {
  const uvec3 groups = work_list_groups(header.counter_lo, 1u, pc.max_groups_x);
  header.groups_x = groups.x;
  header.groups_y = groups.y;
  header.groups_z = groups.z;
  header.tiles = header.counter_lo;
  header.triangles = header.counter_hi;
  const uvec3 items = work_list_groups(header.counter_lo, 64u, pc.max_groups_x);
  fine_header.items_x = items.x;
  fine_header.items_y = items.y;
  fine_header.items_z = items.z;
  header.counter_lo = 0u;
  header.counter_hi = 0u;
}
