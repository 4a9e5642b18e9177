// worklist.h: a list that one pass appends to and a later pass works through, dispatched
// indirectly over exactly the items appended (docs/SPEC.md, "Scene update"; docs/VULKAN.md). One
// storage buffer: this header, then the items (uint), then whatever the owner keeps beside them.
//   append     i = atomicAdd(header.appended, 1); items[i] = item
//   dispatch   one invocation (work_list_dispatch.comp, or the appending pass's last workgroup to
//              finish, counted in `done`): size = appended, appended = 0, and the indirect
//              dispatch's group counts for `size` items (dispatched += size)
//   work       invocation k < size takes items[k] (work_list_index)
// The grid's dirty cells (vulkan/grid.cpp; the reference emulates the same buffer) and the
// frame's compacted bounce rays (vulkan/frame.cpp) use it.
#ifndef GRIDRT_SHARED_WORKLIST_H
#define GRIDRT_SHARED_WORKLIST_H

#include "compat.h"

SH_BEGIN

struct WorkListHeader {
  uint groups_x;   // VkDispatchIndirectCommand of the pass over the list
  uint groups_y;
  uint groups_z;
  uint size;       // items the pass over the list works on (written by the dispatch pass)
  uint appended;   // items appended since the last dispatch pass
  uint dispatched; // items of every dispatch pass so far (statistics)
  uint done;       // workgroups of the appending pass finished (where its last one dispatches; back to 0 then)
  uint pad1;
};

SH_CONST uint kWorkListHeaderWords = 8u;  // the items start at this word of the buffer
SH_CONST uint kWorkListSizeWord = 3u;     // WorkListHeader::size as a word of the buffer
SH_CONST uint kWorkListAppendedWord = 4u; // WorkListHeader::appended as a word of the buffer

// Push constants of the dispatch step (work_list_dispatch.comp).
struct WorkListDispatchPush {
  uint group_size;    // items per workgroup of the pass over the list
  uint max_groups_x;  // maxComputeWorkGroupCount[0]
  uint capacity;      // items the list holds (an append past it was not stored)
};

// The dispatch pass: group counts covering `size` items in workgroups of `group_size`, as a 2D
// grid when one row would exceed `max_groups_x` (maxComputeWorkGroupCount[0]).
SH_INLINE uvec3 work_list_groups(uint size, uint group_size, uint max_groups_x) {
  const uint groups = sh_udiv(size, group_size) + (size % group_size != 0u ? 1u : 0u);
  if (groups <= max_groups_x) return uvec3(groups, 1u, 1u);
  return uvec3(max_groups_x, sh_udiv(groups, max_groups_x) + (groups % max_groups_x != 0u ? 1u : 0u), 1u);
}

// The item an invocation of the pass over the list takes: workgroup (x, y) of a grid
// `groups_x` wide, local invocation `local` of `group_size`.
SH_INLINE uint work_list_index(uvec3 workgroup, uint groups_x, uint group_size, uint local) {
  return (workgroup.y * groups_x + workgroup.x) * group_size + local;
}

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::WorkListHeader) == 32, "std430 layout of WorkListHeader");
static_assert(sizeof(gridrt::shared::WorkListDispatchPush) == 12, "layout of WorkListDispatchPush");
#endif

#endif
