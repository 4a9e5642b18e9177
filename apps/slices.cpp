// gridrt stats --slices DIR: the grid's occupancy and saturation slice by slice, as one contact
// sheet (DIR/occupancy.png): a panel per slice along an axis, each cell coloured by the references
// its slots hold (viridis, 1 .. capacity), empty cells light, saturated cells (a reference found no
// slot: the status texel's bits) red for static, magenta for dynamic references; cells holding a
// moving (dynamic) instance's references outlined orange.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <unordered_map>

#include "apps/commands.h"
#include "apps/slices.h"
#include "gridrt/common/plot.h"
#include "gridrt/common/safe_io.h"

namespace gridrt::app {

namespace sh = gridrt::shared;

namespace {

// The sheet's layout: slice axis a; each panel shows axis u to the right and axis v up.
struct SliceLayout {
  int a, u, v;
  uint32_t ns, nu, nv;    // slices, cells along u and v
  uint32_t cols, rows;    // panels per row, rows of panels
  int cell_px, pw, ph;    // a cell's pixels, a panel's size
  int title_h, pad;
  static constexpr int gap = 10, label_h = 16;

  SliceLayout(const sh::GridParams& g, char axis, bool with_ray) {
    a = axis == 'x' ? 0 : axis == 'y' ? 1 : 2;
    u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
    ns = g.cells[a], nu = g.cells[u], nv = g.cells[v];
    // Panel size: cells of at least 2 pixels, a sheet about 1100 pixels wide.
    cols = std::max(1u, std::min(ns, uint32_t(std::ceil(std::sqrt(double(ns) * double(nv) / double(nu))))));
    rows = (ns + cols - 1) / cols;
    cell_px = std::clamp(int(1000 / (cols * nu)), 2, 24);
    pw = int(nu) * cell_px, ph = int(nv) * cell_px;
    title_h = with_ray ? 74 : 56, pad = 12;
  }
  // The top left corner of slice s's panel
  int panel_x(uint32_t s) const { return pad + int(s % cols) * (pw + gap); }
  int panel_y(uint32_t s) const { return title_h + int(s / cols) * (ph + gap + label_h) + label_h; }
};

// Each cell's colour (references held, saturation) per slice, and which hold a moving instance.
struct SlicePanels {
  std::vector<std::vector<glm::vec3>> colour;
  std::vector<std::vector<uint8_t>> moving;
  bool any_moving = false;
  uint32_t largest = 0;  // the fullest cell's references
  uint32_t scale = 1;    // the colour bar's top: the capacity, or the fullest cell (compact)
  // Saturated cells by kind, as `stats` counts them (a cell saturated by both counts in both; it
  // is drawn red), and those of both kinds
  uint64_t empty = 0, saturated_static = 0, saturated_dynamic = 0, saturated_both = 0;
};

SlicePanels colour_cells(const reference::GridData& grid, const SliceLayout& l) {
  const sh::GridParams& g = grid.params;
  const uint32_t ns = l.ns, nu = l.nu, nv = l.nv;
  SlicePanels p;
  p.colour.assign(ns, std::vector<glm::vec3>(size_t(nu) * nv));
  p.moving.assign(ns, std::vector<uint8_t>(size_t(nu) * nv, 0));
  // The references neither slots nor runs hold: the spill list's entries per cell (the image
  // layout's overflow; the compact layout's dynamic references, which the sheet left out)
  std::unordered_map<uint32_t, std::vector<uint32_t>> spilled;
  const size_t stored = std::min<size_t>(grid.spill_header.count, grid.spill.size());
  for (size_t k = 0; k < stored; ++k) spilled[grid.spill[k].cell].push_back(grid.spill[k].ref);
  // The colour scale: the capacity, or with no slots (compact) the fullest cell
  const bool compact = (g.flags & sh::kGridCompact) != 0u;
  uint32_t scale = g.capacity;
  if (compact) {
    scale = 1;
    for (uint32_t s = 0; s < ns; ++s)
      for (uint32_t j = 0; j < nv; ++j)
        for (uint32_t i = 0; i < nu; ++i) {
          glm::uvec3 cell(0);
          cell[l.a] = s, cell[l.u] = i, cell[l.v] = j;
          const auto it = spilled.find(sh::cell_linear_index(g, cell));
          scale = std::max(scale, uint32_t(reference::cell_references(grid, cell).size() +
                                           (it == spilled.end() ? 0 : it->second.size())));
        }
  }
  p.scale = scale;
  for (uint32_t s = 0; s < ns; ++s)
    for (uint32_t j = 0; j < nv; ++j)
      for (uint32_t i = 0; i < nu; ++i) {
        glm::uvec3 cell(0);
        cell[l.a] = s, cell[l.u] = i, cell[l.v] = j;
        std::vector<uint32_t> refs = reference::cell_references(grid, cell);
        if (const auto it = spilled.find(sh::cell_linear_index(g, cell)); it != spilled.end())
          refs.insert(refs.end(), it->second.begin(), it->second.end());
        const uint32_t n = uint32_t(refs.size());
        for (uint32_t r : refs)
          if (r >= g.comparison_offset) p.moving[s][size_t(nv - 1 - j) * nu + i] = 1, p.any_moving = true;
        p.largest = std::max(p.largest, n);
        const uint32_t status = reference::cell_status(grid, cell);
        glm::vec3 c = n == 0 ? plot::colors::light_grey
                             : plot::viridis(scale > 1 ? std::min(1.0f, float(n - 1) / float(scale - 1)) : 1.0f);
        if (n == 0) ++p.empty;
        // The title counted a cell saturated by both as static only: 15 dynamic where `stats`
        // said 17 (a reviewer's find); now both count it, and the title says how many are both
        if (status & sh::kStatusStatic) c = plot::colors::red, ++p.saturated_static;
        else if (status & sh::kStatusDynamic) c = plot::colors::magenta;
        if (status & sh::kStatusDynamic) ++p.saturated_dynamic;
        if ((status & sh::kStatusStatic) && (status & sh::kStatusDynamic)) ++p.saturated_both;
        p.colour[s][size_t(nv - 1 - j) * nu + i] = c;  // v up
      }
  return p;
}

// The ray: its visited cells outlined, its samples as dots (in cell units from the origin); the
// number of cells it visits.
// The ray's cells read, outlined; returns how many, and in `skips` its skip steps over empty cells
// (a visit each in explain's and the hit record's count, not drawn).
size_t draw_ray(plot::Canvas& c, const SliceLayout& l, const sh::GridParams& g, const reference::ExplainRecord& ray,
                size_t& skips) {
  size_t visits = 0;
  skips = 0;
  for (const sh::ExplainEvent& e : ray.events) {
    skips += e.kind == sh::kEvSkip;
    if (e.kind != sh::kEvCell) continue;
    ++visits;
    const uint32_t s = e.cell[l.a];
    const int x = l.panel_x(s), y = l.panel_y(s);
    const int cx = x + int(e.cell[l.u]) * l.cell_px, cy = y + int(l.nv - 1 - e.cell[l.v]) * l.cell_px;
    c.frame(cx, cy, cx + l.cell_px, cy + l.cell_px, plot::colors::black);
    if (l.cell_px >= 6) c.frame(cx + 1, cy + 1, cx + l.cell_px - 1, cy + l.cell_px - 1, plot::colors::black);
    const glm::vec3 p = (glm::vec3(e.f0) - g.origin) / g.cell_size;  // sample / entry point
    const uint32_t ps = uint32_t(std::clamp(int(std::floor(p[l.a])), 0, int(l.ns) - 1));
    const int px = l.panel_x(ps) + int(std::lround(p[l.u] * float(l.cell_px)));
    const int py = l.panel_y(ps) + int(std::lround((float(l.nv) - p[l.v]) * float(l.cell_px)));
    c.marker(px, py, 2, plot::colors::black);
    c.marker(px, py, 1, plot::colors::white);
  }
  return visits;
}

}  // namespace

void check_slices_folder(const std::string& dir) {
  if (!is_folder(dir))
    throw Error("--slices: '" + dir + "' " +
                (std::filesystem::exists(dir) ? "is not a folder" : "does not exist (the folder is not made for you)"));
}

void write_slices(const reference::ReferenceGridTracer& ref, const std::string& scene_name, const std::string& dir,
                  char axis, const reference::ExplainRecord* ray, const std::string& ray_name) {
  if (!plot::available())
    throw Error("--slices needs OpenImageIO and the DejaVu fonts (Debian: libopenimageio-dev, fonts-dejavu-core)");
  check_slices_folder(dir);
  const reference::GridData& grid = ref.data();
  const sh::GridParams& g = grid.params;
  const SliceLayout l(g, axis, ray != nullptr);
  const char names[3] = {'x', 'y', 'z'};
  // The sheet's pixels count against --max-pixels before anything is drawn (a 4096x4096x2 grid
  // made a figure of 138 Mpixel, 6 GB: an outside sweep)
  {
    const uint64_t w = uint64_t(l.pad) + uint64_t(l.cols) * uint64_t(l.pw + l.gap) + 600;
    const uint64_t h = uint64_t(l.title_h) + uint64_t(l.rows) * uint64_t(l.ph + l.gap + l.label_h) + uint64_t(l.pad);
    if (w * h > frame_limits().max_pixels)
      throw Error("--slices: the figure of " + std::to_string(l.ns) + " slices of " + std::to_string(l.nu) + "x" +
                  std::to_string(l.nv) + " cells would be about " + std::to_string(w) + " x " + std::to_string(h) +
                  " pixels, more than the limit of " + std::to_string(frame_limits().max_pixels) +
                  " (--max-pixels): cut along another --slice-axis, or give a coarser grid");
  }
  const SlicePanels panels = colour_cells(grid, l);

  // The sheet: a title, a panel per slice, the colour bar and the legend
  const int pad = l.pad;
  const int side = 60 + plot::Canvas::text_width("outlined: holds a moving instance", 13);
  const int sheet_w = pad + int(l.cols) * (l.pw + l.gap) + side;
  const int sheet_h = l.title_h + int(l.rows) * (l.ph + l.gap + l.label_h) + pad;
  plot::Canvas c(uint32_t(std::max(sheet_w, 560)), uint32_t(std::max(sheet_h, l.title_h + 330)));
  char t[200];
  std::snprintf(t, sizeof t, "Occupancy and saturation, %c slices", names[l.a]);
  c.text(pad, 22, t, plot::colors::black, 16, plot::Align::left, true);
  const std::string layout = (g.flags & sh::kGridCompact) != 0u ? std::string("compact layout")
                                                                   : "cells of " + std::to_string(g.capacity) + " slots";
  const std::string both =
      panels.saturated_both ? " (" + std::to_string(panels.saturated_both) + " both, red)" : std::string();
  std::snprintf(t, sizeof t,
                "%s: %ux%ux%u %s; %llu empty, %llu saturated (static), %llu (dynamic)%s; fullest %u; "
                "panels: %c right, %c up",
                scene_name.c_str(), g.cells.x, g.cells.y, g.cells.z, layout.c_str(), (unsigned long long)panels.empty,
                (unsigned long long)panels.saturated_static, (unsigned long long)panels.saturated_dynamic, both.c_str(),
                panels.largest, names[l.u], names[l.v]);
  c.text(pad, 41, t, plot::colors::dark_grey, 12);
  for (uint32_t s = 0; s < l.ns; ++s) {
    const int x = l.panel_x(s), y = l.panel_y(s);
    std::snprintf(t, sizeof t, "%c = %u", names[l.a], s);
    c.text(x, y - 4, t, plot::colors::black, 11);
    c.image(x, y, l.nu, l.nv, panels.colour[s], l.cell_px);
    if (l.cell_px >= 4)
      for (uint32_t k = 0; k < l.nu * l.nv; ++k)
        if (panels.moving[s][k]) {
          const int cx = x + int(k % l.nu) * l.cell_px, cy = y + int(k / l.nu) * l.cell_px;
          c.frame(cx, cy, cx + l.cell_px, cy + l.cell_px, plot::colors::orange);
        }
    c.frame(x - 1, y - 1, x + l.pw + 1, y + l.ph + 1, plot::colors::grey);
  }
  if (ray) {
    size_t skips = 0;
    const size_t visits = draw_ray(c, l, g, *ray, skips);
    if (skips == 0)
      std::snprintf(t, sizeof t, "%s: %zu cells visited (outlined), %s (dots)", ray_name.c_str(), visits,
                    g.traversal == sh::kTraversalPaper ? "midpoint samples" : "entry points");
    else  // explain's count of visits: the cells read and the skip steps
      std::snprintf(t, sizeof t, "%s: %zu visits, %zu cells read (outlined) and %zu skip steps over empty cells; entry "
                    "points (dots)", ray_name.c_str(), visits + skips, visits, skips);
    c.text(pad, 60, t, plot::colors::black, 12);
  }
  const int sx = pad + int(l.cols) * (l.pw + l.gap) + 10;
  plot::draw_color_bar(c, sx, l.title_h + 24, 20, 180, {1.0f, float(std::max(panels.scale, 2u)), "references", true});
  plot::draw_legend(c, sx, l.title_h + 230,
                    {{plot::colors::light_grey, "empty"},
                     {plot::colors::red, "saturated (static)"},
                     {plot::colors::magenta, "saturated (dynamic)"},
                     {plot::colors::orange,
                      panels.any_moving ? "outlined: holds a moving instance" : "(no moving instance)"}});
  const std::string path = (std::filesystem::path(dir) / "occupancy.png").string();
  c.write(path);
  std::printf("slices: %s\n", path.c_str());
}

}  // namespace gridrt::app
