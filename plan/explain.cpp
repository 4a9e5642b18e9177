// explain.cpp: an ExplainRecord as text for someone learning the algorithm: every step of the
// traversal, every slot read, every triangle test with the values it decided on (decimal and hex
// bits) and why it was accepted or rejected.
#include <cstdio>
#include <sstream>

#include "common/shared/triangle.h"
#include "plan/records.h"

namespace gridrt::plan {

using namespace gridrt::shared;

namespace {

std::string num(float f) {
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g [%s]", double(f), hex(f).c_str());
  return buf;
}
std::string vec(glm::vec3 v) { return "(" + num(v.x) + ", " + num(v.y) + ", " + num(v.z) + ")"; }
std::string cellstr(glm::uvec3 c) {
  return "(" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}
std::string refstr(uint32_t ref) {
  if (ref == kBlank) return "blank";
  char buf[64];
  std::snprintf(buf, sizeof buf, "0x%08x (instance %u, triangle %u)", ref, ref_instance(ref), ref_triangle(ref));
  return buf;
}

const char* test_reason(uint32_t code) {
  switch (code) {
    case kTestAccepted: return "ACCEPTED: inside the triangle, within the segment, closest so far";
    case kTestParallel: return "rejected: det == 0, the ray is parallel to the triangle's plane";
    case kTestOutsideU: return "rejected: u*|det| < 0, outside edge v0-v2";
    case kTestOutsideV: return "rejected: v*|det| < 0, outside edge v0-v1";
    case kTestOutsideUV: return "rejected: (u+v)*|det| > |det|, outside edge v1-v2";
    case kTestBehind: return "rejected: t*|det| <= t_lo*|det|, before the (elongated) segment or tmin";
    case kTestBeyond: return "rejected: t*|det| >= t_hi*|det|, beyond the (elongated) segment or tmax";
    case kTestNotCloser: return "rejected: t*|det| > best_t*|det|, the best hit so far is closer";
    case kTestSelfHit: return "skipped: the ray's launch triangle (self-hit)";
    case kTestAlphaKeyed: return "rejected: alpha-keyed out by the mask";
    case kTestTieLost: return "rejected: t not smaller than the best hit's (ties keep the smaller reference)";
    default: return "?";
  }
}

const char* miss_reason(uint32_t code) {
  switch (code) {
    case kMissOutsideGrid: return "the ray does not meet the grid box within [tmin, tmax]";
    case kMissLeftGrid: return "the traversal left the grid";
    case kMissTmax: return "the traversal passed tmax";
    case kMissStepLimit: return "the step limit (GridParams::max_segments) was reached";
    default: return "?";
  }
}

}  // namespace

std::string to_text(const ExplainRecord& rec) {
  std::ostringstream os;
  const GridParams& g = rec.params;
  const bool exact = g.traversal == kTraversalExact;
  os << "grid: " << g.cells.x << "x" << g.cells.y << "x" << g.cells.z << " cells of " << num(g.cell_size)
     << ", origin " << vec(g.origin) << ", capacity " << g.capacity << ", traversal "
     << (exact ? "exact (3D DDA)" : "paper (cell-sized segments)") << ", insertion "
     << (g.insertion == kInsertSorted ? "sorted" : "first-empty")
     << ((g.flags & kGridSpill) ? ", spill list on" : "")
     << ((g.flags & kGridSkipEmpty) ? ", empty-space skipping on" : "")
     << ((g.flags & kGridGapFill) ? ", gap-fill on" : "") << "\n";
  for (const ExplainEvent& e : rec.events) {
    switch (e.kind) {
      case kEvRay:
        os << "ray: org " << vec(glm::vec3(e.f0)) << " dir " << vec(glm::vec3(e.f1)) << "\n     tmin "
           << num(e.f0.w) << " tmax " << num(e.f1.w) << ", launched from " << refstr(e.ref) << "\n";
        break;
      case kEvRejected:
        os << "REJECTED: NaN/inf in the ray or a zero direction; reported as a miss with kHitRejected\n";
        break;
      case kEvSetup:
        os << "setup: one cell edge = " << num(e.f0.x) << " in t; t_start " << num(e.f0.y) << ", t_end "
           << num(e.f0.z) << ", hits need t > " << num(e.f0.w) << "; launch normal " << vec(glm::vec3(e.f1))
           << (e.slot ? "" : "; the ray misses the grid box") << "\n";
        break;
      case kEvCell:
        if (exact)
          os << "step " << e.step << ": cell " << cellstr(e.cell) << ", t in [" << num(e.f1.x) << ", "
             << num(e.f1.y) << "]; triangles tested on (" << num(e.f1.z) << ", " << num(e.f1.w) << ")\n";
        else
          os << "segment " << e.step
             << (e.code ? " to " + std::to_string(e.step + e.code) + " (their samples share one cell: one visit)" : "")
             << ": [" << num(e.f1.x) << ", " << num(e.f1.y) << "], midpoint t "
             << num(e.f0.w) << " = " << vec(glm::vec3(e.f0)) << "\n  cell " << cellstr(e.cell)
             << "; triangles tested on the elongated segment (" << num(e.f1.z) << ", " << num(e.f1.w) << ")\n";
        break;
      case kEvSkip:
        os << "step " << e.step << ": cell " << cellstr(e.cell) << " is empty, its nearest reference " << e.code
           << " cells away: the box of " << (2 * e.code - 1) << " cells a side around it passed at once, t in ["
           << num(e.f1.x) << ", " << num(e.f1.y) << "]\n";
        break;
      case kEvCellSkipped:
        os << "segment " << e.step << ": sample at t " << num(e.f0.w) << " lies in cell " << cellstr(e.cell)
           << " again: visited, skipped\n";
        break;
      case kEvSlot:
        os << "  slot " << e.slot << ": " << refstr(e.ref) << (e.ref == kBlank ? " -> end of the cell's list" : "")
           << "\n";
        break;
      case kEvTest:
        os << "    test " << refstr(e.ref) << ": " << test_reason(e.code) << "\n";
        if (e.code != kTestSelfHit)
          os << "      det " << num(e.f0.x) << (e.f0.x < 0.0f ? " (back face)" : "") << ", u*|det| " << num(e.f0.y)
             << ", v*|det| " << num(e.f0.z) << "\n      t*|det| " << num(e.f0.w) << " against t_lo*|det| "
             << num(e.f1.x) << ", t_hi*|det| " << num(e.f1.y) << ", best*|det| " << num(e.f1.z) << "\n";
        if (e.code == kTestAccepted || e.code == kTestAlphaKeyed || e.code == kTestTieLost)
          os << "      t = t*|det| / |det| = " << num(e.f1.w) << "\n";
        break;
      case kEvAlpha:
        os << "      alpha mask: barycentrics (" << num(e.f0.x) << ", " << num(e.f0.y) << "), uv (" << num(e.f0.z)
           << ", " << num(e.f0.w) << ") -> texel (" << e.cell.x << ", " << e.cell.y << ") of material "
           << e.cell.z << ", alpha " << e.slot << (e.code ? " >= " : " < ") << kAlphaCutoff
           << (e.code ? ": kept" : ": cut away") << "\n";
        break;
      case kEvCandidate:
        os << "      new best hit: t " << num(e.f0.x) << ", barycentrics (" << num(e.f0.y) << ", " << num(e.f0.z)
           << ") by Cramer's rule\n";
        break;
      case kEvStatus:
        os << "  status texel: " << e.code << ((e.code & kStatusStatic) ? " saturated-by-static" : "")
           << ((e.code & kStatusDynamic) ? " saturated-by-dynamic" : "") << (e.code ? "" : " (not saturated)")
           << "\n";
        break;
      case kEvSpillScan:
        os << "  spill list: the cell dropped references; its static and dynamic lists follow (the list stores "
           << e.code << " entries in all)"
           << (e.slot > e.code ? " (the list overflowed: " + std::to_string(e.slot - e.code) +
                                     " dropped references were lost, holes are possible)"
                               : "")
           << "\n";
        break;
      case kEvSpilled:
        os << "  spilled " << e.slot << ": " << refstr(e.ref) << "\n";
        break;
      case kEvGapFill:
        os << "  gap-fill: the cell is saturated and no hit was reported; left the launch surface? "
           << num(e.f0.x) << " >= " << num(e.f0.y) << ": "
           << (e.code == kGapApplied ? "yes -> FALSE HIT at the segment's midpoint with the last reference "
                                     : e.code == kGapTooClose ? "no, too close to the launch surface"
                                                              : "yes, but the midpoint is outside (t_lo, tmax)")
           << (e.code == kGapApplied ? refstr(e.ref) : "") << "\n";
        break;
      case kEvReport:
        os << "HIT at step " << e.step << ": " << refstr(e.ref) << ", t " << num(e.f0.x) << ", u " << num(e.f0.y)
           << ", v " << num(e.f0.z) << ((e.code & kHitGapFill) ? ", GAP-FILL" : "")
           << ((e.code & kHitBackFace) ? ", back face" : "")
           << (exact ? " (t <= the cell's exit)" : " (t < the segment's end)") << "\n";
        break;
      case kEvMiss:
        os << "MISS: " << miss_reason(e.code) << "\n";
        break;
      default:
        os << "? event kind " << e.kind << "\n";
    }
  }
  os << "cells visited " << rec.hit.cells << ", triangle tests " << rec.hit.tests << "\n";
  return os.str();
}

}  // namespace gridrt::plan
