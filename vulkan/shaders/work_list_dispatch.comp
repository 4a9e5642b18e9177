#version 460
// work_list_dispatch.comp: the dispatch step of a work list (common/shared/worklist.h), one
// invocation: the items appended become the items of the next indirect dispatch, the append
// counter starts again at 0.
#extension GL_GOOGLE_include_directive : require
#include "gridrt/common/shared/worklist.h"

layout(local_size_x = 1) in;
layout(std430, binding = 0) buffer List { WorkListHeader header; };
layout(push_constant) uniform Push { WorkListDispatchPush pc; };

void main() {
  const uint size = min(header.appended, pc.capacity);
  const uvec3 groups = work_list_groups(size, pc.group_size, pc.max_groups_x);
  header.groups_x = groups.x;
  header.groups_y = groups.y;
  header.groups_z = groups.z;
  header.size = size;
  header.appended = 0u;
  header.dispatched += size;
}
