// gridrt stats --slices DIR: the grid's occupancy and saturation slice by slice, as one contact
// sheet (DIR/occupancy.png): a panel per slice along an axis, each cell coloured by the references
// its slots hold (viridis, 1 .. capacity), empty cells light, saturated cells (a reference found no
// slot: the status texel's bits) red for static, magenta for dynamic references; cells holding a
// moving (dynamic) instance's references outlined orange.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "apps/commands.h"
#include "apps/slices.h"
#include "gridrt/common/plot.h"

namespace gridrt::app {

namespace sh = gridrt::shared;

void write_slices(const reference::ReferenceGridTracer& ref, const std::string& scene_name, const std::string& dir,
                  char axis, const reference::ExplainRecord* ray, const std::string& ray_name) {
  if (!plot::available())
    throw Error("--slices needs OpenImageIO and the DejaVu fonts (Debian: libopenimageio-dev, fonts-dejavu-core)");
  if (!std::filesystem::is_directory(dir)) throw Error("--slices: folder '" + dir + "' does not exist");
  const reference::GridData& grid = ref.data();
  const sh::GridParams& g = grid.params;
  // Slice axis a; the panel shows axis u to the right and axis v up.
  const int a = axis == 'x' ? 0 : axis == 'y' ? 1 : 2;
  const int u = a == 0 ? 1 : 0, v = a == 2 ? 1 : 2;
  const char names[3] = {'x', 'y', 'z'};
  const uint32_t ns = g.cells[a], nu = g.cells[u], nv = g.cells[v];
  // Panel size: cells of at least 2 pixels, a sheet about 1100 pixels wide.
  const uint32_t cols = std::max(1u, std::min(ns, uint32_t(std::ceil(std::sqrt(double(ns) * double(nv) / double(nu))))));
  const uint32_t rows = (ns + cols - 1) / cols;
  const int cell_px = std::clamp(int(1000 / (cols * nu)), 2, 24);
  const int pw = int(nu) * cell_px, ph = int(nv) * cell_px, gap = 10, label_h = 16;
  struct Counts {
    uint64_t empty = 0, saturated_static = 0, saturated_dynamic = 0;
  } counts;
  std::vector<std::vector<glm::vec3>> panels(ns, std::vector<glm::vec3>(size_t(nu) * nv));
  std::vector<std::vector<uint8_t>> moving(ns, std::vector<uint8_t>(size_t(nu) * nv, 0));
  bool any_moving = false;
  uint32_t largest = 0;
  for (uint32_t s = 0; s < ns; ++s)
    for (uint32_t j = 0; j < nv; ++j)
      for (uint32_t i = 0; i < nu; ++i) {
        glm::uvec3 cell(0);
        cell[a] = s, cell[u] = i, cell[v] = j;
        uint32_t n = 0;
        for (uint32_t r; n < g.capacity &&
                           (r = reference::imageLoad(grid.image, glm::ivec3(sh::cell_slot_texel(g, cell, n)))) != sh::kBlank;
             ++n)
          if (r >= g.comparison_offset) moving[s][size_t(nv - 1 - j) * nu + i] = 1, any_moving = true;
        largest = std::max(largest, n);
        const uint32_t status = reference::imageLoad(grid.image, glm::ivec3(sh::cell_status_texel(g, cell)));
        glm::vec3 c = n == 0 ? plot::colors::light_grey
                             : plot::viridis(g.capacity > 1 ? float(n - 1) / float(g.capacity - 1) : 1.0f);
        if (n == 0) ++counts.empty;
        if (status & sh::kStatusStatic) c = plot::colors::red, ++counts.saturated_static;
        else if (status & sh::kStatusDynamic) c = plot::colors::magenta, ++counts.saturated_dynamic;
        panels[s][size_t(nv - 1 - j) * nu + i] = c;  // v up
      }
  const int title_h = ray ? 74 : 56, pad = 12;
  const int side = 60 + plot::Canvas::text_width("outlined: holds a moving instance", 13);
  const int sheet_w = pad + int(cols) * (pw + gap) + side, sheet_h = title_h + int(rows) * (ph + gap + label_h) + pad;
  plot::Canvas c(uint32_t(std::max(sheet_w, 560)), uint32_t(std::max(sheet_h, title_h + 330)));
  char t[200];
  std::snprintf(t, sizeof t, "Occupancy and saturation, %c slices", names[a]);
  c.text(pad, 22, t, plot::colors::black, 16, plot::Align::left, true);
  std::snprintf(t, sizeof t,
                "%s: %ux%ux%u cells of %u slots; %llu empty, %llu saturated (static), %llu (dynamic); fullest %u; "
                "panels: %c right, %c up",
                scene_name.c_str(), g.cells.x, g.cells.y, g.cells.z, g.capacity, (unsigned long long)counts.empty,
                (unsigned long long)counts.saturated_static, (unsigned long long)counts.saturated_dynamic, largest,
                names[u], names[v]);
  c.text(pad, 41, t, plot::colors::dark_grey, 12);
  for (uint32_t s = 0; s < ns; ++s) {
    const int x = pad + int(s % cols) * (pw + gap), y = title_h + int(s / cols) * (ph + gap + label_h) + label_h;
    std::snprintf(t, sizeof t, "%c = %u", names[a], s);
    c.text(x, y - 4, t, plot::colors::black, 11);
    c.image(x, y, nu, nv, panels[s], cell_px);
    if (cell_px >= 4)
      for (uint32_t k = 0; k < nu * nv; ++k)
        if (moving[s][k]) {
          const int cx = x + int(k % nu) * cell_px, cy = y + int(k / nu) * cell_px;
          c.frame(cx, cy, cx + cell_px, cy + cell_px, plot::colors::orange);
        }
    c.frame(x - 1, y - 1, x + pw + 1, y + ph + 1, plot::colors::grey);
  }
  // The ray: its visited cells outlined, its samples as dots (in cell units from the origin)
  size_t visits = 0;
  if (ray)
    for (const sh::ExplainEvent& e : ray->events) {
      if (e.kind != sh::kEvCell) continue;
      ++visits;
      const uint32_t s = e.cell[a];
      const int x = pad + int(s % cols) * (pw + gap), y = title_h + int(s / cols) * (ph + gap + label_h) + label_h;
      const int cx = x + int(e.cell[u]) * cell_px, cy = y + int(nv - 1 - e.cell[v]) * cell_px;
      c.frame(cx, cy, cx + cell_px, cy + cell_px, plot::colors::black);
      if (cell_px >= 6) c.frame(cx + 1, cy + 1, cx + cell_px - 1, cy + cell_px - 1, plot::colors::black);
      const glm::vec3 p = (glm::vec3(e.f0) - g.origin) / g.cell_size;  // sample / entry point
      const int ps = std::clamp(int(std::floor(p[a])), 0, int(ns) - 1);
      const int px = pad + int(uint32_t(ps) % cols) * (pw + gap) + int(std::lround(p[u] * float(cell_px)));
      const int py = title_h + int(uint32_t(ps) / cols) * (ph + gap + label_h) + label_h +
                     int(std::lround((float(nv) - p[v]) * float(cell_px)));
      c.marker(px, py, 2, plot::colors::black);
      c.marker(px, py, 1, plot::colors::white);
    }
  if (ray) {
    std::snprintf(t, sizeof t, "%s: %zu cells visited (outlined), %s (dots)", ray_name.c_str(), visits,
                  g.traversal == sh::kTraversalPaper ? "midpoint samples" : "entry points");
    c.text(pad, 60, t, plot::colors::black, 12);
  }
  const int sx = pad + int(cols) * (pw + gap) + 10;
  plot::draw_color_bar(c, sx, title_h + 24, 20, 180, {1.0f, float(std::max(g.capacity, 2u)), "references", true});
  plot::draw_legend(c, sx, title_h + 230,
                    {{plot::colors::light_grey, "empty"},
                     {plot::colors::red, "saturated (static)"},
                     {plot::colors::magenta, "saturated (dynamic)"},
                     {plot::colors::orange, any_moving ? "outlined: holds a moving instance" : "(no moving instance)"}});
  const std::string path = (std::filesystem::path(dir) / "occupancy.png").string();
  c.write(path);
  std::printf("slices: %s\n", path.c_str());
}

}  // namespace gridrt::app
