// explain_format.cpp: an ExplainRecord as text (full and brief), as JSON, and two records aligned
// side by side (plan/explain_format.h).
#include "gridrt/plan/explain_format.h"

#include "gridrt/common/util.h"

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>

#include "gridrt/common/safe_io.h"
#include "gridrt/common/shared/triangle.h"

namespace gridrt::plan {

using namespace gridrt::shared;

namespace {

// A float: full mode "1.5 [0x3fc00000]", brief mode "1.5".
std::string num(float f, const ExplainFormat& fmt) {
  char buf[64];
  if (fmt.brief)
    std::snprintf(buf, sizeof buf, "%.7g", double(f));
  else
    std::snprintf(buf, sizeof buf, "%.9g [%s]", double(f), hex(f).c_str());
  return buf;
}
std::string vec(glm::vec3 v, const ExplainFormat& fmt) {
  return "(" + num(v.x, fmt) + ", " + num(v.y, fmt) + ", " + num(v.z, fmt) + ")";
}
std::string cellstr(glm::uvec3 c) {
  return "(" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}
std::string u32(uint32_t v) { return std::to_string(v); }

const char* test_reason(uint32_t code) {
  switch (code) {
    case kTestAccepted: return "ACCEPTED: inside the triangle, within the segment, closest so far";
    case kTestParallel:
      return "rejected: det == 0, the triangle seen along the ray has no area (the ray parallel to its plane, or its "
             "sheared vertices on one line)";
    case kTestOutsideU: return "rejected: u*|det| < 0, outside edge v0-v2";
    case kTestOutsideV: return "rejected: v*|det| < 0, outside edge v0-v1";
    case kTestOutsideUV: return "rejected: (u+v)*|det| > |det|, outside edge v1-v2";
    case kTestBehind: return "rejected: t*|det| <= t_lo*|det|, before the (elongated) segment or tmin";
    case kTestBeyond: return "rejected: t*|det| >= t_hi*|det|, beyond the (elongated) segment or tmax";
    case kTestNotCloser: return "rejected: t*|det| > best*|det| (best: best_t two ulps up), the best hit so far is closer";
    case kTestSelfHit: return "skipped: the ray's launch triangle (self-hit)";
    case kTestAlphaKeyed: return "rejected: alpha-keyed out by the mask";
    case kTestTieLost: return "rejected: t not smaller than the best hit's (ties keep the smaller reference)";
    case kTestMailboxed: return "skipped: tested earlier on this ray (mailbox), the result cannot change";
    case kTestOriginPlane: return "rejected: the triangle's plane passes within the surface rule's tolerance of the origin (8 ulps of the largest coordinate of the origin or of its offset to the face's nearest vertex; docs/SPEC.md \"The surface rule\")";
    default: return "?";
  }
}

// Why a ray is outside the domain (shared::ray_domain), from the record's ray event.
std::string rejection_reason(const ExplainRecord& rec) {
  for (const ExplainEvent& e : rec.events) {
    if (e.kind != kEvRay) continue;
    switch (ray_domain(glm::vec3(e.f0), glm::vec3(e.f1), e.f0.w, e.f1.w)) {
      case kDomainNonFinite: return "a NaN or infinite component of the origin or direction";
      case kDomainDirection: return "the direction's largest component is outside [2^-20, 2^20] (or zero)";
      case kDomainOrigin: return "an origin component beyond 2^24";
      case kDomainInterval: return "tmin or tmax is NaN, or tmin < 0";
      default: break;
    }
  }
  return "outside the ray domain (docs/SPEC.md, \"Domain\")";
}

// Whether the record's ray was rejected (outside the domain): its miss then says so, not why a
// traced ray missed.
bool rejected(const ExplainRecord& rec) {
  for (const ExplainEvent& e : rec.events)
    if (e.kind == kEvRejected) return true;
  return false;
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

// A miss's reason; a ray whose interval is empty (tmin >= tmax: valid, and met by nothing) says so,
// where "does not meet the grid box" misled (an outside sweep: the ray did meet it).
std::string miss_text(const ExplainRecord& rec, uint32_t code) {
  if (code == kMissOutsideGrid)
    for (const ExplainEvent& e : rec.events)
      if (e.kind == kEvRay && !(e.f0.w < e.f1.w)) {
        char buf[160];
        std::snprintf(buf, sizeof buf, "the ray's interval is empty (tmin %.9g >= tmax %.9g): nothing can be hit",
                      double(e.f0.w), double(e.f1.w));
        return buf;
      }
  return miss_reason(code);
}

bool is_exact(const ExplainRecord& rec) { return rec.params.traversal == kTraversalExact; }

// Whether visit event i (a kEvCell) found its cell empty: its only event is the blank slot 0.
bool empty_visit(const ExplainRecord& rec, size_t i) {
  const auto& ev = rec.events;
  return ev[i].kind == kEvCell && i + 1 < ev.size() && ev[i + 1].kind == kEvSlot && ev[i + 1].slot == 0u &&
         ev[i + 1].ref == kBlank &&
         (i + 2 == ev.size() || ev[i + 2].kind == kEvCell || ev[i + 2].kind == kEvCellSkipped ||
          ev[i + 2].kind == kEvMiss || ev[i + 2].kind == kEvReport);
}

std::string hex_u32(uint32_t v) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "0x%08x", v);
  return buf;
}

}  // namespace

ExplainNames ExplainNames::of(const Scene& scene) {
  ExplainNames n;
  for (const Instance& inst : scene.instances)
    n.instances.push_back(!inst.name.empty() ? inst.name
                          : inst.mesh < scene.meshes.size() ? scene.meshes[inst.mesh].name
                                                            : std::string());
  return n;
}

const char* event_kind_name(uint32_t kind) {
  switch (kind) {
    case kEvRay: return "ray";
    case kEvRejected: return "rejected";
    case kEvSetup: return "setup";
    case kEvCell: return "cell";
    case kEvCellSkipped: return "cell-skipped";
    case kEvSlot: return "slot";
    case kEvTest: return "test";
    case kEvAlpha: return "alpha";
    case kEvCandidate: return "candidate";
    case kEvStatus: return "status";
    case kEvGapFill: return "gap-fill";
    case kEvReport: return "report";
    case kEvMiss: return "miss";
    case kEvSpillScan: return "spill-scan";
    case kEvSpilled: return "spilled";
    case kEvSkip: return "skip";
    case kEvCovered: return "covered";
    default: return "unknown";
  }
}

namespace {
// A cover face (kEvCovered's code: bit 2 axis + side of the cover bits) as text: "-x" is the
// neighbour at index - 1 along x.
std::string face_name(uint32_t f) {
  if (f >= 6u) return "no";
  return std::string(f % 2u == 0u ? "-" : "+") + char('x' + f / 2u);
}

// A skip step's dynamic boxes (its slot: the boxes the walk can reach, skip_box_reached), as text.
std::string boxes_reached(uint32_t mask) {
  if (mask == 0u) return "";
  std::string list;
  uint32_t n = 0;
  for (uint32_t b = 0; b < 32u; ++b)
    if ((mask >> b) & 1u) list += (n++ ? ", " : "") + std::to_string(b);
  return " (the distance counts the dynamic " + std::string(n > 1 ? "boxes " : "box ") + list +
         ", which the walk can reach)";
}
}  // namespace

std::string event_code_name(uint32_t kind, uint32_t code) {
  switch (kind) {
    case kEvSetup: return code == kTraversalExact ? "exact" : "paper";
    case kEvTest: {
      static const char* names[] = {"accepted", "parallel", "outside-u",  "outside-v",   "outside-uv", "behind",
                                    "beyond",   "not-closer", "self-hit", "alpha-keyed", "tie-lost",
                                    "mailboxed", "origin-plane"};
      return code < std::size(names) ? names[code] : "?";
    }
    case kEvAlpha: return code ? "kept" : "cut";
    case kEvStatus: {
      std::string s = code == 0u ? "not-saturated" : "";
      if (code & kStatusStatic) s += "saturated-by-static";
      if (code & kStatusDynamic) s += std::string(s.empty() ? "" : "+") + "saturated-by-dynamic";
      return s;
    }
    case kEvGapFill: return code == kGapApplied ? "applied" : code == kGapTooClose ? "too-close" : "outside-ray";
    case kEvReport: {
      std::string s = (code & kHitGapFill) ? "gap-fill" : "triangle";
      if (code & kHitBackFace) s += "+back-face";
      return s;
    }
    case kEvMiss: {
      static const char* names[] = {"outside-grid", "left-grid", "tmax", "step-limit"};
      return code < std::size(names) ? names[code] : "?";
    }
    default: return "";
  }
}

std::vector<EventField> event_fields(uint32_t kind, bool exact) {
  // kind, code, ref, step, cell, slot, f0.x, f0.y, f0.z, f0.w, f1.x, f1.y, f1.z, f1.w
  auto make = [](std::initializer_list<const char*> names) {
    static const char* fields[] = {"kind", "code", "ref",  "step", "cell", "slot", "f0.x",
                                   "f0.y", "f0.z", "f0.w", "f1.x", "f1.y", "f1.z", "f1.w"};
    std::vector<EventField> out;
    size_t i = 0;
    for (const char* n : names) out.push_back({fields[i++], n});
    return out;
  };
  switch (kind) {
    case kEvRay:
      return make({"kind", "", "launch_ref", "", "", "", "org.x", "org.y", "org.z", "tmin", "dir.x", "dir.y", "dir.z",
                   "tmax"});
    case kEvSetup:
      return make({"kind", "traversal", "", "", "", "meets grid", "seg_t", "t_start", "t_end", "t_lo",
                   "launch_normal.x", "launch_normal.y", "launch_normal.z", "t_base"});
    case kEvCell:
      if (exact)
        return make({"kind", "", "", "step", "cell", "", "entry.x", "entry.y", "entry.z", "t entry", "t entry",
                     "t exit", "t_lo", "t_hi"});
      return make({"kind", "merged segments", "", "segment", "cell", "", "sample.x", "sample.y", "sample.z",
                   "sample t", "segment begin", "segment end", "t_lo (elongated)", "t_hi (elongated)"});
    case kEvCellSkipped:
      return make({"kind", "", "", "segment", "cell", "", "sample.x", "sample.y", "sample.z", "sample t", "", "", "",
                   ""});
    case kEvSlot: return make({"kind", "", "ref", "step", "cell", "slot", "", "", "", "", "", "", "", ""});
    case kEvTest:
      return make({"kind", "result", "ref", "step", "cell", "slot", "det", "u*|det|", "v*|det|", "t*|det|",
                   "t_lo*|det|", "t_hi*|det|", "best*|det|", "t"});
    case kEvAlpha:
      return make({"kind", "kept", "ref", "step", "texel (x, y, material)", "alpha", "u", "v", "uv.s", "uv.t", "",
                   "", "", ""});
    case kEvCandidate:
      return make({"kind", "", "ref", "step", "cell", "slot", "t", "u", "v", "previous best t", "", "", "", ""});
    case kEvStatus: return make({"kind", "status bits", "", "step", "cell", "slot", "", "", "", "", "", "", "", ""});
    case kEvGapFill:
      return make({"kind", "decision", "last ref", "step", "cell", "", "lhs", "rhs", "sample t", "", "", "", "",
                   ""});
    case kEvReport: return make({"kind", "hit flags", "ref", "step", "", "", "t", "u", "v", "", "", "", "", ""});
    case kEvMiss: return make({"kind", "reason", "", "step", "", "", "", "", "", "", "", "", "", ""});
    case kEvSpillScan:
      return make({"kind", "entries stored", "", "step", "cell", "references appended", "", "", "", "", "", "", "",
                   ""});
    case kEvSpilled:
      return make({"kind", "", "ref", "step", "cell", "index among the spilled", "", "", "", "", "", "", "", ""});
    case kEvSkip:
      return make({"kind", "distance to the nearest reference (cells)", "", "step", "cell",
                   "dynamic boxes the walk can reach (bit b: box b)", "", "", "", "", "t entry", "t exit of the box",
                   "", ""});
    case kEvCovered:
      return make({"kind", "face entered through (bit 2 axis + side)", "", "step", "cell",
                   "references in the run, not read", "", "", "", "", "", "", "", ""});
    default:
      return make({"kind", "code", "ref", "step", "cell", "slot", "f0.x", "f0.y", "f0.z", "f0.w", "f1.x", "f1.y",
                   "f1.z", "f1.w"});
  }
}

std::string reference_text(uint32_t ref, const ExplainFormat& fmt) {
  if (ref == kBlank) return "blank";
  const uint32_t inst = ref_instance(ref);
  std::string s = "instance " + u32(inst);
  if (fmt.names && inst < fmt.names->instances.size() && !fmt.names->instances[inst].empty())
    // Escaped as map words are (a name with a line break printed raw broke the text's lines: an
    // outside sweep; JSON, HTML and CSV escape it themselves)
    s += " \"" + control_escaped(fmt.names->instances[inst]) + "\"";
  s += ", triangle " + u32(ref_triangle(ref));
  return fmt.brief ? s : hex_u32(ref) + " (" + s + ")";
}

std::string grid_text(const GridParams& g, const ExplainFormat& fmt) {
  std::ostringstream os;
  const bool exact = g.traversal == kTraversalExact;
  os << "grid: " << g.cells.x << "x" << g.cells.y << "x" << g.cells.z << " cells of " << num(g.cell_size, fmt)
     << ", origin " << vec(g.origin, fmt) << ", capacity " << g.capacity << ", traversal "
     << (exact ? "exact (3D DDA)" : "paper (cell-sized segments)") << ", insertion "
     << (g.insertion == kInsertSorted ? "sorted" : "first-empty") << ((g.flags & kGridSpill) ? ", spill list on" : "")
     << ((g.flags & kGridSkipEmpty) ? ", empty-space skipping on" : "")
     << ((g.flags & kGridSkipCovered) ? ", covered cells skipped" : "")
     << (mailbox_enabled(g) ? ", mailbox on" : "")
     << ((g.flags & kGridGapFill) ? ", gap-fill on" : "");
  return os.str();
}

std::vector<std::string> event_lines(const ExplainRecord& rec, size_t i, const ExplainFormat& fmt) {
  if (fmt.brief) return {event_summary(rec, i, fmt)};
  const ExplainEvent& e = rec.events[i];
  const bool exact = is_exact(rec);
  std::vector<std::string> out;
  std::ostringstream os;
  auto line = [&] {
    out.push_back(os.str());
    os.str("");
  };
  auto ref = [&](uint32_t r) { return reference_text(r, fmt); };
  switch (e.kind) {
    case kEvRay:
      os << "ray: org " << vec(glm::vec3(e.f0), fmt) << " dir " << vec(glm::vec3(e.f1), fmt);
      line();
      os << "  tmin " << num(e.f0.w, fmt) << " tmax " << num(e.f1.w, fmt) << ", launched from " << ref(e.ref);
      line();
      break;
    case kEvRejected:
      os << "REJECTED: " << rejection_reason(rec) << "; reported as a miss with kHitRejected";
      line();
      break;
    case kEvSetup:
      os << "setup: one cell edge = " << num(e.f0.x, fmt) << " in t; t_start " << num(e.f0.y, fmt) << ", t_end "
         << num(e.f0.z, fmt) << ", hits need t > " << num(e.f0.w, fmt);
      line();
      os << "  launch normal " << vec(glm::vec3(e.f1), fmt) << (e.slot ? "" : "; no part of the ray's interval (tmin, tmax) lies in the grid box");
      line();
      if (e.f1.w > 0.0f) {
        // docs/SPEC.md "Far origins"
        os << "  far origin: moved along the ray by t " << num(e.f1.w, fmt)
           << " to just before the grid box; the t above and below are the moved ray's, the hit's t adds it back";
        line();
      }
      break;
    case kEvCell:
      if (exact) {
        os << "step " << e.step << ": cell " << cellstr(e.cell) << ", t in [" << num(e.f1.x, fmt) << ", "
           << num(e.f1.y, fmt) << "]; triangles tested on (" << num(e.f1.z, fmt) << ", " << num(e.f1.w, fmt) << ")";
        line();
      } else {
        os << "segment " << e.step
           << (e.code ? " to " + std::to_string(e.step + e.code) + " (their samples share one cell: one visit)" : "")
           << ": [" << num(e.f1.x, fmt) << ", " << num(e.f1.y, fmt) << "], midpoint t " << num(e.f0.w, fmt) << " = "
           << vec(glm::vec3(e.f0), fmt);
        line();
        os << "  cell " << cellstr(e.cell) << "; triangles tested on the elongated segment (" << num(e.f1.z, fmt)
           << ", " << num(e.f1.w, fmt) << ")";
        line();
      }
      break;
    case kEvCellSkipped:
      os << "segment " << e.step << ": sample at t " << num(e.f0.w, fmt) << " lies in cell " << cellstr(e.cell)
         << " again: visited, skipped";
      line();
      break;
    case kEvSlot:
      os << "  slot " << e.slot << ": " << ref(e.ref) << (e.ref == kBlank ? " -> end of the cell's list" : "");
      line();
      break;
    case kEvTest:
      os << "    test " << ref(e.ref) << ": " << test_reason(e.code);
      line();
      if (e.code != kTestSelfHit && e.code != kTestMailboxed) {
        os << "      det " << num(e.f0.x, fmt) << (e.f0.x < 0.0f ? " (back face)" : "") << ", u*|det| "
           << num(e.f0.y, fmt) << ", v*|det| " << num(e.f0.z, fmt);
        line();
        // A bound times |det| where det is 0 and the bound infinite (tmax, or no best yet) is
        // inf * 0: NaN, which no comparison passes. Said so, with its bits, not as "-nan"
        const auto bound = [&](float v) {
          if (!std::isnan(v)) return num(v, fmt);
          return std::string("NaN (inf x |det| 0)") + (fmt.brief ? std::string() : " [" + hex(v) + "]");
        };
        os << "      t*|det| " << num(e.f0.w, fmt) << " against t_lo*|det| " << bound(e.f1.x) << ", t_hi*|det| "
           << bound(e.f1.y) << ", best*|det| " << bound(e.f1.z);
        line();
      }
      if (e.code == kTestAccepted || e.code == kTestAlphaKeyed || e.code == kTestTieLost || e.code == kTestOriginPlane) {
        os << "      t = t*|det| / |det| = " << num(e.f1.w, fmt);
        line();
      }
      break;
    case kEvAlpha:
      os << "      alpha mask: barycentrics (" << num(e.f0.x, fmt) << ", " << num(e.f0.y, fmt) << "), uv ("
         << num(e.f0.z, fmt) << ", " << num(e.f0.w, fmt) << ") -> texel (" << e.cell.x << ", " << e.cell.y
         << ") of material " << e.cell.z << ", alpha " << e.slot << (e.code ? " >= " : " < ") << kAlphaCutoff
         << (e.code ? ": kept" : ": cut away");
      line();
      break;
    case kEvCandidate:
      os << "      new best hit: t " << num(e.f0.x, fmt) << ", barycentrics (" << num(e.f0.y, fmt) << ", "
         << num(e.f0.z, fmt) << "), the test's own weights (clamped into the triangle)";
      line();
      break;
    case kEvStatus:
      os << "  status texel: " << e.code << ((e.code & kStatusStatic) ? " saturated-by-static" : "")
         << ((e.code & kStatusDynamic) ? " saturated-by-dynamic" : "") << (e.code ? "" : " (not saturated)");
      line();
      break;
    case kEvSpillScan:
      os << "  spill list: the cell dropped references; its static and dynamic lists follow (the list stores "
         << e.code << " entries in all)"
         << (e.slot > e.code ? " (the list overflowed: " + std::to_string(e.slot - e.code) +
                                   " dropped references were lost, holes are possible)"
                             : "");
      line();
      break;
    case kEvSpilled:
      os << "  spilled " << e.slot << ": " << ref(e.ref);
      line();
      break;
    case kEvSkip:
      os << "step " << e.step << ": cell " << cellstr(e.cell) << " is empty, its nearest reference " << e.code
         << " cells away: the box of " << (2 * e.code - 1) << " cells a side around it passed at once, t in ["
         << num(e.f1.x, fmt) << ", " << num(e.f1.y, fmt) << "]" << boxes_reached(e.slot);
      line();
      break;
    case kEvCovered:
      os << "  covered: the cell's " << e.slot << " static reference(s) all lie in the cell the walk came from "
         << "(entered through its " << face_name(e.code) << " face), tested there: not read again";
      line();
      break;
    case kEvGapFill:
      os << "  gap-fill: the cell is saturated and no hit was reported; left the launch surface? "
         << num(e.f0.x, fmt) << " >= " << num(e.f0.y, fmt) << ": "
         << (e.code == kGapApplied   ? "yes -> FALSE HIT at the segment's midpoint with the last reference " + ref(e.ref)
             : e.code == kGapTooClose ? std::string("no, too close to the launch surface")
                                      : std::string("yes, but the midpoint is outside (t_lo, tmax)"));
      line();
      break;
    case kEvReport:
      os << "HIT at step " << e.step << ": " << ref(e.ref) << ", t " << num(e.f0.x, fmt) << ", u " << num(e.f0.y, fmt)
         << ", v " << num(e.f0.z, fmt) << ((e.code & kHitGapFill) ? ", GAP-FILL" : "")
         << ((e.code & kHitBackFace) ? ", back face" : "")
         << (exact ? " (t <= the cell's exit)" : " (t < the segment's end)");
      line();
      break;
    case kEvMiss:
      os << "MISS: " << (rejected(rec) ? "the ray was rejected (above), never traced" : miss_text(rec, e.code));
      line();
      break;
    default:
      os << "? event kind " << e.kind;
      line();
  }
  return out;
}

std::string event_summary(const ExplainRecord& rec, size_t i, const ExplainFormat& format) {
  ExplainFormat fmt = format;
  fmt.brief = true;
  const ExplainEvent& e = rec.events[i];
  const bool exact = is_exact(rec);
  std::ostringstream os;
  auto ref = [&](uint32_t r) { return reference_text(r, fmt); };
  switch (e.kind) {
    case kEvRay:
      os << "ray org " << vec(glm::vec3(e.f0), fmt) << " dir " << vec(glm::vec3(e.f1), fmt) << " t in ("
         << num(e.f0.w, fmt) << ", " << num(e.f1.w, fmt) << ")"
         << (e.ref == kNoRef ? "" : ", launched from " + ref(e.ref));
      break;
    case kEvRejected: os << "REJECTED: " << rejection_reason(rec); break;
    case kEvSetup:
      if (e.slot)
        os << "setup: a cell edge is " << num(e.f0.x, fmt) << " in t; the grid box from t " << num(e.f0.y, fmt)
           << " to " << num(e.f0.z, fmt) << "; hits need t > " << num(e.f0.w, fmt);
      else
        os << "setup: no part of the ray's interval (tmin, tmax) lies in the grid box";
      // A far origin: the t above are from the moved origin (docs/SPEC.md "Far origins")
      if (e.f1.w > 0.0f) os << " (far origin: moved along the ray by t " << num(e.f1.w, fmt) << ", t from there)";
      break;
    case kEvCell:
      if (exact)
        os << "step " << e.step << ": cell " << cellstr(e.cell) << ", t [" << num(e.f1.x, fmt) << ", "
           << num(e.f1.y, fmt) << "]";
      else
        os << "segment " << e.step << (e.code ? "-" + std::to_string(e.step + e.code) : "") << ": cell "
           << cellstr(e.cell) << ", sample t " << num(e.f0.w, fmt) << ", tested on (" << num(e.f1.z, fmt) << ", "
           << num(e.f1.w, fmt) << ")";
      break;
    case kEvCellSkipped: os << "segment " << e.step << ": cell " << cellstr(e.cell) << " again, skipped"; break;
    case kEvSlot:
      os << "  slot " << e.slot << ": " << (e.ref == kBlank ? std::string("blank (end of the list)") : ref(e.ref));
      break;
    case kEvTest:
      os << "    test " << ref(e.ref) << ": " << event_code_name(e.kind, e.code);
      if (e.code == kTestAccepted || e.code == kTestAlphaKeyed || e.code == kTestTieLost || e.code == kTestOriginPlane)
        os << ", t " << num(e.f1.w, fmt);
      break;
    case kEvAlpha:
      os << "      alpha " << e.slot << " at texel (" << e.cell.x << ", " << e.cell.y << "): "
         << (e.code ? "kept" : "cut away");
      break;
    case kEvCandidate: os << "      new best hit, t " << num(e.f0.x, fmt); break;
    case kEvStatus: os << "  status: " << event_code_name(e.kind, e.code); break;
    case kEvSpillScan:
      os << "  spill list walked (" << e.code << " entries stored"
         << (e.slot > e.code ? ", " + std::to_string(e.slot - e.code) + " LOST to overflow" : "") << ")";
      break;
    case kEvSpilled: os << "  spilled " << e.slot << ": " << ref(e.ref); break;
    case kEvSkip:
      os << "step " << e.step << ": cell " << cellstr(e.cell) << " empty, box of " << (2 * e.code - 1)
         << " cells a side passed, t [" << num(e.f1.x, fmt) << ", " << num(e.f1.y, fmt) << "]";
      break;
    case kEvCovered:
      os << "  covered from the " << face_name(e.code) << " face: " << e.slot << " reference(s) not read again";
      break;
    case kEvGapFill:
      os << "  gap-fill: " << event_code_name(e.kind, e.code)
         << (e.code == kGapApplied ? " -> FALSE HIT with " + ref(e.ref) : "");
      break;
    case kEvReport:
      os << "HIT at step " << e.step << ": " << ref(e.ref) << ", t " << num(e.f0.x, fmt)
         << ((e.code & kHitGapFill) ? ", GAP-FILL" : "") << ((e.code & kHitBackFace) ? ", back face" : "");
      break;
    case kEvMiss:
      os << "MISS: " << (rejected(rec) ? "the ray was rejected, never traced" : miss_text(rec, e.code));
      break;
    default: os << "? event kind " << e.kind;
  }
  return os.str();
}

std::string explain_text(const ExplainRecord& rec, const ExplainFormat& fmt) {
  std::ostringstream os;
  os << grid_text(rec.params, fmt) << "\n";
  if (rec.mode == shared::kTraceAnyHit)
    os << "any hit: the trace stops at the first accepted candidate (occlusion; docs/SPEC.md \"Any hit\")\n";
  const size_t n = rec.events.size();
  const int width = int(std::to_string(n ? n - 1 : 0).size()) + 1;
  for (size_t i = 0; i < n; ++i) {
    // Brief: a run of empty cells in one line
    if (fmt.brief && empty_visit(rec, i)) {
      size_t j = i;
      size_t count = 0;
      while (j < n && empty_visit(rec, j)) {
        j += 2;
        ++count;
      }
      if (count > 1) {
        char buf[128];
        // The exact traversal's steps are its cells; the paper's visits merge segments
        if (is_exact(rec))
          std::snprintf(buf, sizeof buf, "%*s cells %u-%u empty (%zu)\n", width, ("#" + std::to_string(i)).c_str(),
                        rec.events[i].step, rec.events[j - 2].step, count);
        else
          std::snprintf(buf, sizeof buf, "%*s segments %u-%u empty (%zu cells)\n", width,
                        ("#" + std::to_string(i)).c_str(), rec.events[i].step,
                        rec.events[j - 2].step + rec.events[j - 2].code, count);
        os << buf;
        i = j - 1;
        continue;
      }
    }
    const std::vector<std::string> lines = event_lines(rec, i, fmt);
    for (size_t l = 0; l < lines.size(); ++l) {
      char tag[32];
      std::snprintf(tag, sizeof tag, "%*s ", width, l == 0 ? ("#" + std::to_string(i)).c_str() : "");
      os << tag << lines[l] << "\n";
    }
  }
  os << "cells visited " << rec.hit.cells << ", triangle tests " << rec.hit.tests << "\n";
  return os.str();
}

namespace {

nlohmann::json hex_floats(glm::vec4 v) { return {hex(v.x), hex(v.y), hex(v.z), hex(v.w)}; }
// JSON has no inf or NaN: those go as strings ("inf", "-inf", "nan"); the hex bits say all.
nlohmann::json jnum(float f) {
  if (std::isnan(f)) return "nan";
  if (std::isinf(f)) return f > 0 ? "inf" : "-inf";
  return double(f);
}
nlohmann::json jvec(glm::vec4 v) { return {jnum(v.x), jnum(v.y), jnum(v.z), jnum(v.w)}; }

nlohmann::json ref_json(uint32_t ref, const ExplainFormat& fmt) {
  if (ref == kBlank) return nullptr;
  nlohmann::json j{{"word", hex_u32(ref)}, {"instance", ref_instance(ref)}, {"triangle", ref_triangle(ref)}};
  const uint32_t inst = ref_instance(ref);
  if (fmt.names && inst < fmt.names->instances.size()) j["name"] = fmt.names->instances[inst];
  return j;
}

}  // namespace

nlohmann::json explain_json(const ExplainRecord& rec, const ExplainFormat& fmt) {
  using nlohmann::json;
  const GridParams& g = rec.params;
  json out;
  out["ray"] = {{"org", {jnum(rec.ray.org.x), jnum(rec.ray.org.y), jnum(rec.ray.org.z)}},
                {"dir", {jnum(rec.ray.dir.x), jnum(rec.ray.dir.y), jnum(rec.ray.dir.z)}},
                {"tmin", jnum(rec.ray.tmin)},
                {"tmax", jnum(rec.ray.tmax)},
                {"launch_ref", ref_json(rec.ray.launch_ref, fmt)},
                {"hex", {hex(rec.ray.org.x), hex(rec.ray.org.y), hex(rec.ray.org.z), hex(rec.ray.dir.x),
                         hex(rec.ray.dir.y), hex(rec.ray.dir.z), hex(rec.ray.tmin), hex(rec.ray.tmax)}}};
  out["grid"] = {{"cells", {g.cells.x, g.cells.y, g.cells.z}},
                 {"cell_size", jnum(g.cell_size)},
                 {"origin", {jnum(g.origin.x), jnum(g.origin.y), jnum(g.origin.z)}},
                 {"capacity", g.capacity},
                 {"traversal", g.traversal == kTraversalExact ? "exact" : "paper"},
                 {"insertion", g.insertion == kInsertSorted ? "sorted" : "first-empty"},
                 {"spill", (g.flags & kGridSpill) != 0u},
                 {"skip_empty", (g.flags & kGridSkipEmpty) != 0u},
                 {"skip_covered", (g.flags & kGridSkipCovered) != 0u},
                 {"mailbox", mailbox_enabled(g)},
                 {"gap_fill", (g.flags & kGridGapFill) != 0u},
                 {"alpha_keying", (g.flags & kGridAlphaKeying) != 0u},
                 {"elongation", jnum(g.elongation)},
                 {"max_segments", g.max_segments}};
  json events = json::array();
  const bool exact = is_exact(rec);
  for (size_t i = 0; i < rec.events.size(); ++i) {
    const ExplainEvent& e = rec.events[i];
    json j{{"n", i},
           {"kind", e.kind},
           {"kind_name", event_kind_name(e.kind)},
           {"code", e.code},
           {"ref", e.ref},
           {"step", e.step},
           {"cell", {e.cell.x, e.cell.y, e.cell.z}},
           {"slot", e.slot},
           {"f0", jvec(e.f0)},
           {"f1", jvec(e.f1)},
           {"f0_hex", hex_floats(e.f0)},
           {"f1_hex", hex_floats(e.f1)},
           {"text", event_summary(rec, i, fmt)}};
    const std::string code = event_code_name(e.kind, e.code);
    if (!code.empty()) j["code_name"] = code;
    if (e.kind == kEvSlot || e.kind == kEvTest || e.kind == kEvCandidate || e.kind == kEvSpilled ||
        e.kind == kEvReport || e.kind == kEvGapFill || e.kind == kEvAlpha || e.kind == kEvRay)
      j["reference"] = ref_json(e.ref, fmt);
    // The fields by name; null where the step computed nothing (the record holds 0 there): a test
    // never made (the launch triangle, a mailboxed reference) has no values, and the reported t
    // (f1.w) exists only where the geometry accepted the triangle (an outside sweep: the viewer
    // showed t = 0 for rejected tests)
    json named = json::object();
    const std::vector<EventField> fields = event_fields(e.kind, exact);
    const float fl[8] = {e.f0.x, e.f0.y, e.f0.z, e.f0.w, e.f1.x, e.f1.y, e.f1.z, e.f1.w};
    bool computed[8] = {true, true, true, true, true, true, true, true};
    if (e.kind == kEvTest) {
      const bool tested = e.code != kTestSelfHit && e.code != kTestMailboxed;
      const bool t_known = e.code == kTestAccepted || e.code == kTestOriginPlane || e.code == kTestAlphaKeyed ||
                           e.code == kTestTieLost;
      for (bool& c : computed) c = tested;
      computed[7] = t_known;
      j["computed"] = json::array();
      for (bool c : computed) j["computed"].push_back(c);
    }
    for (size_t k = 6; k < fields.size(); ++k)
      if (*fields[k].name) named[fields[k].name] = computed[k - 6] ? jnum(fl[k - 6]) : json(nullptr);
    j["fields"] = named;
    json field_names = json::array();
    for (const EventField& f : fields) field_names.push_back(f.name);
    j["field_names"] = std::move(field_names);
    const size_t v = visit_of(rec, i);
    if (v != kNoEvent) j["visit"] = v;
    events.push_back(std::move(j));
  }
  out["events"] = std::move(events);
  const Hit& h = rec.hit;
  out["hit"] = {{"miss", is_miss(h)},
                {"t", jnum(h.t)},
                {"instance", h.instance},
                {"triangle", h.triangle},
                {"reference", is_miss(h) ? json(nullptr) : ref_json((h.instance << 16) | h.triangle, fmt)},
                {"u", jnum(h.u)},
                {"v", jnum(h.v)},
                {"flags", h.flags},
                {"cells", h.cells},
                {"tests", h.tests},
                {"hex", {hex(h.t), hex(h.u), hex(h.v)}}};
  return out;
}

namespace {
// `s` in quotes for a message, its first 64 characters only where it is longer (a ray file's
// line can be megabytes)
std::string quoted(const std::string& s) {
  if (s.size() <= 64) return "'" + s + "'";
  return "'" + s.substr(0, 64) + "...' (" + std::to_string(s.size()) + " characters)";
}
}  // namespace

Ray parse_ray(const std::string& text) {
  std::vector<std::string> parts;
  std::string part;
  std::istringstream in(text);
  while (std::getline(in, part, ',')) {
    const size_t a = part.find_first_not_of(" \t\r"), b = part.find_last_not_of(" \t\r");
    parts.push_back(a == std::string::npos ? "" : part.substr(a, b - a + 1));
  }
  if (!text.empty() && text.back() == ',') parts.push_back("");
  if (parts.size() != 6 && parts.size() != 8 && parts.size() != 9)
    throw Error("a ray is ox,oy,oz,dx,dy,dz[,tmin,tmax[,launch_ref]] (" + std::to_string(parts.size()) +
                " values in " + quoted(text) + ")");
  auto number = [&](size_t i) {
    const std::string& s = parts[i];
    char* end = nullptr;
    errno = 0;
    const float f = std::strtof(s.c_str(), &end);  // decimal, C99 hex (0x1.8p+1), inf, nan
    if (!s.empty() && *end == '\0' && errno == ERANGE && std::isinf(f))
      throw Error("value " + std::to_string(i + 1) + " of the ray, " + quoted(s) +
                  ", is beyond a float's range (largest 3.40282347e+38; give inf for an infinity)");
    if (s.empty() || *end != '\0')
      throw Error("value " + std::to_string(i + 1) + " of the ray, " + quoted(s) + ", is not a float");
    return f;
  };
  Ray r;
  r.org = glm::vec3(number(0), number(1), number(2));
  r.dir = glm::vec3(number(3), number(4), number(5));
  r.tmin = parts.size() > 6 ? number(6) : 0.0f;
  r.tmax = parts.size() > 6 ? number(7) : std::numeric_limits<float>::infinity();
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = kNoRef;
  if (parts.size() == 9 && parts[8] != "none") {
    // A reference word (decimal or 0x hex), or INSTANCE:TRIANGLE
    const std::string& s = parts[8];
    char* end = nullptr;
    const size_t colon = s.find(':');
    if (colon != std::string::npos) {
      const std::string a = s.substr(0, colon), b = s.substr(colon + 1);
      // Digits only: strtoul would take a sign (and wrap a negative number) or leading blanks
      const auto digits = [](const std::string& t) { return !t.empty() && t.find_first_not_of("0123456789") == std::string::npos; };
      const unsigned long inst = std::strtoul(a.c_str(), &end, 10);
      const bool ok = digits(a) && *end == '\0';
      const unsigned long tri = std::strtoul(b.c_str(), &end, 10);
      if (!ok || !digits(b) || *end != '\0')
        throw Error("launch_ref " + quoted(s) + " is not INSTANCE:TRIANGLE");
      // A reference word holds a 16-bit triangle index and an instance below 0xFFFF (no instance)
      if (inst > 0xFFFEu || tri > 0xFFFFu)
        throw Error("launch_ref " + quoted(s) + " is out of range: a reference holds an instance of at most 65534 "
                    "and a triangle of at most 65535");
      r.launch_ref = uint32_t(inst << 16 | tri);
    } else {
      const unsigned long long v = std::strtoull(s.c_str(), &end, 0);
      const bool unsigned_text = !s.empty() && s.find_first_of("+- \t") == std::string::npos;
      if (!unsigned_text || *end != '\0' || v > 0xFFFFFFFFull)
        throw Error("launch_ref " + quoted(s) + " is not a reference (a number, 0x hex, INSTANCE:TRIANGLE or none)");
      r.launch_ref = uint32_t(v);
    }
  }
  return r;
}

// The most rays a ray file holds.
constexpr size_t kMaxRayFileRays = 1000000;

std::vector<Ray> read_ray_file(const std::string& path) {
  // Read as every input is (a regular file within --max-input-mib: not /dev/zero, a FIFO or a
  // folder), with the text formats' one line-break rule
  const std::string text = normalize_text(read_input_file(path, "ray file"));
  // A NUL byte would end a number early where it is parsed (strtof stops at it): refused, named
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    throw Error(path + ": line " + std::to_string(1 + std::count(text.begin(), text.begin() + long(nul), '\n')) +
                ": a NUL byte (a ray file is text)");
  std::istringstream f(text);
  std::vector<Ray> rays;
  std::string line;
  for (size_t n = 1; std::getline(f, line); ++n) {
    const size_t hash = line.find('#');
    if (hash != std::string::npos) line.resize(hash);
    if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
    // explain is for the rays one reads: a bound, so that a huge file fails named (each ray kept
    // takes about 0.6 KiB before any is traced); verify and bench take many rays
    if (rays.size() == kMaxRayFileRays)
      throw Error(path + ":" + std::to_string(n) + ": more than " + std::to_string(kMaxRayFileRays) +
                  " rays in a ray file (explain is for the rays one reads; split the file)");
    try {
      rays.push_back(parse_ray(line));
    } catch (const Error& e) {
      throw Error(path + ":" + std::to_string(n) + ": " + e.what());
    }
  }
  if (rays.empty()) throw Error("ray file '" + path + "' holds no ray");
  return rays;
}

size_t visit_of(const ExplainRecord& rec, size_t i) {
  if (rec.events.empty()) return kNoEvent;
  for (size_t k = std::min(i, rec.events.size() - 1) + 1; k-- > 0;)
    if (rec.events[k].kind == kEvCell || rec.events[k].kind == kEvCellSkipped || rec.events[k].kind == kEvSkip)
      return k;  // a skip step is a visit too (a divergence inside a run of them was placed before it)
  return kNoEvent;
}

std::string visit_text(const ExplainRecord& rec, size_t i) {
  if (rec.events.empty()) return "before the first cell";
  const size_t v = visit_of(rec, i);
  if (v == kNoEvent) return "before the first cell";
  const ExplainEvent& e = rec.events[v];
  return std::string(is_exact(rec) ? "step " : "segment ") + std::to_string(e.step) + ", cell " + cellstr(e.cell) +
         " (event #" + std::to_string(v) + ")";
}

// ---- Alignment ----------------------------------------------------------------------------------

namespace {

struct EventKey {
  uint32_t kind, step, x, y, z, slot;
  bool operator==(const EventKey&) const = default;
};
EventKey key_of(const ExplainEvent& e) {
  // The ray, its setup and the end of the traversal: by kind alone (a hit reported one step
  // later is the same event, differing in its step)
  if (e.kind == kEvRay || e.kind == kEvSetup || e.kind == kEvRejected || e.kind == kEvReport || e.kind == kEvMiss)
    return {e.kind == kEvMiss ? kEvReport : e.kind, 0, 0, 0, 0, 0};
  return {e.kind, e.step, e.cell.x, e.cell.y, e.cell.z, e.slot};
}
bool same_bits(const ExplainEvent& a, const ExplainEvent& b) { return std::memcmp(&a, &b, sizeof a) == 0; }

}  // namespace

size_t EventAlignment::differing_rows() const {
  return size_t(std::count_if(rows.begin(), rows.end(), [](const Row& r) { return !r.same; }));
}

EventAlignment align_events(std::span<const ExplainEvent> a, std::span<const ExplainEvent> b) {
  EventAlignment out;
  const size_t n = a.size(), m = b.size();
  // The common prefix and suffix by key
  size_t pre = 0;
  while (pre < n && pre < m && key_of(a[pre]) == key_of(b[pre])) ++pre;
  size_t suf = 0;
  while (suf < n - pre && suf < m - pre && key_of(a[n - 1 - suf]) == key_of(b[m - 1 - suf])) ++suf;
  const size_t an = n - pre - suf, bm = m - pre - suf;
  std::vector<std::pair<size_t, size_t>> pairs;  // matched (i, j) in the middle, in order
  // The longest common subsequence of the middle's keys (a table of an+1 by bm+1 lengths); past
  // kMaxCells table entries the middle is set side by side in order
  constexpr size_t kMaxCells = size_t(1) << 24;
  if (an > 0 && bm > 0 && (an + 1) * (bm + 1) <= kMaxCells) {
    std::vector<uint32_t> L((an + 1) * (bm + 1), 0u);
    auto at = [&](size_t i, size_t j) -> uint32_t& { return L[i * (bm + 1) + j]; };
    for (size_t i = an; i-- > 0;)
      for (size_t j = bm; j-- > 0;)
        at(i, j) = key_of(a[pre + i]) == key_of(b[pre + j]) ? at(i + 1, j + 1) + 1u
                                                            : std::max(at(i + 1, j), at(i, j + 1));
    size_t i = 0, j = 0;
    while (i < an && j < bm) {
      if (key_of(a[pre + i]) == key_of(b[pre + j])) {
        pairs.push_back({pre + i, pre + j});
        ++i;
        ++j;
      } else if (at(i + 1, j) >= at(i, j + 1)) {
        ++i;
      } else {
        ++j;
      }
    }
  }
  // Rows: the prefix, the middle (unmatched runs between matches side by side), the suffix
  auto push = [&](size_t i, size_t j) {
    EventAlignment::Row r{i, j, i != kNoEvent && j != kNoEvent && same_bits(a[i], b[j])};
    out.rows.push_back(r);
  };
  for (size_t k = 0; k < pre; ++k) push(k, k);
  size_t i = pre, j = pre;
  pairs.push_back({n - suf, m - suf});  // the end of the middle as a sentinel
  for (const auto& [pi, pj] : pairs) {
    while (i < pi || j < pj) {
      push(i < pi ? i : kNoEvent, j < pj ? j : kNoEvent);
      if (i < pi) ++i;
      if (j < pj) ++j;
    }
    if (pi < n - suf || pj < m - suf) push(pi, pj);
    i = pi + 1;
    j = pj + 1;
  }
  for (size_t k = 0; k < suf; ++k) push(n - suf + k, m - suf + k);
  for (size_t r = 0; r < out.rows.size(); ++r)
    if (!out.rows[r].same) {
      out.first_divergence = r;
      break;
    }
  return out;
}

std::vector<std::string> differing_fields(const ExplainEvent& a, const ExplainEvent& b, bool exact) {
  const std::vector<EventField> names = event_fields(a.kind, exact);
  auto label = [&](size_t k) {
    return std::string(names[k].field) + (*names[k].name && std::strcmp(names[k].name, names[k].field) != 0
                                              ? std::string(" (") + names[k].name + ")"
                                              : "");
  };
  std::vector<std::string> out;
  if (a.kind != b.kind) return {"kind"};
  const uint32_t ua[5] = {a.code, a.ref, a.step, 0, a.slot}, ub[5] = {b.code, b.ref, b.step, 0, b.slot};
  for (size_t k = 0; k < 5; ++k)
    if (k == 3 ? a.cell != b.cell : ua[k] != ub[k]) out.push_back(label(k + 1));
  const float fa[8] = {a.f0.x, a.f0.y, a.f0.z, a.f0.w, a.f1.x, a.f1.y, a.f1.z, a.f1.w};
  const float fb[8] = {b.f0.x, b.f0.y, b.f0.z, b.f0.w, b.f1.x, b.f1.y, b.f1.z, b.f1.w};
  for (size_t k = 0; k < 8; ++k)
    if (std::memcmp(&fa[k], &fb[k], sizeof(float)) != 0) out.push_back(label(k + 6));
  return out;
}

std::vector<std::string> differing_hit_fields(const Hit& a, const Hit& b) {
  std::vector<std::string> out;
  auto f = [&](const char* name, const void* x, const void* y) {
    if (std::memcmp(x, y, 4) != 0) out.push_back(name);
  };
  f("t", &a.t, &b.t);
  f("instance", &a.instance, &b.instance);
  f("triangle", &a.triangle, &b.triangle);
  f("u", &a.u, &b.u);
  f("v", &a.v, &b.v);
  f("flags", &a.flags, &b.flags);
  f("cells", &a.cells, &b.cells);
  f("tests", &a.tests, &b.tests);
  return out;
}

namespace {

// One field of an event as "value" (full: with hex bits).
std::string field_value(const ExplainEvent& e, const std::string& field, const ExplainFormat& fmt) {
  const std::string f = field.substr(0, field.find(' '));
  auto fl = [&](glm::vec4 v, char c) { return num(c == 'x' ? v.x : c == 'y' ? v.y : c == 'z' ? v.z : v.w, fmt); };
  if (f == "kind") return event_kind_name(e.kind);
  if (f == "code") {
    const std::string n = event_code_name(e.kind, e.code);
    return std::to_string(e.code) + (n.empty() ? "" : " " + n);
  }
  if (f == "ref") return reference_text(e.ref, fmt);
  if (f == "step") return std::to_string(e.step);
  if (f == "cell") return cellstr(e.cell);
  if (f == "slot") return std::to_string(e.slot);
  if (f.size() == 4 && f[0] == 'f') return fl(f[1] == '0' ? e.f0 : e.f1, f[3]);
  return "?";
}

std::string pad(const std::string& s, size_t w) {
  if (s.size() > w) return s.substr(0, w - 3) + "...";
  return s + std::string(w - s.size(), ' ');
}

std::string hit_text(const Hit& h, const ExplainFormat& fmt) {
  if (is_miss(h))
    return "miss" + std::string((h.flags & kHitRejected) ? " (rejected)" : "") + ", cells " +
           std::to_string(h.cells) + ", tests " + std::to_string(h.tests);
  return reference_text((h.instance << 16) | h.triangle, fmt) + ", t " + num(h.t, fmt) + ", u " + num(h.u, fmt) +
         ", v " + num(h.v, fmt) + ", flags " + std::to_string(h.flags) + ", cells " + std::to_string(h.cells) +
         ", tests " + std::to_string(h.tests);
}

}  // namespace

std::string divergence_text(const ExplainRecord& want, const ExplainRecord& got, const ExplainFormat& fmt,
                            const std::string& want_label, const std::string& got_label) {
  std::ostringstream os;
  const EventAlignment al = align_events(want.events, got.events);
  const bool same_hit = std::memcmp(&want.hit, &got.hit, sizeof(Hit)) == 0;
  if (al.first_divergence == kNoEvent && want.events.size() == got.events.size() && same_hit) {
    os << "identical: all " << want.events.size() << " events and the hit record agree bit for bit\n";
    return os.str();
  }
  const bool exact = is_exact(want);
  size_t only_a = 0, only_b = 0, changed = 0;
  for (const auto& r : al.rows) {
    only_a += r.b == kNoEvent;
    only_b += r.a == kNoEvent;
    changed += r.a != kNoEvent && r.b != kNoEvent && !r.same;
  }
  os << want_label << ": " << want.events.size() << " events, " << got_label << ": " << got.events.size()
     << " events; aligned over the events' keys (kind, step, cell, slot): " << changed << " differ, " << only_a
     << " only in the " << want_label << ", " << only_b << " only in the " << got_label << "\n";
  size_t context_row = 0;
  if (al.first_divergence != kNoEvent) {
    const auto& r = al.rows[al.first_divergence];
    os << "the " << got_label << " parts from the " << want_label << " at event "
       << (r.a != kNoEvent ? "#" + std::to_string(r.a) : std::string("-")) << " (" << want_label << "), "
       << (r.b != kNoEvent ? "#" + std::to_string(r.b) : std::string("-")) << " (" << got_label << "), in "
       << (r.a != kNoEvent ? visit_text(want, r.a) : visit_text(got, r.b)) << "\n";
    if (r.a != kNoEvent && r.b != kNoEvent) {
      const std::vector<std::string> d = differing_fields(want.events[r.a], got.events[r.b], exact);
      os << "differing fields:";
      for (size_t k = 0; k < d.size(); ++k) os << (k ? ", " : " ") << d[k];
      os << "\n";
    }
    // First-empty insertion keeps a cell's slots in arrival order, which differs between runs and
    // devices by design: a slot holding another reference is no port defect (gridrt diff compares
    // such cells as sets; an outside sweep read this as a divergence)
    if (want.params.insertion == shared::kInsertFirstEmpty)
      os << "note: first-empty insertion (the paper's) fills a cell's slots in arrival order, which differs "
            "between runs and devices by design (docs/SPEC.md \"Scene build\"): events that differ in a slot's "
            "reference, and what follows from them, are expected; the hit record "
         << (same_hit ? "agrees" : "differs") << "\n";
    // The rows shown start at the visit of the divergent event
    const size_t v = r.a != kNoEvent ? visit_of(want, r.a) : kNoEvent;
    context_row = al.first_divergence;
    if (v != kNoEvent)
      while (context_row > 0 && (al.rows[context_row].a == kNoEvent || al.rows[context_row].a > v)) --context_row;
  } else {
    os << "every event agrees; the hit records differ\n";
    context_row = al.rows.size();
  }
  // Side by side; the differing fields always with their bits
  constexpr size_t kColumn = 72;
  const ExplainFormat full{false, fmt.names};
  const int nw = int(std::to_string(std::max(want.events.size(), got.events.size())).size()) + 1;
  auto num_col = [&](size_t i) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%*s", nw, i == kNoEvent ? "-" : ("#" + std::to_string(i)).c_str());
    return std::string(buf);
  };
  os << "\n" << std::string(3 + size_t(nw) + 1, ' ') << pad(want_label, kColumn) << "   "
     << std::string(size_t(nw) + 1, ' ') << got_label << "\n";
  auto fold = [&](size_t from, size_t to) {  // rows [from, to) identical
    if (to <= from) return;
    const auto& f = al.rows[from];
    const auto& l = al.rows[to - 1];
    os << std::string(3, ' ') << "... events #" << f.a << "-#" << l.a << " identical (" << (to - from) << ")";
    if (f.a != f.b || l.a != l.b) os << " (" << got_label << " #" << f.b << "-#" << l.b << ")";
    os << "\n";
  };
  fold(0, context_row);
  size_t run_start = kNoEvent;
  for (size_t r = context_row; r <= al.rows.size(); ++r) {
    const bool same = r < al.rows.size() && al.rows[r].same;
    // Brief: runs of more than 4 identical rows after the divergence are folded
    if (fmt.brief && same) {
      if (run_start == kNoEvent) run_start = r;
      continue;
    }
    if (run_start != kNoEvent) {
      if (r - run_start > 4) {
        for (size_t k = run_start; k < run_start + 2; ++k)
          os << "   " << num_col(al.rows[k].a) << " " << pad(event_summary(want, al.rows[k].a, fmt), kColumn) << " = "
             << num_col(al.rows[k].b) << "\n";
        fold(run_start + 2, r);
      } else {
        for (size_t k = run_start; k < r; ++k)
          os << "   " << num_col(al.rows[k].a) << " " << pad(event_summary(want, al.rows[k].a, fmt), kColumn) << " = "
             << num_col(al.rows[k].b) << "\n";
      }
      run_start = kNoEvent;
    }
    if (r == al.rows.size()) break;
    const auto& row = al.rows[r];
    const std::string left = row.a != kNoEvent ? event_summary(want, row.a, fmt) : "(only in the " + got_label + ")";
    const std::string right = row.b != kNoEvent ? event_summary(got, row.b, fmt) : "(only in the " + want_label + ")";
    const char* mark = r == al.first_divergence ? ">> " : row.same ? "   " : "!  ";
    os << mark << num_col(row.a) << " " << pad(left, kColumn) << (row.same ? " = " : " | ") << num_col(row.b) << " "
       << (row.same ? "" : right) << "\n";
    if (!row.same && row.a != kNoEvent && row.b != kNoEvent) {
      for (const std::string& f : differing_fields(want.events[row.a], got.events[row.b], exact))
        os << std::string(size_t(nw) + 4, ' ') << "^ " << f << ": " << field_value(want.events[row.a], f, full)
           << " | " << field_value(got.events[row.b], f, full) << "\n";
    }
  }
  os << "\n" << want_label << " hit: " << hit_text(want.hit, fmt) << "\n"
     << got_label << " hit: " << hit_text(got.hit, fmt) << "\n";
  const std::vector<std::string> hd = differing_hit_fields(want.hit, got.hit);
  if (!hd.empty()) {
    os << "the hits differ in:";
    for (size_t k = 0; k < hd.size(); ++k) os << (k ? ", " : " ") << hd[k];
    os << "\n";
  } else {
    os << "the hits agree bit for bit\n";
  }
  return os.str();
}

nlohmann::json alignment_json(const ExplainRecord& want, const ExplainRecord& got, const EventAlignment& al) {
  using nlohmann::json;
  json rows = json::array();
  for (const auto& r : al.rows)
    rows.push_back({r.a == kNoEvent ? json(nullptr) : json(r.a), r.b == kNoEvent ? json(nullptr) : json(r.b), r.same});
  json out{{"rows", rows}, {"identical", al.first_divergence == kNoEvent && std::memcmp(&want.hit, &got.hit, sizeof(Hit)) == 0}};
  if (al.first_divergence != kNoEvent) {
    const auto& r = al.rows[al.first_divergence];
    json d{{"row", al.first_divergence},
           {"reference_event", r.a == kNoEvent ? json(nullptr) : json(r.a)},
           {"shader_event", r.b == kNoEvent ? json(nullptr) : json(r.b)},
           {"visit", r.a != kNoEvent ? visit_text(want, r.a) : visit_text(got, r.b)}};
    if (r.a != kNoEvent && r.b != kNoEvent)
      d["fields"] = differing_fields(want.events[r.a], got.events[r.b], is_exact(want));
    out["first_divergence"] = d;
  } else {
    out["first_divergence"] = nullptr;
  }
  out["hit_fields"] = differing_hit_fields(want.hit, got.hit);
  return out;
}

}  // namespace gridrt::plan
