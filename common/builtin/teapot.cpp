// teapot.cpp: Newell's Utah teapot, tessellated from its 28 bicubic Bezier patches.
//
// Steps: convert the control points to the scene's frame (y up); evaluate each patch on a
// (level+1)^2 parameter grid, patch borders through a canonical curve evaluation so that two
// patches sharing a border produce bit-identical points; weld vertices by exact position; drop
// triangles that collapse (poles); orient the patches consistently across shared edges and
// outward by ray parity; average the derivative normals of welded vertices.
#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <span>
#include <vector>

#include "gridrt/common/builtin/builtin.h"

namespace gridrt {

namespace {

constexpr unsigned kPatchCount = 28;

const glm::vec3 kTeapotControlPoints[kPatchCount * 16] = {
#include "gridrt/common/builtin/teapot_patches.inc"
};

using Curve = std::array<glm::vec3, 4>;

bool less(const glm::vec3& a, const glm::vec3& b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

// Cubic Bernstein weights at s = i / level; exact 1 and 0 at both ends.
std::array<float, 4> bernstein(unsigned i, unsigned level) {
  const float s = float(i) / float(level);
  const float t = 1.0f - s;
  return {t * t * t, 3.0f * s * t * t, 3.0f * s * s * t, s * s * s};
}

// Derivative d/ds of the cubic Bernstein weights at s.
std::array<float, 4> bernstein_derivative(float s) {
  const float t = 1.0f - s;
  return {-3.0f * t * t, 3.0f * t * t - 6.0f * s * t, 6.0f * s * t - 3.0f * s * s, 3.0f * s * s};
}

glm::vec3 combine(const std::array<float, 4>& w, const Curve& c) {
  glm::vec3 p = w[0] * c[0];
  p = p + w[1] * c[1];
  p = p + w[2] * c[2];
  p = p + w[3] * c[3];
  return p;
}

// A border curve evaluated the same way from both patches that share it: a collapsed curve (a
// pole) is its point; otherwise the curve is evaluated in the direction that starts at its
// lexicographically smaller end, so that the result does not depend on which patch asks.
glm::vec3 border_point(const Curve& c, unsigned i, unsigned level) {
  if (c[0] == c[1] && c[1] == c[2] && c[2] == c[3]) return c[0];
  const Curve r{c[3], c[2], c[1], c[0]};
  const bool reverse = less(c[3], c[0]) || (c[3] == c[0] && less(c[2], c[1]));
  return reverse ? combine(bernstein(level - i, level), r) : combine(bernstein(i, level), c);
}

struct Patch {
  glm::vec3 p[4][4];  // [row][column]; u runs along a row (columns), v down the rows
  Curve row(int r) const { return {p[r][0], p[r][1], p[r][2], p[r][3]}; }
  Curve column(int c) const { return {p[0][c], p[1][c], p[2][c], p[3][c]}; }

  // Position at grid point (i along u, j along v) of a level x level tessellation.
  glm::vec3 point(unsigned i, unsigned j, unsigned level) const {
    if (j == 0) return border_point(row(0), i, level);
    if (j == level) return border_point(row(3), i, level);
    if (i == 0) return border_point(column(0), j, level);
    if (i == level) return border_point(column(3), j, level);
    const auto wv = bernstein(j, level);
    Curve q;
    for (int c = 0; c < 4; ++c) q[c] = combine(wv, column(c));
    return combine(bernstein(i, level), q);
  }

  // dP/du x dP/dv at parameters (u, v).
  glm::vec3 normal(float u, float v) const {
    const float tu = 1.0f - u, tv = 1.0f - v;
    const std::array<float, 4> bu{tu * tu * tu, 3 * u * tu * tu, 3 * u * u * tu, u * u * u};
    const std::array<float, 4> bv{tv * tv * tv, 3 * v * tv * tv, 3 * v * v * tv, v * v * v};
    const auto du = bernstein_derivative(u), dv = bernstein_derivative(v);
    glm::vec3 pu(0.0f), pv(0.0f);
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) {
        pu += du[c] * bv[r] * p[r][c];
        pv += bu[c] * dv[r] * p[r][c];
      }
    return glm::cross(pu, pv);
  }

  // Unit normal at grid point (i, j); at a pole (zero derivative) the normal of a point moved a
  // little into the patch, i.e. a neighbour's.
  glm::vec3 unit_normal(unsigned i, unsigned j, unsigned level) const {
    float u = float(i) / float(level), v = float(j) / float(level);
    glm::vec3 n = normal(u, v);
    for (int k = 0; k < 8 && glm::length(n) < 1e-10f; ++k) {
      const float d = 1e-3f * float(1 << k);
      u = std::clamp(u, d, 1.0f - d);
      v = std::clamp(v, d, 1.0f - d);
      n = normal(u, v);
    }
    const float len = glm::length(n);
    return len > 0.0f ? n / len : glm::vec3(0.0f, 1.0f, 0.0f);
  }
};

std::vector<Patch> scene_patches() {
  std::vector<Patch> patches(kPatchCount);
  for (unsigned k = 0; k < kPatchCount; ++k)
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) patches[k].p[r][c] = teapot_to_scene(kTeapotControlPoints[k * 16 + r * 4 + c]);
  return patches;
}

struct PatchMesh {
  std::vector<glm::vec3> positions;
  std::vector<glm::uvec3> triangles;
  std::vector<uint32_t> patch_of;        // per triangle
  std::vector<std::vector<uint32_t>> grid;  // per patch, (level+1)^2 vertex indices
};

// Tessellate and weld (exact positions), without orientation or normals.
PatchMesh weld(const std::vector<Patch>& patches, unsigned level) {
  PatchMesh m;
  auto key = [](const glm::vec3& p) { return std::array<float, 3>{p.x, p.y, p.z}; };
  std::map<std::array<float, 3>, uint32_t> index;
  for (uint32_t k = 0; k < patches.size(); ++k) {
    std::vector<uint32_t> g((level + 1) * (level + 1));
    for (unsigned j = 0; j <= level; ++j)
      for (unsigned i = 0; i <= level; ++i) {
        const glm::vec3 p = patches[k].point(i, j, level);
        auto [it, inserted] = index.emplace(key(p), uint32_t(m.positions.size()));
        if (inserted) m.positions.push_back(p);
        g[j * (level + 1) + i] = it->second;
      }
    // Two triangles per quad, wound like dP/du x dP/dv; collapsed ones dropped.
    for (unsigned j = 0; j < level; ++j)
      for (unsigned i = 0; i < level; ++i) {
        const uint32_t a = g[j * (level + 1) + i], b = g[j * (level + 1) + i + 1];
        const uint32_t c = g[(j + 1) * (level + 1) + i + 1], d = g[(j + 1) * (level + 1) + i];
        for (const glm::uvec3 t : {glm::uvec3(a, b, c), glm::uvec3(a, c, d)}) {
          const glm::vec3 n = glm::cross(m.positions[t[1]] - m.positions[t[0]], m.positions[t[2]] - m.positions[t[0]]);
          if (n == glm::vec3(0.0f)) continue;  // zero area (a pole, or collinear points)
          m.triangles.push_back(t);
          m.patch_of.push_back(k);
        }
      }
    m.grid.push_back(std::move(g));
  }
  return m;
}

// Number of crossings of the ray o + t d (t > 0) with the mesh, skipping triangle `skip`.
unsigned crossings(const PatchMesh& m, const std::vector<bool>& flip, glm::dvec3 o, glm::dvec3 d, size_t skip) {
  (void)flip;
  unsigned n = 0;
  for (size_t t = 0; t < m.triangles.size(); ++t) {
    if (t == skip) continue;
    const glm::dvec3 a(m.positions[m.triangles[t][0]]), b(m.positions[m.triangles[t][1]]),
        c(m.positions[m.triangles[t][2]]);
    const glm::dvec3 e1 = b - a, e2 = c - a, p = glm::cross(d, e2);
    const double det = glm::dot(e1, p);
    if (std::abs(det) < 1e-300) continue;
    const glm::dvec3 s = o - a;
    const double u = glm::dot(s, p) / det;
    if (u < 0.0 || u > 1.0) continue;
    const glm::dvec3 q = glm::cross(s, e1);
    const double v = glm::dot(d, q) / det;
    if (v < 0.0 || u + v > 1.0) continue;
    if (glm::dot(e2, q) / det > 0.0) ++n;
  }
  return n;
}

// Which patches are inside-out. Neighbouring patches must traverse their shared edges in
// opposite directions (consistent orientation); each connected set of patches then faces the
// way the area-weighted majority of its sample triangles calls outward: a ray shot along an
// outward normal crosses the model an even number of times.
std::vector<bool> find_flips(const std::vector<Patch>& patches) {
  const PatchMesh m = weld(patches, 6);
  const size_t np = patches.size();
  // Patch adjacency through directed edges.
  std::map<std::pair<uint32_t, uint32_t>, std::vector<std::pair<uint32_t, bool>>> edges;
  for (size_t t = 0; t < m.triangles.size(); ++t)
    for (int e = 0; e < 3; ++e) {
      const uint32_t a = m.triangles[t][e], b = m.triangles[t][(e + 1) % 3];
      edges[{std::min(a, b), std::max(a, b)}].push_back({m.patch_of[t], a < b});
    }
  std::vector<std::vector<std::pair<uint32_t, bool>>> adj(np);  // (neighbour, same direction)
  for (const auto& [e, uses] : edges)
    for (size_t i = 0; i < uses.size(); ++i)
      for (size_t j = i + 1; j < uses.size(); ++j)
        if (uses[i].first != uses[j].first) {
          const bool same = uses[i].second == uses[j].second;
          adj[uses[i].first].push_back({uses[j].first, same});
          adj[uses[j].first].push_back({uses[i].first, same});
        }
  std::vector<bool> flip(np, false);
  std::vector<int> component(np, -1);
  int components = 0;
  for (size_t s = 0; s < np; ++s) {
    if (component[s] >= 0) continue;
    std::vector<size_t> stack{s};
    component[s] = components;
    while (!stack.empty()) {
      const size_t p = stack.back();
      stack.pop_back();
      for (auto [q, same] : adj[p])
        if (component[q] < 0) {
          component[q] = components;
          flip[q] = same ? !flip[p] : bool(flip[p]);
          stack.push_back(q);
        }
    }
    ++components;
  }
  // Outward by ray parity, area-weighted vote per component. The model is open underneath, so
  // parity is counted only along directions of the upper hemisphere: a point just off a surface
  // is outside where more of those rays cross the model an even number of times.
  std::vector<glm::dvec3> dirs{{0.0, 1.0, 0.0}};
  for (int k = 0; k < 6; ++k)
    for (double elevation : {0.15, 0.7}) {
      const double a = 2.0 * 3.14159265358979 * (k + 0.37) / 6.0;
      dirs.push_back({std::cos(a) * std::cos(elevation), std::sin(elevation), std::sin(a) * std::cos(elevation)});
    }
  auto outside_score = [&](glm::dvec3 o, size_t skip) {
    int even = 0;
    for (const glm::dvec3& d : dirs) even += crossings(m, flip, o, d, skip) % 2 == 0 ? 1 : 0;
    return even;
  };
  std::vector<double> vote(components, 0.0);
  for (size_t t = 0; t < m.triangles.size(); t += 5) {  // a sample of the triangles is plenty
    const glm::dvec3 a(m.positions[m.triangles[t][0]]), b(m.positions[m.triangles[t][1]]),
        c(m.positions[m.triangles[t][2]]);
    glm::dvec3 n = glm::cross(b - a, c - a);
    const double area = glm::length(n);
    n /= area;
    if (flip[m.patch_of[t]]) n = -n;
    const glm::dvec3 centre = (a + b + c) / 3.0;
    const int ahead = outside_score(centre + 1e-4 * n, t), behind = outside_score(centre - 1e-4 * n, t);
    if (ahead != behind) vote[component[m.patch_of[t]]] += ahead > behind ? area : -area;
  }
  for (size_t p = 0; p < np; ++p)
    if (vote[component[p]] < 0.0) flip[p] = !flip[p];
  return flip;
}

}  // namespace

std::span<const glm::vec3> teapot_control_points() {
  return {kTeapotControlPoints, kPatchCount * 16};
}

glm::vec3 teapot_to_scene(const glm::vec3& p) {
  // z up -> y up (a rotation about x), the body's axis onto the y axis, the open bottom at y = 0.
  return {p.x - 0.5f, p.z - 0.300049f, 0.0f - p.y};
}

Mesh make_teapot_mesh(unsigned level) {
  if (level < 1 || level > 128) throw Error("teapot tessellation level must lie in [1, 128]");
  const std::vector<Patch> patches = scene_patches();
  static const std::vector<bool> flips = find_flips(scene_patches());
  PatchMesh pm = weld(patches, level);

  Mesh mesh;
  mesh.name = "teapot";
  mesh.positions = std::move(pm.positions);
  // Orientation: inside-out patches get their triangles reversed.
  for (size_t t = 0; t < pm.triangles.size(); ++t) {
    glm::uvec3 tri = pm.triangles[t];
    if (flips[pm.patch_of[t]]) std::swap(tri[1], tri[2]);
    mesh.triangles.push_back(tri);
  }
  // Normals: the derivative normals of every patch point that welded into a vertex, averaged.
  std::vector<glm::vec3> sum(mesh.positions.size(), glm::vec3(0.0f));
  for (size_t k = 0; k < patches.size(); ++k)
    for (unsigned j = 0; j <= level; ++j)
      for (unsigned i = 0; i <= level; ++i) {
        const glm::vec3 n = patches[k].unit_normal(i, j, level);
        sum[pm.grid[k][j * (level + 1) + i]] += flips[k] ? -n : n;
      }
  mesh.normals.resize(sum.size());
  for (size_t v = 0; v < sum.size(); ++v) {
    const float len = glm::length(sum[v]);
    mesh.normals[v] = len > 0.0f ? sum[v] / len : glm::vec3(0.0f, 1.0f, 0.0f);
  }
  // Texture coordinates: the patch parameters (u, v) of the first patch that made the vertex.
  mesh.uvs.assign(mesh.positions.size(), glm::vec2(-1.0f));
  for (size_t k = 0; k < patches.size(); ++k)
    for (unsigned j = 0; j <= level; ++j)
      for (unsigned i = 0; i <= level; ++i) {
        glm::vec2& uv = mesh.uvs[pm.grid[k][j * (level + 1) + i]];
        if (uv.x < 0.0f) uv = glm::vec2(float(i) / float(level), float(j) / float(level));
      }
  mesh.materials.assign(mesh.triangles.size(), 0u);
  return mesh;
}

}  // namespace gridrt
