// test_portal.cpp: the portal ("div") tracer ("A Novel Raytracing Algorithm for GPU") against independent truth: brute-force
// box enumeration, the world's occupancy, the exact voxel DDA, the paper's own 2D example.
#include <catch2/catch.hpp>

#include <array>
#include <cmath>
#include <cstring>
#include <fstream>
#include <random>
#include <set>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/reference/portal/build.h"
#include "gridrt/reference/portal/trace.h"
#include "gridrt/reference/portal/world.h"

using namespace gridrt;
using namespace gridrt::portal;
namespace sh = gridrt::shared;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

Ray make_ray(glm::vec3 o, glm::vec3 d, float tmin = 0.0f, float tmax = kInf) {
  Ray r{};
  r.org = o, r.dir = d, r.tmin = tmin, r.tmax = tmax;
  r.launch_normal = glm::vec3(0.0f);
  r.launch_ref = shared::kNoRef;
  return r;
}

std::string hex(float f) {
  uint32_t b;
  std::memcpy(&b, &f, 4);
  char s[64];
  std::snprintf(s, sizeof s, "%.9g (0x%08X)", double(f), b);
  return s;
}

std::string ray_text(const Ray& r) {
  return "org (" + hex(r.org.x) + ", " + hex(r.org.y) + ", " + hex(r.org.z) + ") dir (" + hex(r.dir.x) + ", " + hex(r.dir.y) +
         ", " + hex(r.dir.z) + ")";
}

// Random world: occupancy with probability `fill`, materials 0..2.
World random_world(glm::uvec3 dims, float fill, uint32_t seed) {
  World w;
  w.name = "random";
  w.dims = dims;
  w.materials = {{"a", glm::vec3(1, 0, 0)}, {"b", glm::vec3(0, 1, 0)}, {"c", glm::vec3(0, 0, 1)}};
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  w.voxels.resize(w.voxel_count());
  for (auto& v : w.voxels) v = U(rng) < fill ? uint16_t(rng() % 3) : kEmpty;
  return w;
}

bool box_all(const World& w, const Box& b, uint32_t medium) {
  for (int z = b.lo.z; z < b.hi.z; ++z)
    for (int y = b.lo.y; y < b.hi.y; ++y)
      for (int x = b.lo.x; x < b.hi.x; ++x)
        if (w.medium({x, y, z}) != medium) return false;
  return true;
}

// Can box b grow by one layer on face f?
bool can_grow(const World& w, const Box& b, uint32_t f) {
  Box g = b;
  const int a = int(f / 2);
  if (f & 1u) g.hi[a] += 1; else g.lo[a] -= 1;
  if (g.lo[a] < 0 || g.hi[a] > int(w.dims[a])) return false;
  return box_all(w, g, b.medium);
}

void check_divs(const World& w, const std::vector<Box>& divs) {
  std::vector<uint8_t> covered(w.voxel_count(), 0);
  for (const Box& b : divs) {
    INFO("div [" << b.lo.x << "," << b.lo.y << "," << b.lo.z << " .. " << b.hi.x << "," << b.hi.y << "," << b.hi.z << ")");
    REQUIRE(box_all(w, b, b.medium));
    for (uint32_t f = 0; f < 6; ++f) REQUIRE_FALSE(can_grow(w, b, f));
    for (int z = b.lo.z; z < b.hi.z; ++z)
      for (int y = b.lo.y; y < b.hi.y; ++y)
        for (int x = b.lo.x; x < b.hi.x; ++x) covered[w.index(x, y, z)] = 1;
  }
  for (size_t i = 0; i < covered.size(); ++i) {
    const glm::ivec3 v(i % w.dims.x, (i / w.dims.x) % w.dims.y, i / (w.dims.x * w.dims.y));
    if (w.medium(v) != World::kOpaque) REQUIRE(covered[i]);
  }
}

// Every maximal box by brute force: all boxes of one medium that cannot grow.
std::vector<Box> brute_force_maximal(const World& w) {
  std::vector<Box> out;
  const glm::ivec3 d(w.dims);
  for (uint32_t medium : {uint32_t(kEmpty)})
    for (int z0 = 0; z0 < d.z; ++z0)
      for (int z1 = z0 + 1; z1 <= d.z; ++z1)
        for (int y0 = 0; y0 < d.y; ++y0)
          for (int y1 = y0 + 1; y1 <= d.y; ++y1)
            for (int x0 = 0; x0 < d.x; ++x0)
              for (int x1 = x0 + 1; x1 <= d.x; ++x1) {
                const Box b{{x0, y0, z0}, {x1, y1, z1}, medium};
                if (!box_all(w, b, medium)) break;  // growing x1 further cannot help
                bool maximal = true;
                for (uint32_t f = 0; f < 6 && maximal; ++f) maximal = !can_grow(w, b, f);
                if (maximal) out.push_back(b);
              }
  return out;
}

const PortalBuild& builtin_build() {
  static const PortalBuild b = build_portal(builtin_level(), PortalOptions{1024, 1024, 0, false});
  return b;
}

const PortalBuild& teapot_build() {
  static const PortalBuild b = [] {
    Scene s = make_builtin("teapot");
    return build_portal(voxelize(s, 24), PortalOptions{1024, 1024, 0, false});
  }();
  return b;
}

// A random ray starting in an empty voxel (or outside the world, `outside`), random direction.
Ray random_ray(const World& w, std::mt19937& rng, bool outside) {
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  glm::vec3 d;
  do d = glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f;
  while (glm::length(d) < 0.1f);
  if (outside) {
    const glm::vec3 c = w.to_world(glm::vec3(w.dims) * 0.5f);
    const float r = glm::length(glm::vec3(w.dims)) * w.voxel_size;
    const glm::vec3 target = w.to_world(glm::vec3(U(rng), U(rng), U(rng)) * glm::vec3(w.dims));
    const glm::vec3 o = c + glm::normalize(d) * r;
    return make_ray(o, target - o);
  }
  for (;;) {
    const glm::ivec3 v(rng() % w.dims.x, rng() % w.dims.y, rng() % w.dims.z);
    if (w.solid(v)) continue;
    const glm::vec3 o = w.to_world(glm::vec3(v) + glm::vec3(U(rng), U(rng), U(rng)));
    return make_ray(o, d);
  }
}

struct Compare {
  size_t rays = 0, hits = 0;
  double portal_steps = 0, dda_steps = 0;
};

Compare compare_with_dda(const PortalBuild& b, size_t n, bool outside, uint32_t seed) {
  std::mt19937 rng(seed);
  Compare c;
  for (size_t i = 0; i < n; ++i) {
    const Ray r = random_ray(b.world, rng, outside);
    const Hit p = trace_portal(b.packed, r);
    const Hit d = trace_dda(b.world, r);
    INFO("ray " << i << ": " << ray_text(r));
    INFO(explain_portal(b.packed, b.world, r));
    REQUIRE(p.instance == d.instance);
    if (is_miss(d)) continue;
    REQUIRE(hit_voxel_index(p) == hit_voxel_index(d));
    REQUIRE(hit_face(p) == hit_face(d));
    // Same plane, same numerator, same division: t and uv agree to the bit.
    REQUIRE(hex(p.t) == hex(d.t));
    REQUIRE(hex(p.u) == hex(d.u));
    REQUIRE(hex(p.v) == hex(d.v));
    ++c.hits;
    c.portal_steps += p.cells;
    c.dda_steps += d.cells;
  }
  c.rays = n;
  return c;
}

}  // namespace

TEST_CASE("Portal: maximal divs equal brute-force enumeration on random worlds", "[portal][unit]") {
  for (uint32_t seed = 1; seed <= 12; ++seed) {
    const World w = random_world({5 + seed % 3, 4 + seed % 2, 3 + seed % 4}, 0.3f + 0.03f * float(seed), seed);
    std::vector<Box> got = maximal_divs(w, 2);
    std::vector<Box> want = brute_force_maximal(w);
    auto key = [](const Box& b) { return std::tuple(b.lo.z, b.lo.y, b.lo.x, b.hi.z, b.hi.y, b.hi.x); };
    std::sort(got.begin(), got.end(), [&](const Box& a, const Box& c) { return key(a) < key(c); });
    std::sort(want.begin(), want.end(), [&](const Box& a, const Box& c) { return key(a) < key(c); });
    INFO("seed " << seed);
    REQUIRE(got.size() == want.size());
    REQUIRE(got == want);
  }
}

TEST_CASE("Portal: divs are empty, maximal and cover empty space (built-in level, teapot)", "[portal][unit]") {
  for (const PortalBuild* b : {&builtin_build(), &teapot_build()}) {
    INFO(b->world.name);
    check_divs(b->world, b->maximal);
    std::vector<Box> stored(b->divs.begin() + 1, b->divs.end());
    for (const Box& d : stored) REQUIRE(std::find(b->maximal.begin(), b->maximal.end(), d) != b->maximal.end());
    // Every entered face has a chosen div containing its voxel.
    for (size_t i = 0; i < b->choice.size(); ++i)
      if (b->choice[i] != kNone) {
        const size_t v = i / 6;
        const glm::ivec3 p(v % b->world.dims.x, (v / b->world.dims.x) % b->world.dims.y,
                           v / (b->world.dims.x * b->world.dims.y));
        REQUIRE(b->maximal[b->choice[i]].contains(p));
      }
  }
}

TEST_CASE("Portal: packed div info and atlas round trip - every texel points to the right div or wall", "[portal][unit]") {
  for (const PortalBuild* b : {&builtin_build(), &teapot_build()}) {
    const World& w = b->world;
    const PackedPortal& p = b->packed;
    INFO(w.name);
    REQUIRE(p.div_count == b->divs.size());
    for (uint32_t d = 0; d < p.div_count; ++d) {
      const DivInfo info = read_div_info(p, d);
      const Box& B = b->divs[d];
      REQUIRE(info.lo == B.lo);
      REQUIRE(info.size == B.size());
      REQUIRE(info.type == (d == 0 ? shared::kPortalDivExterior : B.medium == kEmpty ? shared::kPortalDivAir : shared::kPortalDivGlass));
      for (uint32_t f = 0; f < 6; ++f) {
        const uint32_t a = f / 2, t0 = shared::portal_tangent0(a), t1 = shared::portal_tangent1(a);
        const glm::ivec2 ext = face_extent(B, f);
        REQUIRE(info.face_uv[f].x + ext.x <= p.atlas_width);
        REQUIRE(info.face_uv[f].y + ext.y <= p.atlas_height);
        for (int j = 0; j < ext.y; ++j)
          for (int i = 0; i < ext.x; ++i) {
            glm::ivec3 v;
            v[t0] = B.lo[t0] + i, v[t1] = B.lo[t1] + j;
            if (d == 0) v[a] = (f & 1u) ? B.hi[a] - 1 : 0;
            else v[a] = (f & 1u) ? B.hi[a] : B.lo[a] - 1;
            const uint32_t texel = p.atlas[size_t(info.face_uv[f].y + j) * p.atlas_width + info.face_uv[f].x + i];
            INFO("div " << d << " face " << f << " voxel " << v.x << "," << v.y << "," << v.z << " texel " << texel);
            if (!w.inside(v)) {
              REQUIRE(texel == shared::kPortalOutside);
            } else if (w.medium(v) == World::kOpaque) {
              REQUIRE(texel == shared::kPortalWallBit + w.at(v));
            } else {
              REQUIRE(texel < p.div_count);
              REQUIRE(texel != 0);
              REQUIRE(b->divs[texel].contains(v));
              REQUIRE(b->divs[texel].medium == w.medium(v));
            }
          }
      }
    }
    // Start map: a div containing the voxel, or the wall.
    for (size_t i = 0; i < w.voxel_count(); ++i) {
      const glm::ivec3 v(i % w.dims.x, (i / w.dims.x) % w.dims.y, i / (w.dims.x * w.dims.y));
      if (w.medium(v) == World::kOpaque) REQUIRE(p.start[i] == shared::kPortalWallBit + w.voxels[i]);
      else REQUIRE(b->divs[p.start[i]].contains(v));
    }
  }
}

TEST_CASE("Portal: trace agrees with the voxel DDA on the built-in level", "[portal][unit]") {
  const Compare in = compare_with_dda(builtin_build(), 4000, false, 7);
  const Compare out = compare_with_dda(builtin_build(), 1000, true, 8);
  CHECK(in.hits > 3000);
  CHECK(out.hits > 500);
  WARN("built-in level: mean steps portal " << in.portal_steps / in.hits << " vs DDA " << in.dda_steps / in.hits);
}

TEST_CASE("Portal: trace agrees with the voxel DDA on a voxelized mesh (teapot)", "[portal][unit]") {
  const Compare in = compare_with_dda(teapot_build(), 3000, false, 9);
  const Compare out = compare_with_dda(teapot_build(), 3000, true, 10);
  CHECK(out.hits > 300);
  WARN("teapot: mean steps portal " << (in.portal_steps + out.portal_steps) / double(in.hits + out.hits) << " vs DDA "
                                    << (in.dda_steps + out.dda_steps) / double(in.hits + out.hits));
}

// Every point of every triangle lies in a solid voxel (or within a hair of one: the test's box is
// 1.0001 voxels wide), wherever the model lies: a teapot a million units from the origin lost its
// handle to float box centres, and a sliver's box test its boxes (outside sweeps).
TEST_CASE("Portal: voxelize covers the surface wherever the model lies, slivers too", "[portal][unit]") {
  Scene base = make_builtin("teapot");
  {  // a few slivers beside it: 0.9 long, 1e-7 wide, at odd angles
    Mesh m;
    m.name = "slivers";
    for (int k = 0; k < 6; ++k) {
      const glm::vec3 a(0.2f * k - 0.5f, 0.3f, -0.4f + 0.13f * k), d = glm::normalize(glm::vec3(1.0f, 0.37f * k, 0.21f));
      const uint32_t b = uint32_t(m.positions.size());
      m.positions.insert(m.positions.end(), {a, a + 0.9f * d, a + 0.45f * d + glm::vec3(0.0f, 1e-7f, 1e-7f)});
      m.triangles.push_back({b, b + 1, b + 2});
    }
    m.materials.assign(m.triangles.size(), 0u);
    base.meshes.push_back(m);
    base.instances.push_back(Instance{.name = "slivers", .mesh = uint32_t(base.meshes.size() - 1)});
  }
  for (const float offset : {0.0f, 1.0e5f, 1.0e6f}) {
    Scene s = base;
    for (Instance& i : s.instances) i.transform = glm::translate(glm::mat4(1.0f), glm::vec3(offset, 0.0f, 0.0f)) * i.transform;
    if (s.camera) {
      s.camera->eye.x += offset;
      s.camera->target.x += offset;
    }
    for (Light& l : s.lights)
      if (!l.directional) l.position.x += offset;
    s.finalize();
    const World w = voxelize(s, 48);
    size_t samples = 0, missed = 0;
    for (const Instance& inst : s.instances) {
      const Mesh& mesh = s.meshes[inst.mesh];
      const sh::Affine xf = sh::to_affine(inst.transform_at(0.0f));
      for (const glm::uvec3& t : mesh.triangles) {
        const glm::dvec3 p0(sh::transform_point(xf, mesh.positions[t.x])), p1(sh::transform_point(xf, mesh.positions[t.y])),
            p2(sh::transform_point(xf, mesh.positions[t.z]));
        for (const glm::dvec2 uv : {glm::dvec2(1.0 / 3.0), glm::dvec2(0.05, 0.05), glm::dvec2(0.9, 0.05), glm::dvec2(0.05, 0.9),
                                    glm::dvec2(0.5, 0.0), glm::dvec2(0.0, 0.5)}) {
          const glm::dvec3 p = p0 + uv.x * (p1 - p0) + uv.y * (p2 - p0);
          const glm::dvec3 v = (p - glm::dvec3(w.origin)) / double(w.voxel_size);
          ++samples;
          bool in = false;  // the voxel holding it, or one within the box's hair across a face
          for (int dz = -1; dz <= 1 && !in; ++dz)
            for (int dy = -1; dy <= 1 && !in; ++dy)
              for (int dx = -1; dx <= 1 && !in; ++dx) {
                const glm::dvec3 q = v + glm::dvec3(dx, dy, dz) * 4e-5;
                const glm::ivec3 c(glm::floor(q));
                if (glm::all(glm::greaterThanEqual(c, glm::ivec3(0))) && glm::all(glm::lessThan(c, glm::ivec3(w.dims))))
                  in = w.solid(c);
              }
          missed += in ? 0 : 1;
        }
      }
    }
    INFO("offset " << offset << ": " << missed << " of " << samples << " surface samples in no solid voxel");
    CHECK(missed == 0);
  }
}

// A subnormal direction component is a zero, as the grid takes it: left as it was, the portal
// reported hits at t = inf or below 0 with NaN u, v, and the DDA another answer (an outside sweep).
TEST_CASE("Portal: subnormal direction components are zeros, the portal and the DDA alike", "[portal][unit]") {
  const PortalBuild& b = builtin_build();
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> pos(1.0f, 30.0f), sgn(-1.0f, 1.0f);
  size_t hits = 0;
  for (int i = 0; i < 400; ++i) {
    glm::vec3 d(sgn(rng), sgn(rng), sgn(rng));
    d[i % 3] = (i & 4) ? 1e-40f : -3e-39f;  // subnormal
    const Ray r = make_ray(glm::vec3(pos(rng), 2.0f, pos(rng)), d);
    if (b.world.solid(glm::ivec3(glm::floor(r.org)))) continue;
    glm::vec3 z = d;
    z[i % 3] = 0.0f;
    const Ray rz = make_ray(r.org, z);
    const Hit p = trace_portal(b.packed, r), q = trace_dda(b.world, r), pz = trace_portal(b.packed, rz);
    INFO(ray_text(r));
    REQUIRE(std::memcmp(&p, &pz, sizeof p) == 0);  // as the zero direction
    REQUIRE(p.instance == q.instance);
    REQUIRE(p.triangle == q.triangle);
    REQUIRE(hex(p.t) == hex(q.t));
    REQUIRE(!std::isnan(p.u));
    REQUIRE(!std::isnan(p.v));
    hits += !is_miss(p);
  }
  CHECK(hits > 100);
}

TEST_CASE("Portal: a ray starting in glass starts inside it, empty or negative intervals miss (portal and DDA alike)",
          "[portal][unit]") {
  // Outside sweeps: the portal traced out of the glass a ray started in (naming an empty voxel,
  // face -X) where the DDA said "inside"; an interval with tmin >= tmax hit a wall at t = tmin;
  // tmin < 0 hit or missed by where org + tmin dir fell
  const World w = parse_tile_map("size 9 5 3\nmap\n111111111\n1.......1\n1E..GG..1\n1.......1\n111111111\n", "glass");
  const PortalBuild b = build_portal(w, PortalOptions{64, 64, 1, false});
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> U(0.0f, 1.0f);
  size_t glass = 0;
  for (int i = 0; i < 20000 && glass < 200; ++i) {
    const glm::ivec3 v(rng() % w.dims.x, rng() % w.dims.y, rng() % w.dims.z);
    if (w.medium(v) == kEmpty || w.medium(v) == World::kOpaque) continue;
    ++glass;
    const Ray r = make_ray(w.to_world(glm::vec3(v) + glm::vec3(U(rng), U(rng), U(rng))),
                           glm::vec3(U(rng), U(rng), U(rng)) * 2.0f - 1.0f);
    const Hit p = trace_portal(b.packed, r), d = trace_dda(b.world, r);
    INFO(ray_text(r));
    CHECK(hit_face(p) == shared::kPortalFaceInside);
    CHECK(hex(p.t) == hex(r.tmin));
    REQUIRE(std::memcmp(&p, &d, sizeof p) == 0);
  }
  CHECK(glass >= 100);
  // Inside a wall, in air and in glass alike: nothing where the interval holds nothing
  for (const glm::vec3 o : {glm::vec3(0.5f, 0.5f, 0.5f), glm::vec3(2.5f, 1.5f, 2.5f), glm::vec3(4.5f, 1.5f, 2.5f)}) {
    for (const auto& [tmin, tmax] : {std::pair{0.0f, 0.0f}, {0.7f, 0.2f}, {-1.0f, INFINITY}, {NAN, INFINITY}}) {
      const Ray r = make_ray(w.to_world(o), glm::vec3(1, 0.2f, 0.1f), tmin, tmax);
      INFO(ray_text(r));
      CHECK(is_miss(trace_portal(b.packed, r)));
      CHECK(is_miss(trace_dda(b.world, r)));
    }
  }
  // On the world box's face, moving out of the world: outside, a miss (it started "inside" the
  // boundary voxel, a wall there: an outside sweep); moving in: traced as the DDA traces it
  const glm::vec3 mid(0.0f, float(w.dims.y) * 0.5f + 0.25f, float(w.dims.z) * 0.5f + 0.25f);
  for (const glm::vec3 d : {glm::vec3(-1, 0.1f, 0.2f), glm::vec3(-1, 0, 0), glm::vec3(-0.01f, 1, 0.3f)}) {
    const Ray r = make_ray(w.to_world(mid), d);
    INFO(ray_text(r));
    REQUIRE(hex(to_voxel_ray(b.packed.origin, b.packed.voxel_size, r).org.x) == hex(0.0f));
    CHECK(is_miss(trace_portal(b.packed, r)));
    CHECK(is_miss(trace_dda(b.world, r)));
  }
  {
    const Ray in = make_ray(w.to_world(mid), glm::vec3(1, 0.1f, 0.2f));
    const Hit p = trace_portal(b.packed, in), d = trace_dda(b.world, in);
    CHECK(std::memcmp(&p, &d, sizeof p) == 0);
  }
  // Along the world box's face from outside, parallel to it: on a lower face the ray runs in the
  // boundary voxels (walls here: a hit), on an upper face in the voxels beyond the box (a miss; the
  // entry took the upper plane for the box's own: an outside sweep)
  for (int a : {0, 2}) {
    const int b2 = 2 - a;  // the axis the ray moves along, from 2 voxels before the box
    for (bool upper : {false, true}) {
      glm::vec3 o(0.0f, float(w.dims.y) * 0.5f + 0.25f, 0.0f);
      o[a] = upper ? float(w.dims[a]) : 0.0f;
      o[b2] = -2.0f;
      glm::vec3 d(0.0f);
      d[b2] = 1.0f;
      const Ray r = make_ray(w.to_world(o), d);
      INFO(ray_text(r) << (upper ? ", upper face" : ", lower face"));
      REQUIRE(hex(to_voxel_ray(b.packed.origin, b.packed.voxel_size, r).org[a]) == hex(o[a]));
      const Hit p = trace_portal(b.packed, r), q = trace_dda(b.world, r);
      CHECK(is_miss(p) == upper);
      CHECK(std::memcmp(&p, &q, sizeof p) == 0);
    }
  }
  // A camera in the glass: every primary ray leaves it through a surface (none did)
  Camera cam = w.camera;
  for (int z = 0; z < int(w.dims.z); ++z)
    for (int y = 0; y < int(w.dims.y); ++y)
      for (int x = 0; x < int(w.dims.x); ++x)
        if (w.medium({x, y, z}) != kEmpty && w.medium({x, y, z}) != World::kOpaque)
          cam.eye = w.to_world(glm::vec3(x, y, z) + 0.5f);
  cam.target = cam.eye + (w.camera.target - w.camera.eye);
  RenderOptions o;
  o.width = 16, o.height = 8;
  RenderStats s;
  render(b, cam, o, &s);
  CHECK(s.refractions + s.reflections >= uint64_t(o.width) * o.height);
}

TEST_CASE("Portal: a far camera's cycling rays end at the renderer's limit, as background, counted", "[portal][unit]") {
  // An outside sweep: a camera 1e7 voxels away rounds the crossings (num = plane - org) by about a
  // voxel, and three divs handed one ray round at one t: render() never returned. A 32^3 world of
  // 8 % walls seen from 1e7 voxels (the sweep's harness: 26 of 5,000 such rays cycle)
  const World w = random_world({32, 32, 32}, 0.08f, 7);
  const PortalBuild b = build_portal(w, PortalOptions{1024, 1024, 0, false});
  Camera cam;
  cam.target = w.to_world(glm::vec3(16.0f));
  cam.eye = cam.target + glm::normalize(glm::vec3(0.55f, 0.38f, 0.74f)) * (1.0e7f * w.voxel_size);
  cam.vfov_degrees = 2.0e-4f;
  RenderOptions o;
  o.width = 64, o.height = 64;
  RenderStats fsm_stats, loop_stats;
  const std::vector<glm::vec3> fsm = render(b, cam, o, &fsm_stats);
  o.state_machine = false;
  const std::vector<glm::vec3> loops = render(b, cam, o, &loop_stats);
  CHECK(std::memcmp(fsm.data(), loops.data(), fsm.size() * sizeof(glm::vec3)) == 0);
  CHECK(fsm_stats.cut_pixels == loop_stats.cut_pixels);
  CHECK(fsm_stats.loop_iterations == loop_stats.loop_iterations);
  WARN("far camera: " << fsm_stats.cut_pixels << " of " << o.width * o.height << " pixels cut");
  CHECK(fsm_stats.cut_pixels > 0);  // the case met (else this test tests nothing)
  // A pixel's iterations stay within the limit (plus a mip walk's, none here)
  const uint32_t limit = shared::portal_pixel_iteration_limit(b.packed.div_count, b.packed.fine_dims(), o.max_interfaces);
  CHECK(fsm_stats.loop_iterations <= uint64_t(limit) * o.width * o.height);
}

TEST_CASE("Portal: rays along voxel edges and corners, axis-aligned rays, tmax", "[portal][unit]") {
  const PortalBuild& b = builtin_build();
  // Through voxel corners (integer origins, diagonal directions) and along edges.
  std::vector<Ray> rays;
  for (int x = 1; x < 31; x += 3)
    for (int z = 1; z < 31; z += 2)
      for (glm::vec3 d : {glm::vec3(1, 1, 1), glm::vec3(-1, 0, 1), glm::vec3(1, 0, 0), glm::vec3(0, -1, 0), glm::vec3(-2, 1, 1),
                          glm::vec3(1, 0, -1)})
        rays.push_back(make_ray(glm::vec3(float(x), 2.0f, float(z)), d));
  size_t hits = 0;
  for (const Ray& r : rays) {
    if (b.world.solid(glm::ivec3(glm::floor(r.org)))) continue;
    const Hit p = trace_portal(b.packed, r), d = trace_dda(b.world, r);
    INFO(ray_text(r));
    REQUIRE(p.instance == d.instance);
    REQUIRE(p.triangle == d.triangle);
    REQUIRE(hex(p.t) == hex(d.t));
    hits += !is_miss(p);
  }
  CHECK(hits > 100);
  // tmax before the wall: a miss for both.
  const Ray r = make_ray(glm::vec3(2.5f, 2.5f, 2.5f), glm::vec3(1, 0, 0));
  const Hit full = trace_portal(b.packed, r);
  REQUIRE_FALSE(is_miss(full));
  const Ray shortr = make_ray(r.org, r.dir, 0.0f, full.t * 0.5f);
  CHECK(is_miss(trace_portal(b.packed, shortr)));
  CHECK(is_miss(trace_dda(b.world, shortr)));
  // From outside the world box: an interval that ends before the box is a miss for both, one that
  // reaches it finds the same surface, no nearer than the box's face (10 voxels away).
  const Ray outside = make_ray(glm::vec3(-10.0f, 2.5f, 2.5f), glm::vec3(1, 0, 0));
  const Hit po = trace_portal(b.packed, outside), pd = trace_dda(b.world, outside);
  REQUIRE_FALSE(is_miss(po));
  CHECK(hex(po.t) == hex(pd.t));
  CHECK(po.t >= 10.0f);
  for (float tmax : {2.0f, 9.99f}) {
    INFO("tmax " << tmax);
    const Ray before = make_ray(outside.org, outside.dir, 0.0f, tmax);
    CHECK(is_miss(trace_portal(b.packed, before)));
    CHECK(is_miss(trace_dda(b.world, before)));
  }
}

TEST_CASE("Portal: heuristic picks the paper's 3x1 / 1x3 divs", "[portal][unit]") {
  // The paper's arrangement: a row of three cells and a column of three sharing the top-left cell
  // T, entered from the left and from the top. T sits at the world's corner so that rays enter
  // from outside (through the world's -X and -Z faces) without widening the divs; the walls are
  // 8 voxels tall so that the flux is nearly the paper's 2D one. Map rows run along +z.
  const World w = parse_tile_map("size 4 4 8\nmap\nE..1\n.111\n.111\n1111\n", "seed-example");
  const PortalBuild b = build_portal(w, PortalOptions{64, 64, 1, false});
  const glm::ivec3 v(0, 4, 0);  // T, half way up
  const Box row{{0, 1, 0}, {3, 9, 1}, kEmpty}, col{{0, 1, 0}, {1, 9, 3}, kEmpty};
  REQUIRE(std::find(b.maximal.begin(), b.maximal.end(), row) != b.maximal.end());
  REQUIRE(std::find(b.maximal.begin(), b.maximal.end(), col) != b.maximal.end());
  const size_t vi = b.world.index(glm::uvec3(v));
  // Entering through the -X face (from the left): the row. Through the -Z face (from the top): the column.
  const EntryCost row_x = integrate_flux_density_over_cuboid(b.world, FluxDensity::get(), v, shared::kPortalFaceNegX, row);
  const EntryCost col_x = integrate_flux_density_over_cuboid(b.world, FluxDensity::get(), v, shared::kPortalFaceNegX, col);
  INFO("row: p_open " << row_x.p_open << " length " << row_x.length << "; column: p_open " << col_x.p_open << " length "
                      << col_x.length);
  CHECK(row_x.cost < col_x.cost);
  REQUIRE(b.choice[vi * 6 + shared::kPortalFaceNegX] != kNone);
  REQUIRE(b.choice[vi * 6 + shared::kPortalFaceNegZ] != kNone);
  REQUIRE(b.maximal[b.choice[vi * 6 + shared::kPortalFaceNegX]] == row);
  REQUIRE(b.maximal[b.choice[vi * 6 + shared::kPortalFaceNegZ]] == col);
  // Every flux over a closed cuboid's faces sums to at most 1, and open + wall is the whole flux.
  CHECK(row_x.p_open + row_x.p_wall <= 1.0 + 1e-3);  // Monte Carlo table: 2^18 rays
  CHECK(row_x.p_open + row_x.p_wall > 0.95);
}

TEST_CASE("Portal: flux density table is a distribution", "[portal][unit]") {
  const FluxDensity& f = FluxDensity::get();
  // Every ray leaves the unit cube above the source exactly once: lid + four sides = 1.
  const double lid = f.z_face(0, 0, 1);
  const double side = f.x_face(1, 0, 0);  // plane x = 1 (and by symmetry x = 0, y = 0, y = 1)
  CHECK(lid + 4.0 * side == Approx(1.0).margin(0.01));
  // Form factor of a unit square to a parallel unit square at distance 1: 0.1998.
  CHECK(lid == Approx(0.1998).margin(0.005));
}

TEST_CASE("Portal: state machine and separate loops render the same image, bit for bit", "[portal][unit]") {
  const PortalBuild& b = builtin_build();
  RenderOptions o;
  o.width = 96, o.height = 48;
  RenderStats s1, s2;
  o.state_machine = true;
  const auto a = render(b, b.world.camera, o, &s1);
  o.state_machine = false;
  const auto c = render(b, b.world.camera, o, &s2);
  REQUIRE(a.size() == c.size());
  REQUIRE(std::memcmp(a.data(), c.data(), a.size() * sizeof(glm::vec3)) == 0);
  CHECK(s1.loop_iterations == s2.loop_iterations);
  CHECK(s1.shadow_rays > 0);
  // Lit pixels exist and not everything is lit (shadows).
  size_t bright = 0;
  for (const auto& p : a) bright += p.x + p.y + p.z > 0.5f;
  CHECK(bright > 0);
}

TEST_CASE("Portal: a voxelized scene's lights outside its world box light it", "[portal][unit]") {
  // The world is the model's box and one voxel: a shadow ray leaving it reaches its light. The
  // outside blocked every shadow ray there (the teapot's light, a directional light, a light put
  // at an eye outside the box), and the picture was flat ambient grey (an outside sweep)
  const PortalBuild& b = teapot_build();
  REQUIRE(b.world.open_outside);
  REQUIRE_FALSE(builtin_build().world.open_outside);  // a tile map's outside lies beyond its walls
  RenderOptions o;
  o.width = 64, o.height = 36;
  RenderStats st;
  const auto img = render(b, b.world.camera, o, &st);
  CHECK(st.shadow_rays > 0);
  // The surface's pixels: ambient alone is filter * colour * ambient; a lit one is brighter
  std::set<std::array<float, 3>> shades;
  size_t lit = 0;
  for (const glm::vec3& p : img) {
    if (p == background_of(o, b.world)) continue;
    shades.insert({p.x, p.y, p.z});
    const glm::vec3 ambient_only = b.world.materials[0].color * o.ambient;
    lit += p.x > ambient_only.x * 1.01f;
  }
  CHECK(shades.size() > 10);
  CHECK(lit > 0);
}

TEST_CASE("Portal: refraction never forks - total internal reflection reflects", "[portal][unit]") {
  glm::vec3 out;
  // Into glass at 45 degrees: refracted, bent towards the normal (Snell).
  const glm::vec3 d = glm::normalize(glm::vec3(1, -1, 0)), n(0, 1, 0);
  REQUIRE(refract_or_reflect(d, n, 1.0f / 1.5f, out));
  CHECK(std::abs(out.x) == Approx(std::sin(glm::radians(45.0f)) / 1.5f).margin(1e-5));
  // Out of glass at 60 degrees (critical angle 41.8): total internal reflection.
  const glm::vec3 g = glm::normalize(glm::vec3(std::sin(glm::radians(60.0f)), -std::cos(glm::radians(60.0f)), 0));
  REQUIRE_FALSE(refract_or_reflect(g, n, 1.5f, out));
  CHECK(out.x == Approx(g.x));
  CHECK(out.y == Approx(-g.y));
  // A glass block in a room: the render refracts, and one grazing view reflects internally.
  const World w = parse_tile_map("size 9 5 3\nmap\n111111111\n1.......1\n1E..GG..1\n1.......1\n111111111\n", "glass");
  const PortalBuild b = build_portal(w, PortalOptions{64, 64, 1, false});
  RenderOptions o;
  o.width = 64, o.height = 32;
  RenderStats s;
  const auto img = render(b, b.world.camera, o, &s);
  CHECK(s.refractions > 0);
  CHECK(s.reflections > 0);
  // Non-forking: one primary path per pixel, at most two shadow rays.
  CHECK(s.primary_rays == 64u * 32u);
  CHECK(s.shadow_rays <= 2u * s.primary_rays);
  o.refraction = false;
  RenderStats s0;
  render(b, b.world.camera, o, &s0);
  CHECK(s0.refractions == 0);
}

TEST_CASE("Portal: Tracer interface names, scene build, explain", "[portal][unit]") {
  Scene s = make_builtin("teapot");
  PortalTracer p(24);
  VoxelDdaTracer d(24);
  CHECK(p.name() == "portal-cpu");
  CHECK(d.name() == "voxel-dda");
  p.build(s, 0.0f);
  d.build(s, 0.0f);
  std::vector<Ray> rays;
  const Camera cam = s.frame_camera();
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 16; ++x) rays.push_back(camera_ray(cam, 16, 16, x, y));
  std::vector<Hit> hp(rays.size()), hd(rays.size());
  p.trace(rays, hp);
  d.trace(rays, hd);
  size_t hits = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    REQUIRE(hp[i].instance == hd[i].instance);
    REQUIRE(hp[i].triangle == hd[i].triangle);
    hits += !is_miss(hp[i]);
  }
  CHECK(hits > 20);
  const std::string e = p.explain(rays[8 * 16 + 8]);
  CHECK(e.find("exterior") != std::string::npos);
  CHECK(e.find("agrees") != std::string::npos);
  CHECK(p.dump().kind == "portal");
}

TEST_CASE("Portal: bad input is a clear Error", "[portal][unit][badinput]") {
  auto msg = [](auto f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK_THAT(msg([] { parse_tile_map("size 3 2 1\nmap\n1E1\n11\n"); }), Catch::Contains("ragged"));
  // A model 1e-16 across: one flat colour with exit 0 (an outside sweep); the grid's least extent
  CHECK_THAT(msg([] {
               Scene s;
               s.name = "speck";
               Mesh m;
               m.name = "t";
               m.positions = {{0, 0, 0}, {1e-16f, 0, 0}, {0, 1e-16f, 0}};
               m.triangles = {{0u, 1u, 2u}};
               m.materials = {0u};
               s.meshes.push_back(m);
               s.instances.push_back(Instance{.name = "a", .mesh = 0});
               s.finalize();
               voxelize(s, 16);
             }),
             Catch::Contains("spans only") && Catch::Contains("2^-40"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 2 1\nmap\n1E1\n1?1\n"); }), Catch::Contains("unknown character '?'"));
  // A byte that does not print is named by its value (a NUL cut the message short)
  CHECK_THAT(msg([] { parse_tile_map(std::string("size 3 2 1\nmap\n1E1\n1\0" "1\n", 23)); }),
             Catch::Contains("unknown character byte 0x00 at column 2"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 2 1\nmap\n1E1\n1\t1\n"); }), Catch::Contains("byte 0x09 at column 2"));
  // A header word or keyword of such bytes is shown escaped, whole (a NUL after the size cut the
  // message at the quote; binary junk as a keyword went to the terminal raw: an outside sweep)
  {
    const std::string nul = msg([] { parse_tile_map(std::string("size 3 2 1\0junk\nmap\n1E1\n111\n", 28)); });
    CHECK_THAT(nul, Catch::Contains("unexpected '\\x00junk' after"));
    const std::string junk = msg([] { parse_tile_map("\x01\x9b[2J\xff\n"); });
    CHECK_THAT(junk, Catch::Contains("unknown keyword '\\x01\\x9B[2J\\xFF'"));
    for (const std::string* m : {&nul, &junk})
      for (const char c : *m) CHECK((static_cast<unsigned char>(c) >= 0x20 && static_cast<unsigned char>(c) < 0x7F));
  }
  CHECK_THAT(msg([] { parse_tile_map("size 3 2 1\nmap\n1.1\n111\n"); }), Catch::Contains("no eye"));
  CHECK_NOTHROW(parse_tile_map("size 3 2 1\nmap\n1.1\n111\n", "x", false));
  CHECK_THAT(msg([] { parse_tile_map("size 300 2 1\nmap\n"); }), Catch::Contains("255"));
  CHECK_THAT(msg([] { parse_tile_map("size 0 2 1\nmap\n"); }), Catch::Contains("empty world"));
  CHECK_THAT(msg([] { parse_tile_map("# nothing\n"); }), Catch::Contains("empty world"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 3 1\nmap\n1E1\n"); }), Catch::Contains("expected 3 map rows"));
  // An outside sweep's finds: the row count's error had no line (now where the map ends, or its
  // first extra row), and a second 'size' replaced the first without a word
  CHECK_THAT(msg([] { parse_tile_map("size 3 3 1\nmap\n1E1\n", "few"); }), Catch::Contains("few:3:"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 1 1\nmap\n1E1\n111\n", "extra"); }),
             Catch::Contains("extra:4: expected 1 map rows, found 2"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 1 1\nsize 4 1 1\nmap\n1E1\n", "two"); }),
             Catch::Contains("two:2: 'size' given twice"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 1 1\nbogus\nmap\n1E1\n"); }), Catch::Contains("unknown keyword"));
  // A glass filter or a colour above 1 amplifies light: a filter of 3e38 drew +inf pixels with exit
  // 0 (an outside sweep); 1 itself is a colour
  CHECK_THAT(msg([] { parse_tile_map("size 3 1 1\nmaterial g x 3e38 3e38 3e38 glass 1.5\nmap\n1Eg\n", "f"); }),
             Catch::Contains("f:2: material colour must be within [0, 1]"));
  CHECK_THAT(msg([] { parse_tile_map("size 3 1 1\nmaterial w x 0.5 1.01 0.5\nmap\n1Ew\n", "w"); }),
             Catch::Contains("w:2: material colour must be within [0, 1]"));
  CHECK_NOTHROW(parse_tile_map("size 3 1 1\nmaterial w x 1 1 0\nmap\n1Ew\n", "w"));
  World big;
  big.name = "big";
  big.dims = {256, 1, 1};
  big.voxels.assign(256, kEmpty);
  CHECK_THAT(msg([&] { build_portal(big); }), Catch::Contains("at most 255"));
  World empty;
  empty.name = "nothing";
  CHECK_THAT(msg([&] { build_portal(empty); }), Catch::Contains("empty world"));
  Scene none;
  none.name = "none";
  CHECK_THAT(msg([&] { voxelize(none, 16); }), Catch::Contains("no triangles"));
  CHECK_THAT(msg([] { voxelize(make_builtin("teapot"), 300); }), Catch::Contains("1 .. 253"));
  CHECK_THAT(msg([] { build_portal(builtin_level(), PortalOptions{1024, 12, 1, false}); }), Catch::Contains("multiple of 8"));
  CHECK_THAT(msg([] { build_portal(builtin_level(), PortalOptions{4, 1024, 1, false}); }), Catch::Contains("atlas width"));
}

TEST_CASE("Portal: tile map files parse - the built-in text matches data/maps/builtin.map", "[portal][unit]") {
  for (const char* f : {"builtin.map", "corridors.map", "tiny.map"}) {
    const World w = load_tile_map(std::string(GRIDRT_DATA_DIR) + "/maps/" + f);
    CHECK(w.has_eye);
    CHECK(w.lights.size() >= 1);
  }
  std::ifstream in(std::string(GRIDRT_DATA_DIR) + "/maps/builtin.map");
  std::stringstream ss;
  ss << in.rdbuf();
  CHECK(ss.str() == std::string(builtin_level_text()));
  const World w = builtin_level();
  CHECK(w.dims == glm::uvec3(32, 6, 32));
  CHECK(w.lights.size() == 2);
}

TEST_CASE("Portal: the build's run-length integration equals the direct sum over voxel faces", "[portal][unit]") {
  for (const PortalBuild* b : {&builtin_build(), &teapot_build()}) {
    const World& w = b->world;
    std::mt19937 rng(3);
    size_t checked = 0;
    for (int n = 0; n < 400; ++n) {
      const Box& B = b->maximal[rng() % b->maximal.size()];
      const glm::ivec3 v(B.lo.x + int(rng() % uint32_t(B.size().x)), B.lo.y + int(rng() % uint32_t(B.size().y)),
                         B.lo.z + int(rng() % uint32_t(B.size().z)));
      const uint32_t f = rng() % 6;
      const EntryCost slow = integrate_flux_density_over_cuboid(w, FluxDensity::get(), v, f, B);
      const EntryCost fast = integrate_flux_density_fast(w, v, f, B);
      INFO(w.name << " box " << n << " face " << f);
      REQUIRE(fast.p_open == Approx(slow.p_open).margin(1e-9));
      REQUIRE(fast.p_wall == Approx(slow.p_wall).margin(1e-9));
      ++checked;
    }
    CHECK(checked == 400);
  }
}

TEST_CASE("Portal: greedy divs are maximal divs containing their voxel", "[portal][unit]") {
  for (uint32_t seed = 1; seed <= 8; ++seed) {
    const World w = random_world({5 + seed % 3, 4 + seed % 2, 3 + seed % 4}, 0.3f + 0.03f * float(seed), seed);
    const std::vector<Box> all = brute_force_maximal(w);
    INFO("seed " << seed);
    for (uint32_t z = 0; z < w.dims.z; ++z)
      for (uint32_t y = 0; y < w.dims.y; ++y)
        for (uint32_t x = 0; x < w.dims.x; ++x) {
          const glm::ivec3 v(x, y, z);
          if (w.medium(v) == World::kOpaque) continue;
          for (const glm::ivec3 order : {glm::ivec3(0, 1, 2), glm::ivec3(0, 2, 1), glm::ivec3(1, 0, 2),
                                         glm::ivec3(1, 2, 0), glm::ivec3(2, 0, 1), glm::ivec3(2, 1, 0)}) {
            const Box g = greedy_div(w, v, order);
            REQUIRE(g.contains(v));
            REQUIRE(std::find(all.begin(), all.end(), g) != all.end());
          }
        }
  }
}

TEST_CASE("Portal: the bounded choice never beats the exact one and agrees with the DDA", "[portal][unit]") {
  // The exact choice minimizes the cost over every maximal div containing the voxel, the bounded
  // one over a subset: at every face both choose, the bounded cost is at least the exact cost.
  Scene s = make_builtin("teapot");
  for (const World& w : {builtin_level(), voxelize(s, 16)}) {
    INFO(w.name);
    PortalOptions exact{1024, 1024, 0, false};
    exact.choice = DivChoice::exact;
    const PortalBuild e = build_portal(w, exact);
    for (const uint32_t per_run : {2u, 3u}) {
    PortalOptions bounded{1024, 1024, 0, false};
    bounded.choice_per_run = per_run;
    INFO(per_run << " greedy boxes per run");
    const PortalBuild b = build_portal(w, bounded);
    REQUIRE(b.stats.choice == DivChoice::bounded);
    REQUIRE(b.maximal.size() <= e.maximal.size());
    for (const Box& box : b.maximal) REQUIRE(std::find(e.maximal.begin(), e.maximal.end(), box) != e.maximal.end());
    size_t both = 0, same = 0;
    for (size_t i = 0; i < b.choice.size(); ++i) {
      if (b.choice[i] == kNone || e.choice[i] == kNone) continue;
      const size_t vi = i / 6;
      const glm::ivec3 v(vi % w.dims.x, (vi / w.dims.x) % w.dims.y, vi / (w.dims.x * w.dims.y));
      const uint32_t f = uint32_t(i % 6);
      const Box& bb = b.maximal[b.choice[i]];
      const Box& eb = e.maximal[e.choice[i]];
      REQUIRE(bb.contains(v));
      ++both;
      if (bb == eb) {
        ++same;
        continue;
      }
      const double cb = integrate_flux_density_over_cuboid(w, FluxDensity::get(), v, f, bb).cost;
      const double ce = integrate_flux_density_over_cuboid(w, FluxDensity::get(), v, f, eb).cost;
      INFO("voxel " << v.x << "," << v.y << "," << v.z << " face " << f);
      REQUIRE(float(cb) >= float(ce) * (1.0f - 1e-5f));
    }
    CHECK(both > 100);
    WARN(w.name << ", " << per_run << " per run: bounded and exact choose the same div at " << same << " of " << both
                << " faces");
    const Compare c = compare_with_dda(b, 1000, false, 11);
    CHECK(c.hits > 200);
    }
  }
}

TEST_CASE("Portal: generated levels parse, are deterministic, and trace like the DDA", "[portal][unit]") {
  CHECK(generated_level_text(40, 30, 4, 3) == generated_level_text(40, 30, 4, 3));
  CHECK(generated_level_text(40, 30, 4, 3) != generated_level_text(40, 30, 4, 4));
  const World w = generated_level_spec("gen:60x40x5:2");
  CHECK(w.dims == glm::uvec3(60, 7, 40));
  CHECK(w.name == "gen:60x40x5:2");  // the seed named (two seeds' levels printed one name)
  CHECK(generated_level_spec("gen:60x40x5").name == "gen:60x40x5");
  CHECK(w.lights.size() == 2);
  const PortalBuild b = build_portal(w, PortalOptions{1024, 1024, 0, false});
  const Compare in = compare_with_dda(b, 1500, false, 5), out = compare_with_dda(b, 500, true, 6);
  CHECK(in.hits > 1000);
  CHECK(out.hits > 100);
}

TEST_CASE("Portal: build limits fail fast with the limit named", "[portal][unit][badinput]") {
  auto msg = [](auto f) {
    try {
      f();
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CHECK_THAT(msg([] { generated_level_spec("gen:300x10x4"); }), Catch::Contains("255"));
  CHECK_THAT(msg([] { generated_level_spec("gen:30x10x254"); }), Catch::Contains("height at most 253"));
  CHECK_THAT(msg([] { generated_level_spec("gen:30x10"); }), Catch::Contains("gen:WIDTHxDEPTHxHEIGHT"));
  // Nothing after the numbers is ignored: letters, signs, spaces, a seed past 2^32 - 1.
  for (const char* bad : {"gen:30x10x4:abc", "gen:30x10x4:-1", "gen:30x10x4x", "gen:30x10x4 ", "gen:+30x10x4",
                          "gen:30x10x4:4294967296", "gen:30x10x4:1:2", "gen:30x10x4:"}) {
    INFO(bad);
    CHECK_THAT(msg([bad] { generated_level_spec(bad); }), Catch::Contains("gen:WIDTHxDEPTHxHEIGHT"));
  }
  CHECK(generated_level_spec("gen:30x10x4:4294967295").dims.x > 0);
  CHECK_THAT(msg([] { parse_div_choice("best"); }), Catch::Contains("bounded, exact"));
  // The exact choice refuses worlds beyond its voxel limit before any work.
  World open;
  open.name = "open";
  open.dims = {128, 128, 65};
  open.voxels.assign(open.voxel_count(), kEmpty);
  PortalOptions exact{1024, 1024, 0, false};
  exact.choice = DivChoice::exact;
  CHECK_THAT(msg([&] { build_portal(open, exact); }), Catch::Contains("exact div choice takes at most"));
  // A random world of small walls needs more divs than 15-bit indices address.
  const World noise = random_world({96, 96, 96}, 0.3f, 1);
  CHECK_THAT(msg([&] { build_portal(noise, PortalOptions{1024, 1024, 0, false}); }), Catch::Contains("32768"));
}
