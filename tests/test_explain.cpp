// gridrt explain's formats: the full and brief text, JSON, rays given as text, the alignment of two
// records with a divergence planted by hand, the OBJ and SVG pictures, and the HTML viewer loaded
// in a real headless browser (Debian's chromium).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <regex>
#include <set>
#include <sstream>

#include "gridrt/common/camera.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/reference/explain_export.h"
#include "gridrt/plan/explain_format.h"
#include "gridrt/reference/grid.h"
#include "tests/run_tool.h"

using namespace gridrt;
namespace sh = gridrt::shared;
namespace fs = std::filesystem;
using reference::ExplainRecord;
using plan::kNoEvent;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "gridrt_test_explain";
  fs::create_directories(dir);
  return dir / name;
}

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), {});
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t p = text.find(what); p != std::string::npos; p = text.find(what, p + what.size())) ++n;
  return n;
}

// The Cornell box's record of a camera ray through the middle of the image (exact traversal):
// cells, slots, tests, a hit.
struct Cornell {
  Scene scene = load_scene("builtin:cornell");
  reference::ReferenceGridTracer grid{reference::GridOptions{{.traversal = reference::Traversal::exact}, {}, {.threads = 1}}};
  plan::ExplainNames names;
  Cornell() {
    grid.build(scene, 0.0f);
    names = plan::ExplainNames::of(scene);
  }
  ExplainRecord record(uint32_t x = 20, uint32_t y = 20) const {
    return grid.explain_ray(camera_ray(scene.frame_camera(), 48, 36, x, y));
  }
};

size_t first_of(const ExplainRecord& r, uint32_t kind, size_t from = 0) {
  for (size_t i = from; i < r.events.size(); ++i)
    if (r.events[i].kind == kind) return i;
  return kNoEvent;
}

}  // namespace

TEST_CASE("Explain: rays as text - decimal, C99 hex, defaults, launch references, errors", "[unit][explain]") {
  const Ray a = plan::parse_ray("1, -2.5, 0x1.8p+1, 0,0,-1");
  CHECK(a.org == glm::vec3(1.0f, -2.5f, 3.0f));
  CHECK(a.dir == glm::vec3(0.0f, 0.0f, -1.0f));
  CHECK(a.tmin == 0.0f);
  CHECK(std::isinf(a.tmax));
  CHECK(a.launch_ref == sh::kNoRef);
  const Ray b = plan::parse_ray("0,0,0,1,0,0,0x1p-4,inf,3:12");
  CHECK(b.tmin == 0.0625f);
  CHECK(std::isinf(b.tmax));
  CHECK(b.launch_ref == ((3u << 16) | 12u));
  CHECK(plan::parse_ray("0,0,0,1,0,0,0,10,0x00030007").launch_ref == 0x00030007u);
  CHECK(plan::parse_ray("0,0,0,1,0,0,0,10,none").launch_ref == sh::kNoRef);
  for (const char* bad : {"1,2,3", "1,2,3,4,5,x", "1,2,3,4,5,6,7", "1,2,3,4,5,6,0,1,2:", "1,2,3,4,5,6,0,1,0x1ffffffff",
                          "1,2,3,4,5,6,", "1e99,0,0,1,0,0"})
    CHECK_THROWS_AS(plan::parse_ray(bad), Error);
  // A well-formed INSTANCE:TRIANGLE out of a reference's range says so (it said "not INSTANCE:TRIANGLE")
  CHECK_THROWS_WITH(plan::parse_ray("0,0,0,1,0,0,0,10,0:65536"), Catch::Contains("out of range"));
  CHECK_THROWS_WITH(plan::parse_ray("0,0,0,1,0,0,0,10,65535:0"), Catch::Contains("out of range"));
  CHECK_THROWS_WITH(plan::parse_ray("0,0,0,1,0,0,0,10,a:0"), Catch::Contains("is not INSTANCE:TRIANGLE"));
  // A file: comments, blank lines, and an error with its line
  const fs::path f = scratch("rays.txt");
  std::ofstream(f) << "# two rays\n\n0,0,0, 1,0,0  # along x\n0x1p+0,0,0,0,1,0,0,5\n";
  const std::vector<Ray> rays = plan::read_ray_file(f.string());
  REQUIRE(rays.size() == 2);
  CHECK(rays[1].org.x == 1.0f);
  CHECK(rays[1].tmax == 5.0f);
  std::ofstream(f) << "0,0,0,1,0,0\n1,2\n";
  try {
    plan::read_ray_file(f.string());
    FAIL("a bad line was accepted");
  } catch (const Error& e) {
    CHECK_THAT(e.what(), Catch::Contains("rays.txt:2"));
  }
}

TEST_CASE("Explain: full text numbers every event, brief folds empty cells, JSON keeps the records", "[unit][explain]") {
  // One quad at z = 0 and a ray from far along z: many empty cells before it
  Scene s;
  s.name = "quad";
  Mesh m;
  m.name = "wall";
  m.positions = {{0, 0, 0}, {4, 0, 0}, {4, 4, 0}, {0, 4, 0}, {0, 0, 8}, {0.1f, 0, 8}, {0, 0.1f, 8}};
  m.triangles = {{0, 1, 2}, {0, 2, 3}, {4, 5, 6}};
  m.materials = {0, 0, 0};
  s.meshes.push_back(m);
  s.instances.push_back(Instance{.name = "", .mesh = 0});
  s.finalize();
  // (the plain DDA: empty-space skipping would pass the empty cells as one box, kEvSkip)
  reference::ReferenceGridTracer grid(reference::GridOptions{
      {.traversal = reference::Traversal::exact, .skip_empty = false}, {.resolution = glm::uvec3(8, 8, 16)}, {.threads = 1}});
  grid.build(s, 0.0f);
  Ray r{};
  r.org = glm::vec3(1.3f, 1.7f, 7.9f);
  r.dir = glm::vec3(0.0f, 0.0f, -1.0f);
  r.tmin = 0.0f;
  r.tmax = std::numeric_limits<float>::infinity();
  r.launch_ref = sh::kNoRef;
  const ExplainRecord rec = grid.explain_ray(r);
  REQUIRE_FALSE(is_miss(rec.hit));
  const plan::ExplainNames names = plan::ExplainNames::of(s);
  CHECK(names.instances.at(0) == "wall");  // the mesh's name where the instance has none

  // The empty visits, counted from the events themselves
  size_t empty = 0;
  for (size_t i = 0; i + 1 < rec.events.size(); ++i)
    empty += rec.events[i].kind == sh::kEvCell && rec.events[i + 1].kind == sh::kEvSlot &&
             rec.events[i + 1].ref == sh::kBlank && rec.events[i + 1].slot == 0u;
  REQUIRE(empty >= 3);

  const std::string full = plan::explain_text(rec, {false, &names});
  INFO(full);
  CHECK(count(full, "\n#") + count(full, "\n #") + count(full, "\n  #") == rec.events.size());
  CHECK_THAT(full, Catch::Contains("[0x") && Catch::Contains("\"wall\""));
  const std::string brief = plan::explain_text(rec, {true, &names});
  INFO(brief);
  CHECK_THAT(brief, !Catch::Contains("0x"));
  // One folded line "cells A-B empty (N)" whose N counts the empty visits of the run
  const std::regex folded(R"(cells (\d+)-(\d+) empty \((\d+)\))");
  std::smatch mt;
  REQUIRE(std::regex_search(brief, mt, folded));
  CHECK(std::stoul(mt[3]) == std::stoul(mt[2]) - std::stoul(mt[1]) + 1);
  CHECK(std::stoul(mt[3]) <= empty);
  CHECK(std::stoul(mt[3]) >= 2);
  CHECK(count(brief, "\n") < count(full, "\n"));

  // JSON: every event with its raw fields, names and bits
  const nlohmann::json j = plan::explain_json(rec, {false, &names});
  REQUIRE(j["events"].size() == rec.events.size());
  int rejected = 0;
  for (size_t i = 0; i < rec.events.size(); ++i) {
    const auto& e = j["events"][i];
    CHECK(e["kind"] == rec.events[i].kind);
    CHECK(e["kind_name"] == plan::event_kind_name(rec.events[i].kind));
    CHECK(e["f1_hex"][3] == reference::hex(rec.events[i].f1.w));
    // A test's reported t only where the geometry accepted the triangle; null (never a 0 shown as
    // a distance) where it was rejected
    if (rec.events[i].kind == sh::kEvTest) {
      const uint32_t code = rec.events[i].code;
      const bool t_known = code == sh::kTestAccepted || code == sh::kTestAlphaKeyed || code == sh::kTestTieLost ||
                           code == sh::kTestOriginPlane;
      CHECK(e["computed"][7] == t_known);
      CHECK(e["fields"]["t"].is_null() == !t_known);
      rejected += t_known ? 0 : 1;
    }
  }
  CHECK(rejected > 0);
  CHECK(j["hit"]["reference"]["name"] == "wall");
  CHECK(j["hit"]["tests"] == rec.hit.tests);
}

TEST_CASE("Explain: a planted divergence is shown aligned, its context kept, the rest re-aligned", "[unit][explain]") {
  const Cornell c;
  const ExplainRecord want = c.record();
  const size_t test = first_of(want, sh::kEvTest);
  REQUIRE(test != kNoEvent);
  const size_t later_slot = first_of(want, sh::kEvSlot, test + 1);
  REQUIRE(later_slot != kNoEvent);
  REQUIRE(later_slot + 3 < want.events.size());
  // The "shader": the first test's t*|det| one ulp off, a later slot read missing, an extra
  // status read before the last event
  ExplainRecord got = want;
  uint32_t bits;
  std::memcpy(&bits, &got.events[test].f0.w, 4);
  bits += 1u;
  std::memcpy(&got.events[test].f0.w, &bits, 4);
  got.events.erase(got.events.begin() + std::ptrdiff_t(later_slot));
  sh::ExplainEvent extra{};
  extra.kind = sh::kEvStatus;
  extra.step = 999u;
  got.events.insert(got.events.end() - 1, extra);

  const plan::EventAlignment al = plan::align_events(want.events, got.events);
  REQUIRE(al.first_divergence != kNoEvent);
  const auto& first = al.rows[al.first_divergence];
  CHECK(first.a == test);
  CHECK(first.b == test);
  CHECK(plan::differing_fields(want.events[test], got.events[test], true) ==
        std::vector<std::string>{"f0.w (t*|det|)"});
  // Every event of either side appears once, in order; all but the three planted rows agree
  size_t only_a = 0, only_b = 0, same = 0, next_a = 0, next_b = 0;
  for (const auto& row : al.rows) {
    if (row.a != kNoEvent) CHECK(row.a == next_a++);
    if (row.b != kNoEvent) CHECK(row.b == next_b++);
    only_a += row.b == kNoEvent;
    only_b += row.a == kNoEvent;
    same += row.same;
  }
  CHECK(next_a == want.events.size());
  CHECK(next_b == got.events.size());
  CHECK(only_a == 1);
  CHECK(only_b == 1);
  CHECK(same == want.events.size() - 2);
  CHECK(al.differing_rows() == 3);
  // The missing slot read stands alone on the reference's side
  for (const auto& row : al.rows)
    if (row.b == kNoEvent) CHECK(row.a == later_slot);

  const plan::ExplainFormat fmt{false, &c.names};
  const std::string text = plan::divergence_text(want, got, fmt);
  INFO(text);
  const std::string brief = plan::divergence_text(want, got, {true, &c.names});
  INFO(brief);
  CHECK_THAT(brief, Catch::Contains("^ f0.w (t*|det|)") && Catch::Contains("[0x"));  // the bits that differ
  CHECK_THAT(brief, Catch::Contains(" identical ("));                              // runs folded
  CHECK(count(brief, "\n") < count(text, "\n"));
  CHECK_THAT(text, Catch::Contains(">> ") && Catch::Contains("#" + std::to_string(test)));
  CHECK_THAT(text, Catch::Contains(plan::visit_text(want, test)));
  CHECK_THAT(text, Catch::Contains("^ f0.w (t*|det|)"));
  CHECK_THAT(text, Catch::Contains("(only in the reference)") && Catch::Contains("(only in the shader)"));
  CHECK_THAT(text, Catch::Contains("1 only in the reference, 1 only in the shader"));
  // After the divergence the rows line up again: the event after the missing slot read pairs
  // with the shader's event one number lower
  const std::string after = "#" + std::to_string(later_slot + 1) + " ";
  const size_t at = text.find(after, text.find(">> "));
  REQUIRE(at != std::string::npos);
  const std::string line = text.substr(at, text.find('\n', at) - at);
  CHECK_THAT(line, Catch::Contains(" = ") && Catch::Contains("#" + std::to_string(later_slot)));
  // Identical records say so
  CHECK_THAT(plan::divergence_text(want, want, fmt), Catch::StartsWith("identical"));
  // JSON of the alignment
  const nlohmann::json aj = plan::alignment_json(want, got, al);
  CHECK(aj["first_divergence"]["reference_event"] == test);
  CHECK(aj["rows"].size() == al.rows.size());
}

TEST_CASE("Explain: OBJ and SVG pictures hold the ray, every visited cell and every tested triangle", "[unit][explain]") {
  const Cornell c;
  const ExplainRecord rec = c.record();
  size_t cells = 0;
  std::set<uint32_t> tested;
  for (const auto& e : rec.events) {
    cells += e.kind == sh::kEvCell;
    if (e.kind == sh::kEvTest) tested.insert(e.ref);
  }
  REQUIRE(cells > 0);
  REQUIRE(!tested.empty());
  const std::string obj = reference::explain_obj(rec, c.grid.data(), "ray.mtl");
  CHECK(count(obj, "\nl ") == 1);                                            // the ray
  CHECK(count(obj, "# step ") == cells);                                     // a box per visited cell
  CHECK(count(obj, "\nf ") == cells * 6 + tested.size() + 8);                // 6 quads, 1 face, the hit's octahedron
  CHECK_THAT(obj, Catch::Contains("g ray") && Catch::Contains("g hit_triangle") && Catch::Contains("g hit_point"));
  // Every face names vertices that exist
  const size_t vertices = count(obj, "\nv ");
  std::istringstream in(obj);
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("f ", 0) == 0 || line.rfind("l ", 0) == 0) {
      std::istringstream ls(line.substr(2));
      size_t k;
      while (ls >> k) CHECK((k >= 1 && k <= vertices));
    }
  const std::string mtl = reference::explain_mtl();
  for (const char* g : {"ray", "cells_empty", "cells_with_references", "cells_saturated", "triangles_rejected",
                        "triangles_accepted", "hit_triangle", "hit_point"})
    CHECK_THAT(mtl, Catch::Contains(std::string("newmtl ") + g));

  const std::string svg = reference::explain_svg(rec, c.grid.data(), {true, &c.names});
  CHECK_THAT(svg, Catch::StartsWith("<svg xmlns=\"http://www.w3.org/2000/svg\""));
  CHECK(count(svg, "id=\"cell-") == cells);
  CHECK(count(svg, "id=\"tri-") == tested.size());
  CHECK(count(svg, "id=\"hit\"") == 1);
  CHECK(count(svg, "<svg") == count(svg, "</svg>"));
}

TEST_CASE("Explain: the command line - any ray, ray files, kinds, brief, JSON, pictures", "[cli][explain]") {
  using test::run_tool;
  // A pixel's primary ray says it follows the frame's gather: the exact traversal
  const test::Run p = run_tool("explain builtin:cornell --width 48 --height 36 --pixel 24,18 --kind primary --brief");
  INFO(p.output);
  REQUIRE(p.exit_code == 0);
  CHECK_THAT(p.output, Catch::Contains("explained by the exact traversal on the gather's grid (the watertight test), as the frame's gather traces it"));
  CHECK_THAT(p.output, Catch::Contains("traversal exact") && !Catch::Contains("0x"));
  CHECK_THAT(p.output, Catch::Contains("capacity") && Catch::Contains("policy"));
  // Shadow rays toward the Cornell box's light
  const test::Run s = run_tool("explain builtin:cornell --width 48 --height 36 --pixel 24,30 --kind shadow --brief");
  INFO(s.output);
  REQUIRE(s.exit_code == 0);
  CHECK_THAT(s.output, Catch::Contains("the shadow ray toward light 0"));
  // Rays from a file (decimal, hex, a NaN ray), as JSON, with their pictures (one file a ray)
  const fs::path f = scratch("cli-rays.txt");
  std::ofstream(f) << "# the box's centre, looking down, up and askew\n2.78,2.74,2.79,0,-1,0\n"
                      "2.78,2.74,2.79,0x0p+0,0x1p+0,0\nnan,0,0,1,0,0 # rejected\n";
  const fs::path obj = scratch("ray.obj"), svg = scratch("ray.svg"), html = scratch("ray.html"),
                 json = scratch("rays.json");
  for (const fs::path& q : {obj, svg, html, json}) fs::remove(q);
  const test::Run j = run_tool("explain builtin:cornell --ray-file " + f.string() + " --brief --json " + json.string() +
                               " --export " + obj.string() + " --svg " + svg.string() + " --html " + html.string());
  INFO(j.output);
  REQUIRE(j.exit_code == 0);
  // --json FILE as on every verb: the JSON in the file, the text report still on stdout
  CHECK_THAT(j.output, Catch::Contains("== ray 2 (3 of 3) ==") && Catch::Contains("wrote " + json.string()));
  const nlohmann::json doc = nlohmann::json::parse(slurp(json));
  REQUIRE(doc["rays"].size() == 3);
  CHECK(doc["rays"][0]["reference"]["events"].size() > 2);
  CHECK(doc["rays"][1]["reference"]["ray"]["dir"][1] == 1.0);
  CHECK(doc["rays"][2]["reference"]["events"][1]["kind_name"] == "rejected");
  CHECK_THAT(slurp(scratch("ray_0.obj")), Catch::Contains("g ray") && Catch::Contains("mtllib ray_0.mtl"));
  CHECK(fs::exists(scratch("ray_0.mtl")));
  CHECK_THAT(slurp(scratch("ray_1.svg")), Catch::Contains("</svg>"));
  CHECK_THAT(slurp(scratch("ray_2.svg")), !Catch::Contains("nan") && Catch::Contains("</svg>"));  // no NaN drawn
  CHECK_THAT(slurp(scratch("ray_2.obj")), !Catch::Contains("v nan") && !Catch::Contains("g ray"));  // nor exported
  CHECK_THAT(slurp(html), Catch::Contains("const DATA = {"));
  // Bad input: clear message, the right exit code
  const test::Run bad = run_tool("explain builtin:cornell --ray 1,2,3");
  CHECK(bad.exit_code == 2);  // the command line's value (it was 1, as a bad ray file's: an outside sweep)
  CHECK_THAT(bad.output, Catch::Contains("ox,oy,oz,dx,dy,dz"));
  CHECK(run_tool("explain builtin:cornell").exit_code == 2);
  CHECK(run_tool("explain builtin:cornell --ray 2.78,2.74,2.79,0,-1,0 --json").exit_code == 2);  // --json needs FILE
  CHECK(run_tool("explain builtin:cornell --pixel 1,1 --gpu-frame").exit_code == 2);  // it needs --backend vulkan
  CHECK(run_tool("explain builtin:cornell --pixel 1,1 --ray 0,0,0,1,0,0").exit_code == 2);
  const test::Run nob = run_tool("explain builtin:cornell --width 48 --height 36 --pixel 24,18 --kind bounce");
  CHECK(nob.exit_code == 1);
  CHECK_THAT(nob.output, Catch::Contains("no glossy bounce"));
}

namespace {

// Debian's chromium, or "" (then the test is skipped, unless CI is set).
std::string chromium() {
  for (const char* c : {"/usr/bin/chromium", "/usr/bin/chromium-browser"})
    if (fs::exists(c)) return c;
  return "";
}

}  // namespace

TEST_CASE("Explain: the HTML viewer loads in headless chromium without script errors and shows the events",
          "[cli][explain][html]") {
  const std::string browser = chromium();
  if (browser.empty()) {
    if (std::getenv("CI")) FAIL("chromium is missing, and CI must test the viewer in it (tools/setup.sh installs it)");
    WARN("skipped: chromium is not installed (tools/setup.sh installs it)");
    return;
  }
  // A page of two rays: the Cornell box's record, and the same beside a planted divergence
  const Cornell c;
  const ExplainRecord want = c.record();
  ExplainRecord got = want;
  const size_t test = first_of(want, sh::kEvTest);
  REQUIRE(test != kNoEvent);
  got.events[test].code = sh::kTestBeyond;
  got.events.erase(got.events.begin() + std::ptrdiff_t(test + 1));
  const plan::ExplainFormat fmt{false, &c.names};
  nlohmann::json views = nlohmann::json::array();
  views.push_back(reference::explain_view("alone", {"the reference alone"}, want, nullptr, c.grid.data(), fmt));
  // (a name holding "<!--" then "<script" put the page's own </script> inside the script: an
  // outside sweep)
  views.push_back(reference::explain_view("diverged </script><!-- <script> <b>", {"a planted divergence"}, want, &got,
                                          c.grid.data(), fmt));
  const fs::path page = scratch("viewer.html");
  std::ofstream(page) << reference::explain_html("viewer test <&>", views);
  const std::string page_text = slurp(page);
  CHECK_THAT(page_text, !Catch::Contains("http://") || Catch::Contains("http://www.w3.org/2000/svg"));
  CHECK_THAT(page_text, !Catch::Contains("<script src") && !Catch::Contains("<link"));

  const fs::path profile = scratch("chromium-profile");
  fs::remove_all(profile);
  // (timeout: a browser that hangs fails the test rather than the suite; /dev/shm is small in
  // containers)
  const std::string cmd = "timeout 120 " + browser +
                          " --headless --no-sandbox --disable-gpu --disable-dev-shm-usage --disable-quic --no-first-run "
                          "--disable-background-networking --disable-component-update --disable-sync "
                          "--user-data-dir=" +
                          profile.string() + " --dump-dom 'file://" + page.string() + "#selftest' 2>/dev/null";
  FILE* pipe = popen(cmd.c_str(), "r");
  REQUIRE(pipe != nullptr);
  std::string dom;
  char buf[4096];
  while (size_t n = fread(buf, 1, sizeof buf, pipe)) dom.append(buf, n);
  const int status = pclose(pipe);
  INFO(dom.substr(dom.find("id=\"status\"") == std::string::npos ? 0 : dom.find("id=\"status\"")));
  REQUIRE(status == 0);
  // The page's own account: no script error, the rows shown, every row stepped through
  std::smatch m;
  REQUIRE(std::regex_search(dom, m, std::regex(R"(<div id="status"[^>]*>)")));
  const std::string tag = m[0];
  CHECK_THAT(tag, Catch::Contains("data-errors=\"0\""));
  CHECK_THAT(tag, Catch::Contains("data-events=\"" + std::to_string(want.events.size()) + "\""));
  CHECK_THAT(tag, Catch::Contains("data-rows=\"" + std::to_string(want.events.size()) + "\""));
  const plan::EventAlignment al = plan::align_events(want.events, got.events);
  CHECK_THAT(tag, Catch::Contains("data-visited=\"" + std::to_string(want.events.size() + al.rows.size()) + "\""));
  CHECK_THAT(dom, Catch::Contains("script errors: 0"));
  // The events are in the DOM: one row each (the first ray's, shown last), the picture drawn
  CHECK(count(dom, "<tr class=\"ev") == want.events.size());
  CHECK_THAT(dom, Catch::Contains("id=\"cell-") && Catch::Contains("id=\"marker\""));
  CHECK_THAT(dom, Catch::Contains("#" + std::to_string(test)));
}

// An outside sweep's find: a pixel's primary ray was explained on the explain's own grid options,
// where the frame's gather traces it on the gather's grid with its own test: on coplanar faces it
// showed another triangle than the pixel's. It is explained on the gather's grid now, whatever
// --triangle-test says.
TEST_CASE("Explain: a pixel's primary ray is traced on the gather's grid, as the frame traces it", "[cli][explain]") {
  for (const char* test : {"", " --triangle-test moller", " --triangle-test watertight"}) {
    const gridrt::test::Run r =
        gridrt::test::run_tool(std::string("explain builtin:cornell --width 32 --height 24 --pixel 16,12 --kind primary --brief") + test);
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK_THAT(r.output, Catch::Contains("on the gather's grid (the watertight test)"));
  }
}

// An outside sweep's find: on a scene of more lights than the frame traces shadow rays to (8),
// explain explained a ninth light's shadow ray, which render refuses to trace.
TEST_CASE("Explain: no shadow ray is explained on a scene whose shadows the frame refuses", "[cli][explain]") {
  const std::filesystem::path d = std::filesystem::temp_directory_path() / "gridrt_explain_nine";
  std::filesystem::create_directories(d);
  {
    std::ofstream s(d / "nine.json");
    s << R"({"meshes":{"pot":{"builtin":"teapot","level":2}},"instances":[{"mesh":"pot"}],"lights":[)";
    for (int i = 0; i < 9; ++i) s << (i ? "," : "") << R"({"position":[)" << i - 4 << R"(,6,3],"intensity":10})";
    s << "]}";
  }
  const gridrt::test::Run r = gridrt::test::run_tool("explain " + (d / "nine.json").string() +
                                                     " --width 16 --height 16 --pixel 8,8 --kind shadow --light 8 --brief");
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK_THAT(r.output, Catch::Contains("8 at most"));
  std::filesystem::remove_all(d);
}

TEST_CASE("Explain: pictures give a triangle its decisive result, a gap-fill hit no triangle, far rays an end",
          "[unit][explain]") {
  // Outside sweeps: a triangle accepted (the best hit then) and retested in the next cell
  // (not-closer) was drawn "rejected"; the launch triangle's self-hit skips counted as tests; a
  // gap-fill voxel's reported triangle was drawn as "the hit triangle"; a far ray's grid lines
  // never ended (a float stepped by a cell size below its half-ulp)
  const Cornell c;
  ExplainRecord rec = c.record();
  size_t t = first_of(rec, sh::kEvTest);
  REQUIRE(t != kNoEvent);
  const uint32_t ref = rec.events[t].ref;
  ExplainRecord edited = rec;
  sh::ExplainEvent accepted = rec.events[t], later = rec.events[t], self = rec.events[t];
  accepted.code = sh::kTestAccepted;
  later.code = sh::kTestNotCloser;
  self.code = sh::kTestSelfHit;
  edited.events.insert(edited.events.begin() + ptrdiff_t(t), {self, accepted, later});
  edited.events.erase(edited.events.begin() + ptrdiff_t(t) + 3);
  const reference::ExplainGeometry g = reference::explain_geometry(edited, c.grid.data());
  uint32_t counted = 0;  // its tests but the self-hit skip and mailboxed retests
  for (const auto& e : edited.events)
    counted += e.kind == sh::kEvTest && e.ref == ref && e.code != sh::kTestSelfHit && e.code != sh::kTestMailboxed;
  bool found = false;
  for (const auto& tri : g.triangles)
    if (tri.ref == ref) {
      found = true;
      CHECK(tri.code == sh::kTestAccepted);
      CHECK(tri.tests == counted);  // the self-hit skip is none
      CHECK(counted >= 2u);
    }
  CHECK(found);
  // A gap-fill report: the reported triangle is no hit triangle; the legend says gap-fill
  ExplainRecord gap = rec;
  for (auto& e : gap.events)
    if (e.kind == sh::kEvReport) e.code |= sh::kHitGapFill, e.ref = ref;
  const reference::ExplainGeometry gg = reference::explain_geometry(gap, c.grid.data());
  CHECK(gg.gap_fill);
  for (const auto& tri : gg.triangles) CHECK_FALSE(tri.hit);
  CHECK_THAT(reference::explain_svg(gap, c.grid.data(), {true, &c.names}), Catch::Contains("gap-fill hit"));
  CHECK_THAT(reference::explain_obj(gap, c.grid.data(), "ray.mtl"), Catch::Contains("g gap_fill_point"));
  // A rejected ray far from the origin: its picture ends (it looped forever)
  const ExplainRecord far = c.grid.explain_ray(plan::parse_ray("3e7,2,2,-1,0,0"));
  CHECK_THAT(reference::explain_svg(far, c.grid.data(), {true, &c.names}), Catch::Contains("</svg>"));
}
