// test_verify.cpp: the adversarial ray families against the exact referee (verify/), the domain's
// rejections, and the Embree oracle's refusal of rays it cannot take.
#include <catch2/catch.hpp>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <tuple>
#include <utility>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/reference/grid.h"
#include "run_tool.h"
#include "verify/verify.h"

using namespace gridrt;
using namespace gridrt::verify;
namespace sh = gridrt::shared;
namespace fs = std::filesystem;

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

Ray ray(glm::vec3 o, glm::vec3 d, float tmin = 0.0f, float tmax = kInf, uint32_t launch = sh::kNoRef) {
  Ray r{};
  r.org = o;
  r.dir = d;
  r.tmin = tmin;
  r.tmax = tmax;
  r.launch_ref = launch;
  return r;
}

std::vector<FamilyResult> run(const Scene& scene, reference::GridOptions go, size_t rays, bool translated) {
  go.threads = 2;
  VerifyOptions vo;
  vo.family.rays = rays;
  vo.translated = translated;
  vo.threads = 2;
  const auto make = [go](const Scene&) -> std::unique_ptr<Tracer> {
    return std::make_unique<reference::ReferenceGridTracer>(go);
  };
  return verify_scene(scene, go, make, vo);
}

std::string real_scene(const std::string& file) {
  const char* env = std::getenv("GRIDRT_SCENES");
  const fs::path dir = env ? fs::path(env) : fs::path(GRIDRT_SHARED_SCENES);
  if (!fs::is_directory(dir)) {
    if (std::getenv("CI")) FAIL("the real scenes folder '" << dir.string() << "' is missing, and CI must test with it");
    WARN("skipped: the real scenes folder '" << dir.string() << "' is missing (set GRIDRT_SCENES)");
    return "";
  }
  return std::string(GRIDRT_DATA_DIR) + "/scenes/" + file;
}

}  // namespace

TEST_CASE("Exact referee: a ray through a shared edge hits both triangles exactly, on their boundary", "[verify][unit]") {
  // The unit square as two triangles sharing the diagonal (0,0,0)-(1,1,0)
  const glm::vec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
  const Ray r = ray({0.25f, 0.25f, 1.0f}, {0.0f, 0.0f, -1.0f});  // through (0.25, 0.25, 0), on the diagonal
  const ExactTest t1 = exact_test(r, a, b, c), t2 = exact_test(r, a, c, d);
  REQUIRE(t1.hit);
  REQUIRE(t2.hit);
  CHECK(t1.boundary);
  CHECK(t2.boundary);
  CHECK(compare_t(t1, t2) == 0);
  CHECK(exact_t_float(t1) == 1.0f);
  // Off the diagonal by one ulp: exactly one triangle, no boundary
  const Ray s = ray({0.25f, std::nextafter(0.25f, 1.0f), 1.0f}, {0.0f, 0.0f, -1.0f});
  const ExactTest s1 = exact_test(s, a, b, c), s2 = exact_test(s, a, c, d);
  CHECK(s1.hit != s2.hit);
  CHECK_FALSE(s1.boundary);
  CHECK_FALSE(s2.boundary);
  // A ray in the plane is no hit; t must be > tmin strictly
  CHECK(exact_test(ray({-1, 0.5f, 0}, {1, 0, 0}), a, b, c).parallel);
  CHECK_FALSE(exact_test(ray({0.5f, 0.25f, 1}, {0, 0, -1}, 1.0f), a, b, c).hit);
  // t exactly 1/3: rounded to the nearest float
  const ExactTest third = exact_test(ray({0.5f, 0.25f, 1}, {0, 0, -3}), a, b, c);
  REQUIRE(third.hit);
  CHECK(exact_t_float(third) == 1.0f / 3.0f);
}

TEST_CASE("Domain: what the tracers reject, identically", "[verify][unit]") {
  CHECK(sh::ray_domain({0, 0, 0}, {1, 0, 0}, 0.0f, kInf) == sh::kDomainOk);
  CHECK(sh::ray_domain({0, 0, 0}, {1e-40f, 1.0f, -0.0f}, 0.0f, kInf) == sh::kDomainOk);  // denormal components
  CHECK(sh::ray_domain({1.6e7f, 0, 0}, {1, 0, 0}, 0.0f, kInf) == sh::kDomainOk);
  CHECK(sh::ray_domain({kNaN, 0, 0}, {1, 0, 0}, 0.0f, kInf) == sh::kDomainNonFinite);
  CHECK(sh::ray_domain({0, 0, 0}, {1, kInf, 0}, 0.0f, kInf) == sh::kDomainNonFinite);
  CHECK(sh::ray_domain({0, 0, 0}, {1e18f, 0, 0}, 0.0f, kInf) == sh::kDomainDirection);
  CHECK(sh::ray_domain({0, 0, 0}, {1e-18f, 1e-19f, 0}, 0.0f, kInf) == sh::kDomainDirection);
  CHECK(sh::ray_domain({0, 0, 0}, {-0.0f, 0.0f, 0.0f}, 0.0f, kInf) == sh::kDomainDirection);
  CHECK(sh::ray_domain({1e12f, 0, 0}, {1, 0, 0}, 0.0f, kInf) == sh::kDomainOrigin);
  CHECK(sh::ray_domain({0, 0, 0}, {1, 0, 0}, -1.0f, kInf) == sh::kDomainInterval);
  CHECK(sh::ray_domain({0, 0, 0}, {1, 0, 0}, kNaN, kInf) == sh::kDomainInterval);
  CHECK(sh::ray_domain({0, 0, 0}, {1, 0, 0}, 0.0f, kNaN) == sh::kDomainInterval);
  // Both tracers reject those rays (kHitRejected) and never report a NaN t on the others
  const Scene scene = make_builtin("cornell");
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  go.threads = 2;
  reference::ReferenceGridTracer grid(go);
  grid.build(scene, 0.0f);
  EmbreeTracer embree(2);
  embree.build(scene, 0.0f);
  const glm::vec3 o = scene.frame_camera().eye, d = scene.frame_camera().target - o;
  const std::vector<Ray> rays{ray(o, d * 1e18f), ray(o, d * 1e-19f), ray(glm::vec3(3e18f, 1e17f, 2e17f), -d),
                              ray(o, d, kNaN), ray(o, d, -0.5f), ray(o, d)};
  std::vector<Hit> got(rays.size()), want(rays.size());
  grid.trace(rays, got);
  embree.trace(rays, want);  // must not abort on the components above Embree's limit
  for (size_t i = 0; i + 1 < rays.size(); ++i) {
    INFO("ray " << i);
    CHECK((got[i].flags & sh::kHitRejected) != 0);
    CHECK((want[i].flags & sh::kHitRejected) != 0);
    CHECK(is_miss(got[i]));
  }
  CHECK(embree.rejected_rays() == rays.size() - 1);
  CHECK(!is_miss(got.back()));
  CHECK(std::isfinite(got.back().t));
}

TEST_CASE("Domain: a grid with cells narrower than its coordinates' ulps is coarsened, or refused", "[verify][unit]") {
  Scene scene = translated(make_builtin("cornell"), glm::vec3(1.0e6f, 0.0f, 0.0f));
  reference::GridOptions go;
  go.threads = 2;
  go.density = 1.0e3f;  // asks for cells far narrower than 64 ulps of 1e6 (1,000 cells a triangle, the most allowed)
  const sh::GridParams g = reference::choose_grid(scene, 0.0f, go);
  const float reach = std::max(std::abs(g.origin.x), std::abs(g.upper.x));
  CHECK(g.cell_size >= 0.999f * plan::min_cell_size(reach));  // reach: of the padded box
  go.cell_size = 0.01f;  // an override below the floor: refused
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go), Catch::Contains("ulps"));
  go.cell_size.reset();
  go.density = 2.0f;
  scene = translated(make_builtin("cornell"), glm::vec3(3.0e7f, 0.0f, 0.0f));
  CHECK_THROWS_WITH(reference::choose_grid(scene, 0.0f, go), Catch::Contains("2^24"));
}

TEST_CASE("Exact traversal at its defaults: no crack, no wrong answer on every family of the built-in scenes",
          "[verify][grid]") {
  for (const char* name : {"cornell", "teapot", "atrium"}) {
    reference::GridOptions go;
    go.traversal = reference::Traversal::exact;
    const std::vector<FamilyResult> res = run(make_builtin(name), go, 300, std::string(name) == "cornell");
    for (const FamilyResult& r : res) {
      INFO(name << " " << r.name << ":\n" << to_table({r}));
      CHECK(r.count(Verdict::crack) == 0);
      CHECK(r.count(Verdict::grid_wrong) == 0);  // far origins included: judged as traced (referee.h)
      CHECK(r.max_ulps <= kTBoundUlps);  // t on the well-conditioned exact hits (kappa <= 100)
      CHECK(r.nan_t == 0);
      if (r.name != "plane") CHECK(r.rays > 0);  // plane: only scenes with axis-aligned triangles
    }
  }
}

namespace {
// Meshes nobody tuned anything for, written as OBJ files: a closed UV sphere away from the origin,
// a needle box (1e4 long, 1e-3 thick: its far end's cross-section is about one ulp of its
// coordinates) and a soup of random triangles, a third of them slivers.
Scene untuned_mesh(const std::string& name) {
  std::ostringstream obj;
  obj.precision(9);
  if (name == "sphere" || name == "tinysphere") {
    // "tinysphere": radius 1e-6 at the origin
    const int n = 16, m = 32;
    const bool tiny = name == "tinysphere";
    const glm::dvec3 c = tiny ? glm::dvec3(0.0) : glm::dvec3(3.0e3, -2.0e3, 1.0e3);
    const double rad = tiny ? 1e-6 : 2.0;
    obj << "v " << c.x << ' ' << c.y + rad << ' ' << c.z << '\n';
    for (int i = 1; i < n; ++i)
      for (int j = 0; j < m; ++j) {
        const double th = M_PI * i / n, ph = 2.0 * M_PI * j / m;
        obj << "v " << c.x + rad * std::sin(th) * std::cos(ph) << ' ' << c.y + rad * std::cos(th) << ' '
            << c.z + rad * std::sin(th) * std::sin(ph) << '\n';
      }
    obj << "v " << c.x << ' ' << c.y - rad << ' ' << c.z << '\n';
    const auto v = [&](int i, int j) { return 2 + (i - 1) * m + (j % m); };  // 1-based
    const int last = 2 + (n - 1) * m;
    for (int j = 0; j < m; ++j) obj << "f 1 " << v(1, j + 1) << ' ' << v(1, j) << '\n';
    for (int i = 1; i < n - 1; ++i)
      for (int j = 0; j < m; ++j) {
        obj << "f " << v(i, j) << ' ' << v(i, j + 1) << ' ' << v(i + 1, j + 1) << '\n';
        obj << "f " << v(i, j) << ' ' << v(i + 1, j + 1) << ' ' << v(i + 1, j) << '\n';
      }
    for (int j = 0; j < m; ++j) obj << "f " << last << ' ' << v(n - 1, j) << ' ' << v(n - 1, j + 1) << '\n';
  } else if (name.rfind("cone", 0) == 0) {
    // "coneN": N slivers round one apex (a fan, as cones, cylinder caps and fan-triangulated
    // polygons are), unit height and base radius
    const int n = std::stoi(name.substr(4));
    obj << "v 0 0 1\n";
    for (int k = 0; k < n; ++k) obj << "v " << std::cos(2.0 * M_PI * k / n) << ' ' << std::sin(2.0 * M_PI * k / n) << " 0\n";
    for (int k = 0; k < n; ++k) obj << "f 1 " << k + 2 << ' ' << (k + 1) % n + 2 << '\n';
  } else if (name == "tjunction") {
    // 16 x 16 squares in z = 0, each three triangles round a vertex at the middle of its lower
    // edge: that vertex lies on the upper edge of the square below, one triangle's edge there
    // (a T-junction: the surface is closed, but by different edges on either side)
    const int n = 16;
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) {
        const double x = double(i) / n, y = double(j) / n, h = 1.0 / n;
        for (const glm::dvec2 q : {glm::dvec2(x, y), glm::dvec2(x + h, y), glm::dvec2(x + h, y + h), glm::dvec2(x, y + h),
                                   glm::dvec2(x + h / 2, y)})
          obj << "v " << q.x << ' ' << q.y << " 0\n";
        const int b = 5 * (i * n + j) + 1;
        obj << "f " << b << ' ' << b + 4 << ' ' << b + 3 << "\nf " << b + 4 << ' ' << b + 2 << ' ' << b + 3 << "\nf "
            << b + 4 << ' ' << b + 1 << ' ' << b + 2 << '\n';
      }
  } else if (name == "needle") {
    for (double x : {0.0, 1.0e4})
      for (double y : {0.0, 1.0e-3})
        for (double z : {0.0, 1.0e-3}) obj << "v " << x << ' ' << y << ' ' << z << '\n';
    for (const char* f : {"1 2 4", "1 4 3", "5 7 8", "5 8 6", "1 5 6", "1 6 2", "3 4 8", "3 8 7", "1 3 7", "1 7 5",
                          "2 6 8", "2 8 4"})
      obj << "f " << f << '\n';
  } else if (name == "needleprism") {
    // A closed triangular prism 1e-3 wide and 3.2 long across the world's origin (an outside
    // sweep's find): its faces' vertices lie a thousand times farther from a launch point near
    // the origin than the point's own coordinates
    for (const char* v : {"0.9718825817108154 -0.7990728616714478 0.9000957608222961",
                          "0.9712044596672058 -0.7983062267303467 0.9014930129051208",
                          "0.9725607633590698 -0.7975924611091614 0.9006861448287964",
                          "-0.9914295673370361 0.8386271595954895 -0.9513225555419922",
                          "-0.9921076893806458 0.8393937945365906 -0.9499253034591675",
                          "-0.9907513856887817 0.8401075601577759 -0.9507321715354919"})
      obj << "v " << v << '\n';
    for (const char* f : {"1 3 2", "4 5 6", "1 2 5", "1 5 4", "2 3 6", "2 6 5", "3 1 4", "3 4 6"}) obj << "f " << f << '\n';
  } else if (name == "captorus" || name == "captorus40") {
    // A 12 x 6 torus stretched 1e4 times along x and turned (an outside sweep's find): its
    // triangles are caps, three vertices nearly on a line, whose every pair of edges meets at a
    // small angle, so that their normals' directions are off by about 2e-4 rad. captorus40: 40 x 5
    // stretched 1e3 (an outside review's find: grazing rays met its caps at t 1 % off, behind a
    // neighbour, where the test took the vertices' weighted depths)
    const bool forty = name == "captorus40";
    const int n = forty ? 40 : 12, m = forty ? 5 : 6;
    const double stretch = forty ? 1.0e3 : 1.0e4;
    const glm::dvec3 axis = glm::normalize(glm::dvec3(0.3, 0.5, 0.8));
    const double c = std::cos(37.0 * M_PI / 180.0), s = std::sin(37.0 * M_PI / 180.0);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < m; ++j) {
        const double a = 2.0 * M_PI * i / n, b = 2.0 * M_PI * j / m;
        const glm::dvec3 p(stretch * (1.0 + 0.4 * std::cos(b)) * std::cos(a), (1.0 + 0.4 * std::cos(b)) * std::sin(a),
                           0.4 * std::sin(b));
        // Rodrigues' rotation of p about axis
        const glm::dvec3 q = p * c + glm::cross(axis, p) * s + axis * glm::dot(axis, p) * (1.0 - c);
        obj << "v " << q.x << ' ' << q.y << ' ' << q.z << '\n';
      }
    const auto v = [&](int i, int j) { return (i % n) * m + (j % m) + 1; };
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < m; ++j)
        obj << "f " << v(i, j) << ' ' << v(i + 1, j) << ' ' << v(i + 1, j + 1) << "\nf " << v(i, j) << ' '
            << v(i + 1, j + 1) << ' ' << v(i, j + 1) << '\n';
  } else if (name == "midpointcaps") {
    // A closed unit sphere (20 x 10) and 200 caps over its edges: (a, b, the midpoint of a and b
    // rounded to float), an edge split as T-junction repair leaves it (an outside sweep's find: a
    // cap's t came out 5 % short, before a triangle in front of it)
    const int n = 10, m = 20;
    std::vector<glm::dvec3> v{{0, 1, 0}};
    for (int i = 1; i < n; ++i)
      for (int j = 0; j < m; ++j) {
        const double th = M_PI * i / n, ph = 2.0 * M_PI * j / m;
        v.emplace_back(std::sin(th) * std::cos(ph), std::cos(th), std::sin(th) * std::sin(ph));
      }
    v.emplace_back(0, -1, 0);
    std::vector<glm::ivec3> f;
    const auto at = [&](int i, int j) { return 1 + (i - 1) * m + (j % m); };  // 0-based
    const int last = int(v.size()) - 1;
    for (int j = 0; j < m; ++j) f.emplace_back(0, at(1, j + 1), at(1, j));
    for (int i = 1; i < n - 1; ++i)
      for (int j = 0; j < m; ++j) {
        f.emplace_back(at(i, j), at(i, j + 1), at(i + 1, j + 1));
        f.emplace_back(at(i, j), at(i + 1, j + 1), at(i + 1, j));
      }
    for (int j = 0; j < m; ++j) f.emplace_back(last, at(n - 1, j), at(n - 1, j + 1));
    uint64_t s = 5;
    const size_t faces = f.size();
    for (int k = 0; k < 200; ++k) {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      const glm::ivec3 t = f[size_t(s >> 33) % faces];
      const glm::dvec3 mid = 0.5 * (glm::dvec3(glm::vec3(v[size_t(t.x)])) + glm::dvec3(glm::vec3(v[size_t(t.y)])));
      v.emplace_back(glm::vec3(mid));  // rounded to float: off the edge's line by its rounding
      f.emplace_back(t.x, t.y, int(v.size()) - 1);
    }
    for (const glm::dvec3& q : v) obj << "v " << float(q.x) << ' ' << float(q.y) << ' ' << float(q.z) << '\n';
    for (const glm::ivec3& t : f) obj << "f " << t.x + 1 << ' ' << t.y + 1 << ' ' << t.z + 1 << '\n';
  } else if (name == "smallbesidehuge") {
    // A triangle 0.08 wide near the origin beside one with corners at +-2e5 (an outside sweep's
    // find): the cells are about 4e5 wide, so every ray tests the small triangle from afar
    obj << "v -0.154912174 0.292154968 0.0909840837\nv -0.162222207 0.281493962 0.0952775478\n"
           "v -0.0952777714 0.281493992 0.162222117\nf 1 2 3\n"
           "v -200000 -200000 -200000\nv 200000 -200000 -200000\nv 200000 200000 200000\nf 4 5 6\n";
  } else {
    uint64_t s = 7;
    const auto rnd = [&s](double lo, double hi) {
      s = s * 6364136223846793005ULL + 1442695040888963407ULL;
      return lo + (hi - lo) * double(s >> 11) * 0x1p-53;
    };
    for (int i = 0; i < 600; ++i) {
      const glm::dvec3 p(rnd(-10, 10), rnd(-10, 10), rnd(-10, 10));
      const glm::dvec3 a = p + glm::dvec3(rnd(-1, 1), rnd(-1, 1), rnd(-1, 1));
      glm::dvec3 b = p + glm::dvec3(rnd(-1, 1), rnd(-1, 1), rnd(-1, 1));
      if (i % 3 == 0) b = p + 1e-4 * (a - p) + glm::dvec3(1e-7 * rnd(0, 1));
      for (const glm::dvec3& q : {p, a, b}) obj << "v " << q.x << ' ' << q.y << ' ' << q.z << '\n';
      obj << "f " << 3 * i + 1 << ' ' << 3 * i + 2 << ' ' << 3 * i + 3 << '\n';
    }
  }
  const fs::path path = fs::temp_directory_path() / ("gridrt_verify_untuned_" + name + ".obj");
  std::ofstream(path) << obj.str();
  return load_scene(path.string());
}

// A scene's exact-traversal grid, Embree and the referee over them (the referee's unit tests)
struct Rig {
  explicit Rig(Scene s) : scene(std::move(s)), grid(options()), embree(2) {
    grid.build(scene, 0.0f);
    embree.build(scene, 0.0f);
    topo = make_topology(grid.data());
  }
  static reference::GridOptions options() {
    reference::GridOptions go;
    go.traversal = reference::Traversal::exact;
    go.threads = 2;
    return go;
  }
  Scene scene;  // kept: Embree's filter reads it while it traces
  reference::ReferenceGridTracer grid;
  EmbreeTracer embree;
  Topology topo;
  Referee referee{grid.data(), topo, embree};
};
}  // namespace

TEST_CASE("A needle prism across the origin: no wrong answer for rays launched from its faces or grazing them",
          "[verify][grid]") {
  // The surface rule's tolerance was 8 ulps of the origin's coordinates alone: rays launched from
  // the middle of a face (near the world's origin) met the next face through their own launch
  // point (20 wrong of 1000 surface rays); it is now 8 ulps of org - v0's too, where the plane
  // value rounds. Grazing rays that pass within the vertices' rounding of a long edge are judged
  // with the referee's radius at the vertices' scale (unresolved, not wrong)
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  for (const FamilyResult& r : run(untuned_mesh("needleprism"), go, 1000, false)) {
    INFO(r.name << ":\n" << to_table({r}));
    CHECK(r.count(Verdict::crack) == 0);
    CHECK(r.count(Verdict::grid_wrong) == 0);
    CHECK(r.nan_t == 0);
  }
}

TEST_CASE("A small triangle beside a huge one: no ray far from the small one hits it", "[verify][grid]") {
  // Its edge functions' products (1e9) rounded to the same floats for rays 4e4 away: counted as
  // inside, 10 wrong answers of 2000 rays per family; zeros are now taken again exactly
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  for (const FamilyResult& r : run(untuned_mesh("smallbesidehuge"), go, 1000, false)) {
    INFO(r.name << ":\n" << to_table({r}));
    CHECK(r.count(Verdict::crack) == 0);
    CHECK(r.count(Verdict::grid_wrong) == 0);
    CHECK(r.nan_t == 0);
  }
}

TEST_CASE("Coincident triangles (copies of one, half of them reversed): judged as one, no wrong answer", "[verify][grid]") {
  // The referee tests one of each group of coincident triangles at each moved origin (it tested
  // every copy: seconds a ray on 3,000 copies, an outside sweep); the answers stay the copies'
  Scene s;
  s.name = "coincident";
  Mesh m;
  m.name = "copies";
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0.3f}, {-2, -2, -1}, {3, -2, -1}, {-2, 3, -1}};
  for (uint32_t k = 0; k < 200; ++k) m.triangles.push_back(k % 2 ? glm::uvec3(0, 2, 1) : glm::uvec3(0, 1, 2));
  m.triangles.push_back({3, 4, 5});
  m.materials.assign(m.triangles.size(), 0u);
  s.meshes.push_back(std::move(m));
  s.instances.push_back(Instance{.name = "copies", .mesh = 0});
  s.finalize();
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  for (const FamilyResult& r : run(s, go, 60, false)) {
    INFO(r.name << ":\n" << to_table({r}));
    CHECK(r.count(Verdict::crack) == 0);
    CHECK(r.count(Verdict::grid_wrong) == 0);
  }
}

TEST_CASE("Exact traversal at its defaults on meshes nobody tuned for: no crack, no wrong answer, every family",
          "[verify][grid]") {
  // The needle's silhouette edges are where a ray only touches the surface: a ray aimed exactly at
  // one may miss (no triangle test promises the touch), which the referee must not call a crack
  // cone300's slivers: t within the bound only with the plane's normal from their shortest edges
  for (const char* name : {"sphere", "needle", "soup", "tjunction", "cone300"}) {
    reference::GridOptions go;
    go.traversal = reference::Traversal::exact;
    for (const FamilyResult& r : run(untuned_mesh(name), go, 150, std::string(name) == "needle")) {
      INFO(name << " " << r.name << ":\n" << to_table({r}));
      CHECK(r.count(Verdict::crack) == 0);
      CHECK(r.count(Verdict::grid_wrong) == 0);
      // The cone's edge rays, since they pass through its slivers' shared edges exactly (they
      // passed through none before an outside sweep's find), measure 39 ulps (Embree 26 on the same
      // rays): one of the documented exceptions to the stated bound on meshes built to be hard
      // (docs/ACCURACY.md "t against the exact t"); held to twice the bound here
      const bool exception = std::string(name) == "cone300" && r.name == "edge";
      CHECK(r.max_ulps <= (exception ? 2 * kTBoundUlps : kTBoundUlps));
      CHECK(r.nan_t == 0);
    }
  }
}

TEST_CASE("A sphere 1e-6 across: the aimed, grazing and other families judge rays, no crack, no wrong answer",
          "[verify][grid]") {
  // Their directions were the scene's size, below the domain's least (2^-20): every edge, vertex
  // and graze ray lay outside it and those families judged nothing (an outside sweep); now
  // lengthened by a power of two, the same lines
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  for (const FamilyResult& r : run(untuned_mesh("tinysphere"), go, 200, false)) {
    INFO(r.name << ":\n" << to_table({r}));
    CHECK(r.count(Verdict::crack) == 0);
    CHECK(r.count(Verdict::grid_wrong) == 0);
    CHECK(r.max_ulps <= kTBoundUlps);
    if (r.name == "edge" || r.name == "vertex" || r.name == "graze" || r.name == "random" || r.name == "camera") {
      CHECK(r.rays > 100);
      CHECK(r.outside == 0);
    }
  }
}

TEST_CASE("The surface rule: an origin on a sliver's shared edge lies on its neighbour's plane, a point off it does not",
          "[verify][unit]") {
  // Two slivers of a cone of 1000 round the apex: their shared edge runs from the apex to the base
  const double a0 = 0.0, a1 = 2.0 * M_PI / 1000.0, a2 = 4.0 * M_PI / 1000.0;
  const glm::vec3 apex(0, 0, 1), b0(float(std::cos(a0)), float(std::sin(a0)), 0), b1(float(std::cos(a1)), float(std::sin(a1)), 0),
      b2(float(std::cos(a2)), float(std::sin(a2)), 0);
  const glm::vec3 mid = 0.5f * (apex + b1);  // on the shared edge, rounded
  CHECK(sh::origin_on_plane(mid, apex, b0, b1));
  CHECK(sh::origin_on_plane(mid, apex, b1, b2));  // the neighbour: its apex's two edges' normal is too rounded to
                                                  // say so, its two shortest edges' is not
  // The neighbour's plane is the launch plane turned by 2 pi / 1000 round the shared edge: the
  // launch sliver's centroid is about 1e-3 off it, far beyond 8 ulps of its coordinates
  const glm::vec3 inside = (apex + b0 + b1) / 3.0f;
  CHECK_FALSE(sh::origin_on_plane(inside, apex, b1, b2));
  // A face whose plane holds the origin is refused wherever it lies in the plane (a ray from a
  // point of the plane meets it only at t = 0). The tolerance is 8 ulps of the larger of the
  // origin's and org - v0's coordinates (the plane value rounds at the latter's scale): here
  // |org - v0| reaches 9.75, so 2^-20 * 9.75 = 9.3e-6; 2e-6 off is within it, 2e-5 off is not
  const glm::vec3 f0(10, 10, 0), f1(11, 10, 0), f2(10, 11, 0);
  CHECK(sh::origin_on_plane(glm::vec3(0.25f, 0.5f, 0.0f), f0, f1, f2));
  CHECK(sh::origin_on_plane(glm::vec3(0.25f, 0.5f, 2e-6f), f0, f1, f2));
  CHECK_FALSE(sh::origin_on_plane(glm::vec3(0.25f, 0.5f, 2e-5f), f0, f1, f2));
  // A unit face at the world's origin, launched from 0.25 away: 2e-6 off is kept (tol 2.4e-7)
  CHECK_FALSE(sh::origin_on_plane(glm::vec3(0.25f, 0.25f, 2e-6f), glm::vec3(0, 0, 0), glm::vec3(1, 0, 0), glm::vec3(0, 1, 0)));
  // A zero-area face is refused (det == 0 refuses it anyway); the origin itself at 0: exactly on
  CHECK(sh::origin_on_plane(glm::vec3(1, 2, 3), glm::vec3(0), glm::vec3(1, 1, 1), glm::vec3(2, 2, 2)));
  CHECK(sh::origin_on_plane(glm::vec3(0.0f), glm::vec3(-1, -1, 0), glm::vec3(1, -1, 0), glm::vec3(0, 1, 0)));
  // The origin at 0, a face of unit size 1e-30 off: within its own rounding, refused; 1e-5 off, kept
  CHECK(sh::origin_on_plane(glm::vec3(0.0f), glm::vec3(-1, -1, 1e-30f), glm::vec3(1, -1, 1e-30f), glm::vec3(0, 1, 1e-30f)));
  CHECK_FALSE(sh::origin_on_plane(glm::vec3(0.0f), glm::vec3(-1, -1, 1e-5f), glm::vec3(1, -1, 1e-5f), glm::vec3(0, 1, 1e-5f)));
}

TEST_CASE("Rays launched from fans of slivers: no wrong answer (the surface rule), where the origin epsilon alone "
          "gave 4 / 3 / 7 / 14 of 300",
          "[verify][grid]") {
  // A ray from a sliver's edge midpoint, leaving nearly in its neighbour's plane, met that
  // neighbour (through the origin) at 1.5 to 3.2 origin epsilons; the exact answer is a sliver
  // further on, or nothing
  for (const char* name : {"cone64", "cone128", "cone300", "cone1000"}) {
    reference::GridOptions go;
    go.traversal = reference::Traversal::exact;
    go.threads = 2;
    VerifyOptions vo;
    vo.family.rays = 300;
    vo.families = {Family::surface};
    vo.translated = false;
    vo.threads = 2;
    const auto make = [go](const Scene&) -> std::unique_ptr<Tracer> {
      return std::make_unique<reference::ReferenceGridTracer>(go);
    };
    for (const FamilyResult& r : verify_scene(untuned_mesh(name), go, make, vo)) {
      INFO(name << " " << r.name << ":\n" << to_table({r}));
      CHECK(r.rays == 300);
      CHECK(r.count(Verdict::grid_wrong) == 0);
      CHECK(r.count(Verdict::crack) == 0);
    }
  }
}

TEST_CASE("Cap slivers: a torus stretched 1e4 times and caps of rounded edge midpoints - no wrong answer, t "
          "within the bound",
          "[verify][grid]") {
  // Every pair of a cap's edges meets at a small angle, so a normal made in float is off by about
  // 2e-4 rad on the torus: rays launched from the caps met a neighbour's plane at a t of noise
  // (0.2 units; 54 wrong answers of 400), rays through their vertices and grazing them at t's
  // 10,000 to 20,000 ulps off (Embree 16,000), and a cap made of a rounded edge midpoint was met
  // 5 % short, before a triangle in front of it. The normal is now made again from the exact edges
  // where it is that ill-conditioned, the distance's plane value taken at the vertex nearest the
  // hit and the surface rule's at the vertex nearest the origin (docs/ACCURACY.md, "cap slivers")
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  go.threads = 2;
  VerifyOptions vo;
  vo.family.rays = 400;
  vo.families = {Family::surface, Family::vertex, Family::graze};
  vo.translated = false;
  vo.threads = 2;
  const auto make = [go](const Scene&) -> std::unique_ptr<Tracer> {
    return std::make_unique<reference::ReferenceGridTracer>(go);
  };
  for (const char* name : {"captorus", "captorus40", "midpointcaps"})
    for (const FamilyResult& r : verify_scene(untuned_mesh(name), go, make, vo)) {
      INFO(name << " " << r.name << ":\n" << to_table({r}));
      CHECK(r.rays > 0);
      CHECK(r.count(Verdict::grid_wrong) == 0);
      CHECK(r.count(Verdict::crack) == 0);
      CHECK(r.max_ulps <= kTBoundUlps);
      CHECK(r.nan_t == 0);
    }
}

TEST_CASE("The referee finds Moller-Trumbore's cracks at shared vertices (so the zero above can fail)",
          "[verify][grid]") {
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  go.triangle_test = reference::GridOptions::TriangleTest::moller;
  go.threads = 2;
  VerifyOptions vo;
  vo.family.rays = 400;
  vo.families = {Family::vertex};
  vo.translated = false;
  vo.threads = 2;
  const auto make = [go](const Scene&) -> std::unique_ptr<Tracer> {
    return std::make_unique<reference::ReferenceGridTracer>(go);
  };
  const std::vector<FamilyResult> res = verify_scene(make_builtin("cornell"), go, make, vo);
  REQUIRE(res.size() == 1);
  INFO(to_table(res));
  CHECK(res[0].count(Verdict::crack) > 0);
}

TEST_CASE("Exact traversal at its defaults on a real scene: shared edges and vertices, surface-launched rays",
          "[verify][scenes]") {
  const std::string path = real_scene("sibenik-teapots.json");
  if (path.empty()) return;
  const Scene scene = load_scene(path);
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  go.threads = 2;
  VerifyOptions vo;
  vo.family.rays = 400;
  vo.families = {Family::edge, Family::vertex, Family::surface, Family::plane};
  vo.translated = false;
  vo.threads = 2;
  const auto make = [go](const Scene&) -> std::unique_ptr<Tracer> {
    return std::make_unique<reference::ReferenceGridTracer>(go);
  };
  for (const FamilyResult& r : verify_scene(scene, go, make, vo)) {
    INFO(r.name << ":\n" << to_table({r}));
    CHECK(r.failures() == 0);
    CHECK(r.rays > 0);
  }
}

TEST_CASE("gridrt verify: a table, JSON, and exit 3 where the exact traversal cracks", "[verify][cli]") {
  const fs::path json = fs::temp_directory_path() / "gridrt_verify_test.json";
  const test::Run ok = test::run_tool("verify builtin:cornell --traversal exact -n 100 --families edge,vertex,degenerate "
                                      "--no-translated --threads 2 --json " + json.string());
  INFO(ok.output);
  CHECK(ok.exit_code == 0);
  CHECK(ok.output.find("vertex") != std::string::npos);
  std::ifstream f(json);
  const nlohmann::json j = nlohmann::json::parse(f);
  CHECK(j["families"].size() == 3);
  CHECK(j["failures"] == 0);
  const test::Run bad = test::run_tool("verify builtin:cornell --traversal exact --triangle-test moller -n 400 "
                                       "--families vertex --no-translated --threads 2");
  INFO(bad.output);
  CHECK(bad.exit_code == 3);
  CHECK(test::run_tool("verify builtin:cornell --families nonsense").exit_code == 2);  // a bad command line
  fs::remove(json);
}

TEST_CASE("gridrt verify: a model too small for the translated run's offset skips that run, or names why when asked",
          "[verify][cli]") {
  // A few triangles 2e-3 across: at (1e5, -5e4, 7.5e4) a float's step is 0.0078, every vertex and
  // the framed camera round to one point. Before, the whole command failed with "camera: eye and
  // target coincide".
  const fs::path obj = fs::temp_directory_path() / "gridrt_verify_tiny.obj";
  {
    std::ofstream f(obj);
    f << "v -0.001 -0.001 0\nv 0.001 -0.001 0\nv 0 0.001 0.0005\nv 0.001 0.001 -0.001\nf 1 2 3\nf 2 4 3\n";
  }
  const Scene scene = load_scene(obj.string());
  CHECK(translated_problem(scene, glm::vec3(1.0e5f, -5.0e4f, 7.5e4f)) != "");
  CHECK(translated_problem(scene, glm::vec3(1.0f, 2.0f, 3.0f)) == "");
  CHECK(translated_problem(make_builtin("cornell"), glm::vec3(1.0e5f, -5.0e4f, 7.5e4f)) == "");
  const test::Run skipped = test::run_tool("verify " + obj.string() + " --traversal exact -n 50 --threads 2");
  INFO(skipped.output);
  CHECK(skipped.exit_code == 0);
  CHECK(skipped.output.find("the translated run is skipped") != std::string::npos);
  CHECK(skipped.output.find("\ntranslated ") == std::string::npos);  // no table row
  CHECK(skipped.output.find("\ncamera ") != std::string::npos);      // the other families ran
  const test::Run asked = test::run_tool("verify " + obj.string() + " --traversal exact -n 50 --threads 2 "
                                         "--families camera,translated");
  INFO(asked.output);
  CHECK(asked.exit_code == 1);
  CHECK(asked.output.find("the translated run") != std::string::npos);
  CHECK(asked.output.find("eye and target coincide") == std::string::npos);
  fs::remove(obj);
}

TEST_CASE("gridrt verify: cells too fine for the translated run's coordinates skip that run, with the reason",
          "[verify][cli]") {
  // An outside tester's find: a unit triangle with --cell-size 0.05 exited 1 with "cells of 0.05 are
  // narrower than 64 ulps ... at 100002 from the origin", a reach the scene never has (the
  // translated run's), and no family's results
  const fs::path obj = fs::temp_directory_path() / "gridrt_verify_fine_cells.obj";
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  reference::GridOptions go;
  go.cell_size = 0.05f;
  CHECK_THAT(translated_problem(load_scene(obj.string()), glm::vec3(1.0e5f, -5.0e4f, 7.5e4f), &go),
             Catch::Contains("narrower than"));
  const test::Run r = test::run_tool("verify " + obj.string() + " --traversal exact -n 20 --threads 2 --cell-size 0.05");
  INFO(r.output);
  CHECK(r.exit_code == 0);
  CHECK_THAT(r.output, Catch::Contains("the translated run is skipped") && Catch::Contains("narrower than"));
  CHECK_THAT(r.output, Catch::Contains("\ncamera ") && Catch::Contains("verify: OK"));
  // A grid the scene itself cannot take is the run's error, not the translated run's
  const test::Run bad = test::run_tool("verify " + obj.string() + " --traversal exact -n 20 --aabb-padding 0");
  INFO(bad.output);
  CHECK(bad.exit_code == 2);  // options that contradict one another: the command line's error
  CHECK_THAT(bad.output, Catch::Contains("AABB padding of 0"));
  CHECK(bad.output.find("translated run is skipped") == std::string::npos);
  fs::remove(obj);
}

TEST_CASE("gridrt render --backend embree: a camera beyond Embree's limits is refused with a message, not an abort",
          "[verify][cli]") {
  // Its eye lies beyond the ray domain's 2^24 (and Embree's ~1.8e18): the scene is refused at load
  // (every primary ray would be rejected), exit 1, no picture; the oracle's own refusal of rays it
  // cannot take is tested in "Domain: what the tracers reject, identically"
  const fs::path scene = fs::temp_directory_path() / "gridrt_far_camera.json";
  {
    std::ofstream f(scene);
    f << R"({"name": "far", "meshes": {"m": {"file": ")" << GRIDRT_DATA_DIR << R"(/fixtures/quad.obj"}},
             "instances": [{"mesh": "m"}],
             "camera": {"eye": [3e18, 1e17, 2e17], "target": [0, 0, 0], "up": [0, 1, 0], "vfov": 50}})";
  }
  const fs::path out = fs::temp_directory_path() / "gridrt_far_camera.ppm";
  const test::Run r = test::run_tool("render " + scene.string() + " --backend embree --width 8 --height 8 -o " + out.string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK(r.output.find("beyond 2^24") != std::string::npos);
  CHECK(!fs::exists(out));
  fs::remove(scene);
  fs::remove(out);
}

TEST_CASE("Exact referee: an answer right for the ray as traced (v - org in float, moved within its rounding) is "
          "unresolved, a wrong one is not", "[verify][unit]") {
  Rig rig(make_builtin("cornell"));
  reference::ReferenceGridTracer& grid = rig.grid;
  const Topology& topo = rig.topo;
  const Referee& referee = rig.referee;
  // A ray from 3e5 away through the centroid of triangle 0, and through a point 1e-4 beyond its
  // edge v1-v2 (the origin's rounding there is 16 ulps of 3e5, about 0.3 units)
  const auto& t = topo.tri[0];
  const glm::vec3 n = glm::normalize(glm::cross(t[1] - t[0], t[2] - t[0]));
  const glm::vec3 centroid = (t[0] + t[1] + t[2]) / 3.0f;
  const glm::vec3 mid = (t[1] + t[2]) * 0.5f;
  const glm::vec3 beyond = mid + glm::normalize(mid - t[0]) * 1.0e-4f;
  const glm::vec3 o = centroid + n * 3.0e5f;
  for (const glm::vec3 target : {centroid, beyond}) {
    const std::vector<Ray> rs{ray(o, target - o)};
    const Ray& r = rs[0];
    std::vector<Hit> got(1);
    grid.trace(rs, got);
    INFO("target " << target.x << " " << target.y << " " << target.z << " got t " << got[0].t);
    // The tracer's own answer (through the centroid a hit; beyond the edge a hit or a miss): right
    // for the ray as traced
    if (target == centroid) REQUIRE(!is_miss(got[0]));
    CHECK(referee.exact_for_moved_origin(r, got[0], sh::kNoRef));
    // A miss through the centroid: no moved origin gives it
    Hit miss = got[0];
    miss.instance = sh::kNoInstance;
    if (target == centroid) CHECK_FALSE(referee.exact_for_moved_origin(r, miss, sh::kNoRef));
  }
  // Another wall's triangle, nowhere near the ray: never right
  const std::vector<Ray> rs{ray(o, centroid - o)};
  const Ray& r = rs[0];
  std::vector<Hit> got(1);
  grid.trace(rs, got);
  for (size_t k = 0; k < topo.tri.size(); ++k) {
    // a triangle the ray misses by far more than the rounding: its centroid a unit off the line
    const glm::dvec3 c = glm::dvec3(topo.tri[k][0] + topo.tri[k][1] + topo.tri[k][2]) / 3.0;
    const glm::dvec3 d = glm::normalize(glm::dvec3(r.dir)), oc = c - glm::dvec3(r.org);
    if (exact_test(r, topo.tri[k][0], topo.tri[k][1], topo.tri[k][2]).hit || glm::length(oc - d * glm::dot(oc, d)) < 1.0)
      continue;
    Hit wrong = got[0];
    wrong.instance = sh::ref_instance(topo.ref[k]);
    wrong.triangle = sh::ref_triangle(topo.ref[k]);
    CHECK_FALSE(referee.exact_for_moved_origin(r, wrong, sh::kNoRef));
    break;
  }
}

TEST_CASE("Exact referee: a miss within rounding of a T-junction's open edge is unresolved, one at a shared edge "
          "is not", "[verify][unit]") {
  Rig rig(untuned_mesh("tjunction"));
  reference::ReferenceGridTracer& grid = rig.grid;
  const Referee& referee = rig.referee;
  EmbreeTracer& embree = rig.embree;
  // Rays straight down from z = 1 (t = 1 at the plane); the square (2, 2) spans [0.125, 0.1875]^2
  const auto down = [](double x, double y) { return ray(glm::vec3(float(x), float(y), 1.0f), glm::vec3(0, 0, -1)); };
  const double h = 1.0 / 16;
  // Its T-vertex (0.15625, 0.125), just above it (1e-9: within 16 ulps of 1), on the open edge
  // (0.125, 0.125)-(0.15625, 0.125) a little way along, and on the square below's upper edge: open edges
  CHECK(referee.near_open_edge(down(2.5 * h, 2 * h), 1.0));
  CHECK(referee.near_open_edge(down(2.5 * h, 2 * h + 1e-9), 1.0));
  CHECK(referee.near_open_edge(down(2.2 * h, 2 * h), 1.0));
  // The edge from the T-vertex to the square's upper left corner, shared by two triangles: not open
  const double s = 0.4;  // a point along it, away from both ends
  CHECK_FALSE(referee.near_open_edge(down(2.5 * h + s * (2 * h - 2.5 * h), 2 * h + s * h), 1.0));
  // A square's inside, far from every edge, and its left edge (x = 0.125: the same two positions
  // as the right edge of the square beside it, a shared edge)
  CHECK_FALSE(referee.near_open_edge(down(2.9 * h, 2.5 * h), 1.0));
  CHECK_FALSE(referee.near_open_edge(down(2 * h, 2.5 * h), 1.0));
  // The verdict: a miss straight through the T-vertex is unresolved, a miss through the inside is
  // wrong
  for (const auto& [x, y, verdict] : {std::tuple{2.5 * h, 2 * h + 1e-9, Verdict::unresolved},
                                      std::tuple{2.9 * h, 2.5 * h, Verdict::grid_wrong}}) {
    const std::vector<Ray> rs{down(x, y)};
    std::vector<Hit> got(1), want(1);
    grid.trace(rs, got);
    embree.trace(rs, want);
    REQUIRE(!is_miss(got[0]));
    Hit miss = got[0];
    miss.instance = sh::kNoInstance;
    const Judgement j = referee.judge(rs[0], miss, want[0], {});
    INFO(x << " " << y << ": " << to_string(j.verdict) << " (" << j.why << ")");
    CHECK(j.verdict == verdict);
  }
}

// An outside sweep's find: the edge family's identity was o + 2d == a + b, which put a + b, not the
// edge's midpoint, on the ray: its rays passed through no edge (a thousand on the atrium, no tie),
// and on a scene moved 2^21 away their directions, about (a + b) / 4, left the domain.
// Now every edge ray meets two triangles exactly on their shared boundary at one t, and every
// vertex ray two or more, wherever the ray reaches the point beyond its origin epsilon.
TEST_CASE("The edge and vertex families' rays pass exactly through a shared edge or vertex, here and far away",
          "[verify][unit]") {
  reference::GridOptions go;
  go.traversal = reference::Traversal::exact;
  go.threads = 2;
  for (const glm::vec3 offset : {glm::vec3(0.0f), glm::vec3(1.0e5f, -5.0e4f, 7.5e4f)}) {
    const Scene scene = offset == glm::vec3(0.0f) ? make_builtin("teapot") : translated(make_builtin("teapot"), offset);
    reference::ReferenceGridTracer ref(go);
    ref.build(scene, 0.0f);
    const Topology topo = make_topology(ref.data());
    EmbreeTracer embree(2);
    embree.build(scene, 0.0f);
    for (const Family f : {Family::edge, Family::vertex}) {
      const FamilyRays fr = make_family(f, scene, ref.data(), topo, embree, FamilyOptions{300, 1});
      size_t reached = 0, through = 0;
      for (size_t i = 0; i < fr.rays.size(); ++i) {
        std::vector<ExactTest> hits;
        for (uint32_t r : fr.aimed[i]) {
          const size_t k = topo.index_of(r);
          REQUIRE(k != SIZE_MAX);
          const ExactTest e = exact_test(fr.rays[i], topo.tri[k][0], topo.tri[k][1], topo.tri[k][2]);
          if (e.hit && e.boundary) hits.push_back(e);
        }
        reached += !hits.empty();
        bool pair = false;
        for (size_t a = 0; a < hits.size() && !pair; ++a)
          for (size_t b = a + 1; b < hits.size() && !pair; ++b) pair = compare_t(hits[a], hits[b]) == 0;
        through += pair;
      }
      INFO(to_string(f) << " at offset (" << offset.x << ", " << offset.y << ", " << offset.z << "): " << fr.rays.size()
                        << " rays, " << reached << " reach an aimed triangle's boundary, " << through
                        << " two of them at one t");
      CHECK(fr.rays.size() >= 250);
      CHECK(reached >= fr.rays.size() / 2);
      CHECK(through >= reached * 9 / 10);
    }
  }
}

TEST_CASE("Faces 1 ulp apart met by grazing rays: ordered within their conditioning, judged near - faces far apart "
          "are not", "[verify][grid]") {
  // Two closed tetrahedra x, y, z >= 0, x + y + z <= s, s 1 ulp apart in float, and a third at
  // s = 1.5. A grazing ray meets the two slanted faces at t's closer than its condition number
  // (1e3 to 1e4) lets any float test order: the grid computed one t for both and the tie rule
  // took the lower reference, which `verify` failed as wrong (an outside sweep: 5 of 3,000 graze
  // rays, exit 3). Such answers are near; a face well apart from the closest is still wrong.
  Scene s;
  s.name = "layers";
  Mesh m;
  m.name = "layers";
  for (const float sz : {1.0000298f, 1.0000299f, 1.5f}) {
    const uint32_t b = uint32_t(m.positions.size());
    m.positions.insert(m.positions.end(), {{0, 0, 0}, {sz, 0, 0}, {0, sz, 0}, {0, 0, sz}});
    for (const glm::uvec3 f : {glm::uvec3(0, 2, 1), glm::uvec3(0, 1, 3), glm::uvec3(0, 3, 2), glm::uvec3(1, 2, 3)})
      m.triangles.push_back(f + b);
  }
  m.materials.assign(m.triangles.size(), 0u);
  s.meshes.push_back(std::move(m));
  s.instances.push_back(Instance{.name = "layers", .mesh = 0});
  s.finalize();
  Rig rig(s);
  VerifyOptions vo;
  vo.family.rays = 3000;
  vo.family.seed = 1;
  const FamilyResult r = verify_family(Family::graze, rig.scene, rig.grid, rig.grid.data(), rig.topo, rig.embree, vo);
  INFO(to_table({r}));
  CHECK(r.count(Verdict::grid_wrong) == 0);
  CHECK(r.count(Verdict::crack) == 0);
  CHECK(r.count(Verdict::near) > 0);
  // A ray from outside through the slanted faces, well conditioned: it meets the outer (s = 1.5)
  // face first; the innermost one reported instead is wrong, not near
  const glm::vec3 target(0.2f, 0.3f, 0.4f);  // inside all three
  const glm::vec3 o(2.0f, 2.0f, 2.0f);
  const Ray ry = ray(o, target - o);
  std::vector<Hit> got(1);
  rig.grid.trace(std::vector<Ray>{ry}, got);
  REQUIRE(!is_miss(got[0]));
  REQUIRE(got[0].triangle == 11);  // the third tetrahedron's slanted face
  Hit inner = got[0];
  inner.triangle = 3;  // the first tetrahedron's
  const auto& tri = rig.topo.tri[rig.topo.index_of(sh::ref_pack(0, 3))];
  const ExactTest e = exact_test(ry, tri[0], tri[1], tri[2]);
  REQUIRE(e.hit);
  inner.t = float(e.t);
  const Judgement j = rig.referee.judge(ry, inner, got[0], {});
  INFO(j.why);
  CHECK(j.verdict == Verdict::grid_wrong);
}
