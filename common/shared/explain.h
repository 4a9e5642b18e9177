// explain.h: the events a traced ray leaves when it is explained, as fixed-size records that the
// reference (reference/trace.cpp) and the Vulkan trace shader (into a storage buffer) write alike,
// in the same order. Field meanings per kind are listed at each kind; unused fields are 0.
#ifndef GRIDRT_SHARED_EXPLAIN_H
#define GRIDRT_SHARED_EXPLAIN_H

#include "compat.h"

SH_BEGIN

// Event kinds
SH_CONST uint kEvRay = 1u;        // f0 = (org, tmin), f1 = (dir, tmax), ref = launch_ref
SH_CONST uint kEvRejected = 2u;   // the ray has NaN/inf values or a zero direction
SH_CONST uint kEvSetup = 3u;      // code = traversal, f0 = (seg_t, t_start, t_end, t_lo),
                                  // f1 = (launch normal xyz, t_base: the ray's origin moved
                                  // along it by t_base, docs/SPEC.md "Far origins"); slot = 1
                                  // if the ray meets the grid
SH_CONST uint kEvCell = 4u;       // a cell is visited: step, cell; paper: code = further
                                  // segments merged into this visit, f0 = (midpoint of the
                                  // visit's segments xyz, its t), f1 = (segment begin, end,
                                  // elongated begin, elongated end, clipped to (t_lo, tmax));
                                  // exact: f0 = (entry point xyz, t entry), f1 = (t entry, t exit,
                                  // t_lo, t_hi)
SH_CONST uint kEvCellSkipped = 5u;  // paper: same cell as the previous step; f0 = (sample, t)
SH_CONST uint kEvSlot = 6u;       // slot read: cell, slot, ref (kBlank ends the cell)
SH_CONST uint kEvTest = 7u;       // triangle test: ref, code = kTest*, f0 = (det, u*|det|,
                                  // v*|det|, t*|det|), f1 = (t_lo*|det|, t_hi*|det|,
                                  // best*|det|, t if accepted)
SH_CONST uint kEvAlpha = 8u;      // alpha keying: ref, code = 1 kept / 0 cut, f0 = (u, v, s, t)
                                  // barycentrics and uv, slot = alpha, cell = (x, y, material)
SH_CONST uint kEvCandidate = 9u;  // a new best hit: ref, f0 = (t, u, v, previous best t)
SH_CONST uint kEvStatus = 10u;    // status texel read: cell, code = status bits
SH_CONST uint kEvGapFill = 11u;   // gap-fill decision: code = kGap*, ref = last ref read,
                                  // f0 = (lhs, rhs, t of the sample, 0)
SH_CONST uint kEvReport = 12u;    // the hit: ref, code = hit flags, f0 = (t, u, v, 0), step
SH_CONST uint kEvMiss = 13u;      // the miss: code = kMiss*, step
SH_CONST uint kEvSpillScan = 14u; // a saturated cell's spill lists are walked (kGridSpill): cell,
                                  // code = entries the list stores, slot = references appended
                                  // (more than stored: the list overflowed, some were lost)
SH_CONST uint kEvSpilled = 15u;   // a spilled reference of the cell, in ascending reference order:
                                  // ref, cell, slot = its place among the cell's spilled
                                  // references; its kEvTest follows
SH_CONST uint kEvSkip = 16u;      // exact, kGridSkipEmpty: an empty cell, its box of empty cells
                                  // passed at once: cell, code = the cell's distance d (the box
                                  // spans d - 1 cells each way), slot = the dynamic boxes the
                                  // walk can reach (bit b: box b; skip_box_reached), f0 = (entry
                                  // point xyz, t entry), f1 = (t entry, t exit of the box, t_lo, t_hi)
SH_CONST uint kEvCovered = 17u;   // exact, kGridSkipCovered: the cell's static run is not read, every
                                  // reference of it lies in the run of the neighbour the walk entered
                                  // it from, tested there: cell, code = the face entered through
                                  // (bit 2 axis + side of the cover bits), slot = the run's length

// kEvGapFill codes
SH_CONST uint kGapApplied = 0u;      // saturated, no hit reported in the cell, left the surface
SH_CONST uint kGapTooClose = 1u;     // saturated, but the segment has not left the launch surface
SH_CONST uint kGapOutsideRay = 2u;   // saturated, but the sample's t is outside (t_lo, tmax)

// kEvMiss codes
SH_CONST uint kMissOutsideGrid = 0u;  // the ray does not meet the grid box within [tmin, tmax]
SH_CONST uint kMissLeftGrid = 1u;     // the traversal left the grid
SH_CONST uint kMissTmax = 2u;         // the traversal passed tmax
SH_CONST uint kMissStepLimit = 3u;    // GridParams::max_segments steps

struct ExplainEvent {
  uint kind;   // kEv*
  uint code;   // kind-specific code (kTest*, kGap*, kMiss*, status bits, hit flags)
  uint ref;    // reference (instance << 16 | triangle), kBlank if none
  uint step;   // segment index (paper) or DDA step
  uvec3 cell;  // cell coordinates
  uint slot;   // slot index
  vec4 f0;     // kind-specific floats
  vec4 f1;     // kind-specific floats
};

SH_END

#ifdef __cplusplus
static_assert(sizeof(gridrt::shared::ExplainEvent) == 64, "std430 layout of ExplainEvent");
#endif

#endif
