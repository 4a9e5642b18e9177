// explain_export.cpp: an explained ray as OBJ, SVG and a self-contained HTML viewer
// (reference/explain_export.h).
#include "gridrt/reference/explain_export.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>

namespace gridrt::reference {

using namespace gridrt::shared;
using namespace gridrt::plan;

// The viewer's page (reference/explain_viewer.html, embedded at build time: explain_viewer.cpp.in)
extern const char* const kExplainViewerHtml;

namespace {

glm::vec3 at(const ExplainGeometry& g, float t) { return g.org + t * g.dir; }

std::string fmt(const char* f, double a) {
  char buf[64];
  std::snprintf(buf, sizeof buf, f, a);
  return buf;
}
std::string px(float v) { return fmt("%.2f", double(v)); }

// Escapes text for XML/HTML.
std::string xml(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '<': o += "&lt;"; break;
      case '>': o += "&gt;"; break;
      case '&': o += "&amp;"; break;
      case '"': o += "&quot;"; break;
      default: o += c;
    }
  }
  return o;
}

std::string ref_word(uint32_t ref) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "%08x", ref);
  return buf;
}

const char* triangle_class(const ExplainGeometry::Triangle& t) {
  if (t.hit) return "tri-hit";
  if (t.code == kTestAccepted || t.code == kTestTieLost) return "tri-accepted";
  if (t.code == kTestAlphaKeyed) return "tri-alpha";
  return "tri-rejected";
}

}  // namespace

ExplainGeometry explain_geometry(const ExplainRecord& rec, const GridData& grid) {
  ExplainGeometry g;
  const GridParams& p = rec.params;
  g.org = rec.ray.org;
  g.dir = rec.ray.dir;
  g.event_t.assign(rec.events.size(), std::nullopt);
  bool meets = false;
  float t_start = std::max(rec.ray.tmin, 0.0f), t_exit = t_start;
  std::map<uint32_t, size_t> tri_index;
  for (size_t i = 0; i < rec.events.size(); ++i) {
    const ExplainEvent& e = rec.events[i];
    switch (e.kind) {
      case kEvSetup:
        meets = e.slot != 0u;
        if (meets) {
          t_start = e.f0.y;
          t_exit = t_start;
        }
        break;
      case kEvCell: {
        ExplainGeometry::Cell c;
        c.cell = e.cell;
        c.lo = p.origin + glm::vec3(e.cell) * p.cell_size;
        c.hi = c.lo + glm::vec3(p.cell_size);
        c.event = i;
        c.step = e.step;
        c.empty = i + 1 < rec.events.size() && rec.events[i + 1].kind == kEvSlot && rec.events[i + 1].slot == 0u &&
                  rec.events[i + 1].ref == kBlank;
        g.cells.push_back(c);
        const float exit = e.f1.y;
        if (std::isfinite(exit)) t_exit = std::max(t_exit, exit);
        g.event_t[i] = p.traversal == kTraversalExact ? e.f1.x : e.f0.w;
        break;
      }
      case kEvCellSkipped: g.event_t[i] = e.f0.w; break;
      case kEvStatus:
      case kEvSpillScan:
        if ((e.kind == kEvSpillScan || e.code != 0u) && !g.cells.empty()) g.cells.back().saturated = true;
        break;
      case kEvTest: {
        if (e.code == kTestMailboxed) break;  // tested earlier on the ray: its first result stands
        if (e.code == kTestAccepted || e.code == kTestAlphaKeyed || e.code == kTestTieLost || e.code == kTestOriginPlane)
          g.event_t[i] = e.f1.w;
        auto it = tri_index.find(e.ref);
        if (it == tri_index.end()) {
          const uint32_t inst = ref_instance(e.ref), tri = ref_triangle(e.ref);
          if (inst >= grid.instances.size() || tri >= grid.instances[inst].tri_count) break;
          const GridTriangle& gt = grid.triangles[grid.instances[inst].tri_offset + tri];
          ExplainGeometry::Triangle t;
          t.ref = e.ref;
          t.v[0] = gt.v0;
          t.v[1] = gt.v1;
          t.v[2] = gt.v2;
          t.event = i;
          it = tri_index.emplace(e.ref, g.triangles.size()).first;
          g.triangles.push_back(t);
        }
        // Its decisive result, not its last: a triangle accepted once (the best hit then, beaten
        // later) stays accepted, though the next cell's retest says not-closer (it was drawn
        // rejected: an outside sweep); the launch triangle's self-hit skips are no tests (the
        // footer's count leaves them out)
        ExplainGeometry::Triangle& t = g.triangles[it->second];
        const auto rank = [](uint32_t c) {
          return c == kTestAccepted ? 3 : c == kTestTieLost ? 2 : c == kTestAlphaKeyed ? 1 : 0;
        };
        if (t.tests == 0u || rank(e.code) > rank(t.code)) t.code = e.code;
        if (e.code != kTestSelfHit) t.tests += 1u;
        break;
      }
      case kEvCandidate: g.event_t[i] = e.f0.x; break;
      case kEvGapFill: g.event_t[i] = e.f0.z; break;
      case kEvReport: {
        g.event_t[i] = e.f0.x;
        g.hit_point = at(g, e.f0.x);
        g.gap_fill = (e.code & kHitGapFill) != 0u;
        // A gap-fill hit is the cell's voxel, not its last reference's triangle, which the ray may
        // miss: that triangle keeps its own test's result (it was drawn as "the hit triangle")
        auto it = tri_index.find(e.ref);
        if (it != tri_index.end() && !g.gap_fill) g.triangles[it->second].hit = true;
        break;
      }
      default: break;
    }
  }
  // The part of the ray drawn: the grid box's entry to the hit (or the last cell's exit)
  const glm::vec3 diag = p.upper - p.origin;
  const float len = glm::length(g.dir) > 0.0f ? glm::length(diag) / glm::length(g.dir) : 1.0f;
  g.t_begin = t_start;
  g.t_end = g.hit_point ? std::max(t_start, rec.hit.t) : (t_exit > t_start ? t_exit : t_start + (meets ? 0.0f : len));
  if (g.t_end > rec.ray.tmax) g.t_end = std::max(t_start, rec.ray.tmax);  // a shadow ray ends at its light
  if (!std::isfinite(g.t_end)) g.t_end = t_start + len;
  if (!std::isfinite(g.t_begin)) g.t_begin = 0.0f;
  return g;
}

std::string explain_mtl() {
  return "# gridrt explain: one material per kind of element\n"
         "newmtl ray\nKd 1 0.1 0.1\nKa 1 0.1 0.1\n\n"
         "newmtl cells_empty\nKd 0.7 0.7 0.7\nd 0.15\n\n"
         "newmtl cells_with_references\nKd 0.2 0.45 1\nd 0.3\n\n"
         "newmtl cells_saturated\nKd 1 0.55 0\nd 0.4\n\n"
         "newmtl triangles_rejected\nKd 0.55 0.55 0.55\n\n"
         "newmtl triangles_accepted\nKd 0.1 0.8 0.2\n\n"
         "newmtl hit_triangle\nKd 0 1 0.3\n\n"
         "newmtl hit_point\nKd 1 0 0\n\n"
         "newmtl gap_fill_point\nKd 1 0.63 0\n";
}

std::string explain_obj(const ExplainRecord& rec, const GridData& grid, const std::string& mtl_name) {
  const ExplainGeometry g = explain_geometry(rec, grid);
  std::ostringstream os;
  os.precision(9);
  os << "# gridrt explain: the ray, the cells it visited (boxes), the triangles it tested, the hit\n";
  os << "# ray org (" << g.org.x << ", " << g.org.y << ", " << g.org.z << ") dir (" << g.dir.x << ", " << g.dir.y
     << ", " << g.dir.z << ")\n";
  if (!mtl_name.empty()) os << "mtllib " << mtl_name << "\n";
  size_t vertices = 0;
  auto v = [&](glm::vec3 p) {
    os << "v " << p.x << " " << p.y << " " << p.z << "\n";
    return ++vertices;
  };
  auto group = [&](const char* name) { os << "g " << name << "\nusemtl " << name << "\n"; };
  // The ray as a line from its origin to the hit (or the grid's exit); a ray that is not finite
  // (rejected: a NaN or infinite origin or direction) has no line (OBJ readers refuse nan)
  const glm::vec3 end = at(g, g.t_end);
  const auto finite = [](glm::vec3 p) { return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z); };
  if (finite(g.org) && finite(end)) {
    group("ray");
    const size_t a = v(g.org), b = v(end);
    os << "l " << a << " " << b << "\n";
  } else {
    os << "# the ray has no finite segment to draw (rejected, or it leaves to infinity)\n";
  }
  // The visited cells as boxes, one group per kind
  for (const char* kind : {"cells_empty", "cells_with_references", "cells_saturated"}) {
    bool opened = false;
    for (const ExplainGeometry::Cell& c : g.cells) {
      const char* k = c.saturated ? "cells_saturated" : c.empty ? "cells_empty" : "cells_with_references";
      if (std::string(k) != kind) continue;
      if (!opened) group(kind);
      opened = true;
      os << "# step " << c.step << ", cell (" << c.cell.x << ", " << c.cell.y << ", " << c.cell.z << "), event #"
         << c.event << "\n";
      size_t i0 = 0;
      for (int k8 = 0; k8 < 8; ++k8) {
        const size_t id = v(glm::vec3(k8 & 1 ? c.hi.x : c.lo.x, k8 & 2 ? c.hi.y : c.lo.y, k8 & 4 ? c.hi.z : c.lo.z));
        if (k8 == 0) i0 = id;
      }
      static const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
      for (const auto& f : faces)
        os << "f " << i0 + size_t(f[0]) << " " << i0 + size_t(f[1]) << " " << i0 + size_t(f[2]) << " "
           << i0 + size_t(f[3]) << "\n";
    }
  }
  // The tested triangles by their result
  for (const char* kind : {"triangles_rejected", "triangles_accepted", "hit_triangle"}) {
    bool opened = false;
    for (const ExplainGeometry::Triangle& t : g.triangles) {
      const char* k = t.hit ? "hit_triangle"
                      : (t.code == kTestAccepted || t.code == kTestTieLost) ? "triangles_accepted"
                                                                            : "triangles_rejected";
      if (std::string(k) != kind) continue;
      if (!opened) group(kind);
      opened = true;
      os << "# instance " << ref_instance(t.ref) << ", triangle " << ref_triangle(t.ref) << ": "
         << event_code_name(kEvTest, t.code) << " (first tested at event #" << t.event << ")\n";
      const size_t i0 = v(t.v[0]);
      v(t.v[1]);
      v(t.v[2]);
      os << "f " << i0 << " " << i0 + 1 << " " << i0 + 2 << "\n";
    }
  }
  // The hit point: a small octahedron (a tenth of a cell) and a point
  if (g.hit_point) {
    if (g.gap_fill)
      os << "# a gap-fill hit: the paper traversal's voxel in a saturated cell, reported with the cell's last "
            "reference (a false hit: the ray need not meet that triangle)\n";
    group(g.gap_fill ? "gap_fill_point" : "hit_point");
    const float r = 0.1f * rec.params.cell_size;
    const glm::vec3 h = *g.hit_point;
    const size_t c = v(h);
    os << "p " << c << "\n";
    const size_t i0 = v(h + glm::vec3(r, 0, 0));
    v(h - glm::vec3(r, 0, 0));
    v(h + glm::vec3(0, r, 0));
    v(h - glm::vec3(0, r, 0));
    v(h + glm::vec3(0, 0, r));
    v(h - glm::vec3(0, 0, r));
    static const int faces[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
    for (const auto& f : faces)
      os << "f " << i0 + size_t(f[0]) << " " << i0 + size_t(f[1]) << " " << i0 + size_t(f[2]) << "\n";
  }
  return os.str();
}

glm::vec2 ExplainProjection::map(glm::vec3 p) const {
  return {margin + (p[u] - lo.x) * scale, margin + height - (p[v] - lo.y) * scale};
}

ExplainProjection explain_projection(const ExplainGeometry& g, float max_size) {
  ExplainProjection pr;
  // Drop the axis along which the ray runs least
  const glm::vec3 ad = glm::abs(g.dir);
  const int drop = ad.x <= ad.y && ad.x <= ad.z ? 0 : ad.y <= ad.z ? 1 : 2;
  pr.u = drop == 0 ? 1 : 0;
  pr.v = drop == 2 ? 1 : 2;
  // Bounds: the visited cells and the drawn part of the ray
  glm::vec2 lo(std::numeric_limits<float>::infinity()), hi(-std::numeric_limits<float>::infinity());
  auto grow = [&](glm::vec3 p) {
    const glm::vec2 q(p[pr.u], p[pr.v]);
    if (!std::isfinite(q.x) || !std::isfinite(q.y)) return;
    lo = glm::min(lo, q);
    hi = glm::max(hi, q);
  };
  for (const auto& c : g.cells) {
    grow(c.lo);
    grow(c.hi);
  }
  grow(at(g, g.t_begin));
  grow(at(g, g.t_end));
  if (!(lo.x <= hi.x)) lo = hi = glm::vec2(0.0f);
  const glm::vec2 ext = glm::max(hi - lo, glm::vec2(1e-6f));
  const glm::vec2 pad = 0.05f * glm::vec2(std::max(ext.x, ext.y));
  pr.lo = lo - pad;
  const glm::vec2 size = ext + 2.0f * pad;
  pr.scale = max_size / std::max(size.x, size.y);
  pr.width = size.x * pr.scale;
  pr.height = size.y * pr.scale;
  return pr;
}

namespace {

// The SVG's drawing (without the <svg> element), shared by the standalone file and the viewer.
std::string svg_body(const ExplainRecord& rec, const ExplainGeometry& g, const ExplainProjection& pr) {
  const GridParams& p = rec.params;
  std::ostringstream os;
  const char axis[3] = {'x', 'y', 'z'};
  // Grid lines over the picture (where they are not too dense)
  const float world_w = pr.width / pr.scale, world_h = pr.height / pr.scale;
  if (p.cell_size * pr.scale >= 4.0f) {
    os << "<g class=\"gridlines\">\n";
    const float cs = p.cell_size;
    for (int dim = 0; dim < 2; ++dim) {
      const int ax = dim == 0 ? pr.u : pr.v;
      const float lo = dim == 0 ? pr.lo.x : pr.lo.y, hi = lo + (dim == 0 ? world_w : world_h);
      // The grid's planes by index, 0 .. cells, that fall in the picture (a float stepped by the
      // cell size stood still where its half-ulp passed the cell size, a picture 3e7 from the
      // origin, and the loop never ended: an outside sweep)
      const double k_lo = std::max(0.0, std::ceil((double(lo) - p.origin[ax]) / cs));
      const double k_hi = std::min(double(p.cells[ax]), std::floor((double(hi) - p.origin[ax]) / cs));
      if (!(k_lo <= k_hi)) continue;  // no plane in the picture (NaN included)
      for (uint32_t k = uint32_t(k_lo); k <= uint32_t(k_hi); ++k) {
        const float w = p.origin[ax] + float(k) * cs;
        glm::vec3 a(0.0f), b(0.0f);
        a[ax] = b[ax] = w;
        const int other = dim == 0 ? pr.v : pr.u;
        a[other] = std::max(p.origin[other], dim == 0 ? pr.lo.y : pr.lo.x);
        b[other] = std::min(p.upper[other], (dim == 0 ? pr.lo.y + world_h : pr.lo.x + world_w));
        const glm::vec2 sa = pr.map(a), sb = pr.map(b);
        os << "<line x1=\"" << px(sa.x) << "\" y1=\"" << px(sa.y) << "\" x2=\"" << px(sb.x) << "\" y2=\"" << px(sb.y)
           << "\"/>\n";
      }
    }
    os << "</g>\n";
  }
  // The visited cells
  os << "<g class=\"cells\">\n";
  for (const auto& c : g.cells) {
    const glm::vec2 a = pr.map(c.lo), b = pr.map(c.hi);
    os << "<rect id=\"cell-" << c.event << "\" class=\"cell " << (c.saturated ? "cell-saturated" : c.empty ? "cell-empty" : "cell-refs")
       << "\" x=\"" << px(std::min(a.x, b.x)) << "\" y=\"" << px(std::min(a.y, b.y)) << "\" width=\""
       << px(std::abs(b.x - a.x)) << "\" height=\"" << px(std::abs(b.y - a.y)) << "\"><title>"
       << (p.traversal == kTraversalExact ? "step " : "segment ") << c.step << ": cell (" << c.cell.x << ", "
       << c.cell.y << ", " << c.cell.z << "), event #" << c.event << "</title></rect>\n";
  }
  os << "</g>\n";
  // The tested triangles
  os << "<g class=\"triangles\">\n";
  for (const auto& t : g.triangles) {
    os << "<polygon id=\"tri-" << ref_word(t.ref) << "\" class=\"tri " << triangle_class(t) << "\" points=\"";
    for (int k = 0; k < 3; ++k) {
      const glm::vec2 s = pr.map(t.v[k]);
      os << (k ? " " : "") << px(s.x) << "," << px(s.y);
    }
    os << "\"><title>instance " << ref_instance(t.ref) << ", triangle " << ref_triangle(t.ref) << ": "
       << event_code_name(kEvTest, t.code) << " (" << t.tests << " test" << (t.tests == 1 ? "" : "s")
       << ", first at event #" << t.event << ")</title></polygon>\n";
  }
  os << "</g>\n";
  // The ray, its paper samples and the hit
  // (a ray with NaN or inf values has no line)
  const glm::vec2 r0 = pr.map(g.org), r1 = pr.map(at(g, g.t_end)), rb = pr.map(at(g, g.t_begin));
  auto line = [&](const char* id, glm::vec2 a, glm::vec2 b) {
    if (!std::isfinite(a.x + a.y + b.x + b.y)) return;
    os << "<line id=\"" << id << "\" class=\"" << id << "\" x1=\"" << px(a.x) << "\" y1=\"" << px(a.y) << "\" x2=\""
       << px(b.x) << "\" y2=\"" << px(b.y) << "\"/>\n";
  };
  line("ray-outside", r0, rb);
  line("ray", rb, r1);
  if (p.traversal != kTraversalExact)
    for (const auto& c : g.cells)
      if (const auto& t = g.event_t[c.event]) {
        const glm::vec2 s = pr.map(at(g, *t));
        os << "<circle class=\"sample\" cx=\"" << px(s.x) << "\" cy=\"" << px(s.y) << "\" r=\"2.5\"/>\n";
      }
  if (g.hit_point) {
    const glm::vec2 h = pr.map(*g.hit_point);
    os << "<circle id=\"hit\" class=\"hit" << (g.gap_fill ? " hit-gap-fill" : "") << "\" cx=\"" << px(h.x)
       << "\" cy=\"" << px(h.y) << "\" r=\"5\"><title>" << (g.gap_fill ? "gap-fill hit" : "hit") << " at t "
       << fmt("%.7g", double(rec.hit.t)) << "</title></circle>\n";
  }
  // The axes
  const float W = pr.width + 2 * pr.margin, H = pr.height + 2 * pr.margin;
  os << "<text class=\"axis\" x=\"" << px(W - pr.margin) << "\" y=\"" << px(H - 8) << "\" text-anchor=\"end\">"
     << axis[pr.u] << " &#8594;</text>\n";
  os << "<text class=\"axis\" x=\"8\" y=\"" << px(pr.margin - 8) << "\">" << axis[pr.v] << " &#8593;</text>\n";
  return os.str();
}

const char* kSvgStyle =
    ".gridlines line{stroke:#d0d0d0;stroke-width:0.5}"
    ".cell{stroke:#506070;stroke-width:0.6}"
    ".cell-empty{fill:#e8e8e8;fill-opacity:0.5}"
    ".cell-refs{fill:#6a9cff;fill-opacity:0.35}"
    ".cell-saturated{fill:#ff9a20;fill-opacity:0.5}"
    ".tri{fill-opacity:0.25;stroke-width:1}"
    ".tri-rejected{fill:#909090;stroke:#606060}"
    ".tri-accepted{fill:#30c050;stroke:#209040}"
    ".tri-alpha{fill:#b060d0;stroke:#8040a0}"
    ".tri-hit{fill:#00e060;stroke:#008030;stroke-width:2.5;fill-opacity:0.45}"
    ".ray{stroke:#e01010;stroke-width:2}"
    ".ray-outside{stroke:#e01010;stroke-width:1;stroke-dasharray:4 3}"
    ".sample{fill:#202020}"
    ".hit{fill:#ff0000;stroke:#000;stroke-width:1}"
    ".hit-gap-fill{fill:#ffa000}"
    ".axis,.legend text{font:12px sans-serif;fill:#303030}";

}  // namespace

std::string explain_svg(const ExplainRecord& rec, const GridData& grid, const ExplainFormat& format) {
  const ExplainGeometry g = explain_geometry(rec, grid);
  const ExplainProjection pr = explain_projection(g);
  const float W = pr.width + 2 * pr.margin, H = pr.height + 2 * pr.margin;
  const float legend_h = 7 * 18 + 30;
  std::ostringstream os;
  os << "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" << px(W + 240) << "\" height=\""
     << px(std::max(H, legend_h)) << "\" viewBox=\"0 0 " << px(W + 240) << " " << px(std::max(H, legend_h)) << "\">\n";
  os << "<style>" << kSvgStyle << "</style>\n";
  os << "<rect x=\"0\" y=\"0\" width=\"" << px(W + 240) << "\" height=\"" << px(std::max(H, legend_h))
     << "\" fill=\"#ffffff\"/>\n";
  os << "<svg x=\"0\" y=\"0\" width=\"" << px(W) << "\" height=\"" << px(H) << "\" overflow=\"hidden\">\n"
     << svg_body(rec, g, pr) << "</svg>\n";
  // Legend
  os << "<g class=\"legend\" transform=\"translate(" << px(W + 10) << ",20)\">\n";
  const std::pair<const char*, const char*> items[] = {{"cell cell-empty", "cell visited, empty"},
                                                       {"cell cell-refs", "cell visited, references"},
                                                       {"cell cell-saturated", "cell visited, saturated"},
                                                       {"tri tri-rejected", "triangle tested, rejected"},
                                                       {"tri tri-accepted", "triangle accepted"},
                                                       {"tri tri-hit", "the hit triangle"},
                                                       {"hit", g.gap_fill ? "gap-fill hit (a voxel, no triangle)" : "hit point"}};
  float y = 0.0f;
  for (const auto& [cls, text] : items) {
    if (std::string(cls) == "hit")
      os << "<circle class=\"hit" << (g.gap_fill ? " hit-gap-fill" : "") << "\" cx=\"7\" cy=\"" << px(y + 6)
         << "\" r=\"5\"/>";
    else
      os << "<rect class=\"" << cls << "\" x=\"0\" y=\"" << px(y) << "\" width=\"14\" height=\"12\"/>";
    os << "<text x=\"20\" y=\"" << px(y + 11) << "\">" << text << "</text>\n";
    y += 18.0f;
  }
  os << "<line class=\"ray\" x1=\"0\" y1=\"" << px(y + 6) << "\" x2=\"14\" y2=\"" << px(y + 6) << "\"/><text x=\"20\" y=\""
     << px(y + 11) << "\">the ray (dashed: outside the grid)</text>\n";
  y += 24.0f;
  const char axis[3] = {'x', 'y', 'z'};
  os << "<text x=\"0\" y=\"" << px(y + 11) << "\">projection onto " << axis[pr.u] << axis[pr.v] << ", "
     << g.cells.size() << " cells, " << g.triangles.size() << " triangles</text>\n";
  os << "<text x=\"0\" y=\"" << px(y + 29) << "\">"
     << xml(is_miss(rec.hit) ? std::string("miss")
                             : std::string(g.gap_fill ? "gap-fill hit (false hit) reported as " : "hit: ") +
                                   reference_text((rec.hit.instance << 16) | rec.hit.triangle,
                                                  ExplainFormat{true, format.names}))
     << "</text>\n";
  os << "</g>\n</svg>\n";
  return os.str();
}

nlohmann::json explain_view(const std::string& label, const std::vector<std::string>& header,
                            const ExplainRecord& want, const ExplainRecord* got, const GridData& grid,
                            const ExplainFormat& format) {
  using nlohmann::json;
  const ExplainGeometry g = explain_geometry(want, grid);
  const ExplainProjection pr = explain_projection(g, 560.0f);
  json view;
  view["label"] = label;
  view["header"] = header;
  view["grid"] = grid_text(want.params, ExplainFormat{true, format.names});
  const float W = pr.width + 2 * pr.margin, H = pr.height + 2 * pr.margin;
  view["svg"] = "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"" + px(W) + "\" height=\"" + px(H) +
                "\" viewBox=\"0 0 " + px(W) + " " + px(H) + "\"><style>" + kSvgStyle + "</style>" +
                svg_body(want, g, pr) + "<circle id=\"marker\" cx=\"-100\" cy=\"-100\" r=\"6\"/></svg>";
  auto record = [&](const ExplainRecord& rec) {
    const ExplainGeometry rg = explain_geometry(rec, grid);
    json j = explain_json(rec, format);
    for (size_t i = 0; i < rec.events.size(); ++i) {
      // The point along the ray each event concerns (the visit's, where it names none)
      std::optional<float> t = rg.event_t[i];
      if (!t) {
        const size_t v = visit_of(rec, i);
        if (v != kNoEvent) t = rg.event_t[v];
      }
      if (t && std::isfinite(*t)) {
        const glm::vec2 s = pr.map(at(rg, *t));
        j["events"][i]["xy"] = {s.x, s.y};
      }
      j["events"][i]["lines"] = event_lines(rec, i, ExplainFormat{false, format.names});
    }
    return j;
  };
  view["reference"] = record(want);
  if (got) {
    view["shader"] = record(*got);
    view["alignment"] = alignment_json(want, *got, align_events(want.events, got->events));
  } else {
    view["shader"] = nullptr;
    view["alignment"] = nullptr;
  }
  return view;
}

std::string explain_html(const std::string& title, const nlohmann::json& views) {
  std::string page = kExplainViewerHtml;
  // The data as JSON inside a script element: every '<' and '>' written as \u003c and \u003e (the
  // same strings in JSON; they occur in strings only). "</" alone was escaped, and a name holding
  // "<!--" then "<script" put the page's own </script> inside the script (an outside sweep)
  std::string data = nlohmann::json{{"title", title}, {"views", views}}.dump(-1, ' ', false,
                                                                             nlohmann::json::error_handler_t::replace);
  std::string safe;
  safe.reserve(data.size());
  for (const char c : data) {
    if (c == '<') safe += "\\u003c";
    else if (c == '>') safe += "\\u003e";
    else safe += c;
  }
  const std::string data_mark = "/*GRIDRT_DATA*/null", title_mark = "<!--GRIDRT_TITLE-->";
  for (size_t t = page.find(title_mark); t != std::string::npos; t = page.find(title_mark, t)) {
    page.replace(t, title_mark.size(), xml(title));
    t += xml(title).size();
  }
  const size_t d = page.find(data_mark);
  if (d == std::string::npos) throw Error("explain viewer: the page template has no data mark");
  page.replace(d, data_mark.size(), safe);
  return page;
}

}  // namespace gridrt::reference
