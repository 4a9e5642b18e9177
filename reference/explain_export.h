// explain_export.h: pictures of an explained ray: a Wavefront OBJ scene (the ray as a line, the
// visited cells as boxes, the tested triangles, the hit point; one group per kind, so that any 3D
// viewer shows them apart), an SVG projection onto the plane the ray spans most, and one
// self-contained HTML page that steps through the events (no network: its script, style and
// pictures inline).
#pragma once

#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "gridrt/plan/explain_format.h"
#include "gridrt/reference/grid.h"

namespace gridrt::reference {

using plan::ExplainFormat;

// What an explained ray visited and tested, in world space.
struct ExplainGeometry {
  glm::vec3 org{0.0f}, dir{0.0f, 0.0f, 1.0f};
  float t_begin = 0.0f, t_end = 0.0f;  // the part of the ray drawn: from the grid box to the hit or exit
  struct Cell {
    glm::uvec3 cell{0};
    glm::vec3 lo{0.0f}, hi{0.0f};  // world box
    size_t event = 0;              // its kEvCell
    uint32_t step = 0;
    bool empty = false;      // no reference in its slots
    bool saturated = false;  // its status texel says it dropped references
  };
  std::vector<Cell> cells;
  struct Triangle {
    uint32_t ref = 0;
    glm::vec3 v[3]{};
    size_t event = 0;   // its first kEvTest
    uint32_t code = 0;  // its decisive test result (kTest*): accepted once stays accepted
    uint32_t tests = 0;
    bool hit = false;   // the reported hit's triangle
  };
  std::vector<Triangle> triangles;
  std::optional<glm::vec3> hit_point;
  bool gap_fill = false;
  std::vector<std::optional<float>> event_t;  // per event: the t along the ray it concerns, if any
};
ExplainGeometry explain_geometry(const ExplainRecord& rec, const GridData& grid);

// The OBJ text (groups ray, cells_empty, cells_with_references, cells_saturated,
// triangles_rejected, triangles_accepted, hit_triangle, hit_point; materials of the same names
// in `mtl_name`, written by explain_mtl).
std::string explain_obj(const ExplainRecord& rec, const GridData& grid, const std::string& mtl_name);
std::string explain_mtl();

// The projection onto the plane of the two axes along which the ray runs farthest (the axis of
// its smallest direction component dropped), scaled to fit the visited cells and the drawn ray.
struct ExplainProjection {
  int u = 0, v = 1;         // the world axes drawn to the right and up
  glm::vec2 lo{0.0f};       // world coordinates at the picture's lower left
  float scale = 1.0f;       // pixels per world unit
  float width = 0.0f, height = 0.0f, margin = 40.0f;
  glm::vec2 map(glm::vec3 p) const;  // SVG coordinates (y down)
};
ExplainProjection explain_projection(const ExplainGeometry& geometry, float max_size = 720.0f);

// A standalone SVG of the projection: grid lines, the visited cells (empty, with references,
// saturated), the tested triangles by their result, the ray, the hit, a legend. Elements carry
// ids (cell-EVENT, tri-REFWORD, ray, hit) that the HTML viewer highlights.
std::string explain_svg(const ExplainRecord& rec, const GridData& grid, const ExplainFormat& format);

// What the HTML viewer shows of one ray: its label and header lines, the SVG, the reference's
// record (explain_json, with per-event picture coordinates), the shader's (null without one) and
// their alignment.
nlohmann::json explain_view(const std::string& label, const std::vector<std::string>& header,
                            const ExplainRecord& want, const ExplainRecord* got, const GridData& grid,
                            const ExplainFormat& format);
// The page: `views` is an array of explain_view objects; `title` heads it.
std::string explain_html(const std::string& title, const nlohmann::json& views);

}  // namespace gridrt::reference
