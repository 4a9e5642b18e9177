// The gridrt tool end to end: exit codes, messages, and no image left behind on bad input.
#include <catch2/catch.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <vector>

#include "gridrt/common/safe_io.h"
#include "tests/run_tool.h"

namespace fs = std::filesystem;
using gridrt::test::Run;
using gridrt::test::run_tool;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "gridrt_test_cli";
  fs::create_directories(dir);
  return dir / name;
}

}  // namespace

TEST_CASE("CLI: every verb has --help", "[cli]") {
  for (const char* verb : {"render", "convert", "explain", "stats", "bench", "diff", "sweep", "portal render",
                           "portal explain", "portal bench", "portal diff"}) {
    const Run r = run_tool(std::string(verb) + " --help");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    CHECK_THAT(r.output, Catch::Contains("Usage"));
    // One vocabulary: image sizes are --width/--height wherever a verb takes one
    if (std::string(verb) != "convert") CHECK_THAT(r.output, Catch::Contains("--width") && Catch::Contains("--height"));
    CHECK_THAT(r.output, !Catch::Contains("--size"));
    // Readable choices ("a|b|c"), not CLI11's internals ("ENUM:value in {a->1}", "TEXT:{a,b}")
    CHECK_THAT(r.output, !Catch::Contains("ENUM") && !Catch::Contains("->") && !Catch::Contains(":{"));
    // --json takes a FILE on every verb that writes JSON
    if (r.output.find("--json") != std::string::npos) CHECK_THAT(r.output, Catch::Contains("--json FILE"));
  }
}

TEST_CASE("CLI: render writes an image of a built-in scene", "[cli]") {
  const fs::path out = scratch("cornell.ppm");
  fs::remove(out);
  const Run r = run_tool("render builtin:cornell --width 32 --height 24 -o " + out.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  REQUIRE(fs::exists(out));
  std::ifstream f(out, std::ios::binary);
  std::string magic;
  int w = 0, h = 0;
  f >> magic >> w >> h;
  CHECK(magic == "P6");
  CHECK(w == 32);
  CHECK(h == 24);
}

TEST_CASE("CLI: bad input gives a clear message, a non-zero exit and no image", "[cli][badinput]") {
  const fs::path out = scratch("bad.ppm");
  const fs::path bad_json = scratch("bad.json");
  std::ofstream(bad_json) << "{ \"meshes\": {\n  \"a\": [1, 2,\n}\n";
  struct Case {
    std::string args, message;
    int exit_code;
  };
  const Case cases[] = {
      {"render /nonexistent/scene.json", "/nonexistent/scene.json", 1},
      {"render " + bad_json.string(), "bad.json:3", 1},
      {"render builtin:nosuch", "nosuch", 1},
      {"render builtin:cornell --width 0", "width", 2},
      {"render builtin:cornell --height 0", "height", 2},
      {"render builtin:cornell --shadows sometimes", "sometimes", 2},
      {"render builtin:cornell --backend warp-drive", "warp-drive", 2},  // a bad command line
      {"render builtin:cornell -o /nonexistent-dir/x.ppm", "/nonexistent-dir", 1},
      {"render builtin:cornell -o " + scratch("x.notanimage").string(), "x.notanimage", 2},  // the command line's
      {"render scene.unknown", "unknown extension", 1},
      {"convert builtin:cornell -o " + scratch("x.png").string(), "gridscene", 2},
      {"no-such-verb", "subcommand", 2},
  };
  for (const Case& c : cases) {
    fs::remove(out);
    const Run r = run_tool(c.args + (c.args.find(" -o ") == std::string::npos ? " -o " + out.string() : ""));
    INFO("gridrt " << c.args << "\n" << r.output);
    CHECK(r.exit_code == c.exit_code);
    CHECK_THAT(r.output, Catch::Contains(c.message));
    CHECK_THAT(r.output, !Catch::Contains("internal error"));
    CHECK_FALSE(fs::exists(out));
  }
}

TEST_CASE("CLI: convert writes a cache that renders like the scene", "[cli]") {
  const fs::path cache = scratch("cornell.gridscene");
  const fs::path a = scratch("a.pfm"), b = scratch("b.pfm");
  REQUIRE(run_tool("convert builtin:cornell -o " + cache.string()).exit_code == 0);
  REQUIRE(run_tool("render builtin:cornell --width 16 --height 12 -o " + a.string()).exit_code == 0);
  REQUIRE(run_tool("render " + cache.string() + " --width 16 --height 12 -o " + b.string()).exit_code == 0);
  auto slurp = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(f), {});
  };
  CHECK(slurp(a) == slurp(b));
}

TEST_CASE("CLI: the portal backend renders a tile map and explains a pixel against the voxel DDA", "[cli][portal]") {
  const fs::path out = scratch("portal.ppm");
  fs::remove(out);
  const Run r = run_tool("render --backend portal-cpu " + std::string(GRIDRT_DATA_DIR) +
                         "/maps/tiny.map --width 24 --height 12 -o " + out.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  CHECK(fs::exists(out));
  // The grid's and the frame's options do not apply to it: refused, not dropped (an outside sweep's find)
  const Run frames = run_tool("render --backend portal-cpu " + std::string(GRIDRT_DATA_DIR) +
                              "/maps/tiny.map --width 24 --height 12 --frames 3 --shadows off -o " + out.string());
  INFO(frames.output);
  CHECK(frames.exit_code == 2);
  CHECK_THAT(frames.output, Catch::Contains("--frames") && Catch::Contains("--shadows"));
  const Run e = run_tool("portal explain --width 24 --height 12 --pixel 12,6");
  INFO(e.output);
  REQUIRE(e.exit_code == 0);
  CHECK_THAT(e.output, Catch::Contains("(agrees)"));
  const Run bad = run_tool("portal explain --width 24 --height 12 --pixel 30,6");
  CHECK(bad.exit_code == 2);  // a contradiction on the command line, as render's and explain's
  CHECK_THAT(bad.output, Catch::Contains("outside"));
}

TEST_CASE("CLI: the spill list - stats report it, an overflow warns, a bad value is refused", "[cli][grid]") {
  const Run on = run_tool("stats builtin:teapot --capacity 4 --traversal exact");
  INFO(on.output);
  REQUIRE(on.exit_code == 0);
  CHECK_THAT(on.output, Catch::Contains("spill list: ") && Catch::Contains(", 0 lost to overflow"));
  const Run over = run_tool("stats builtin:teapot --capacity 4 --spill on --spill-capacity 2");
  INFO(over.output);
  REQUIRE(over.exit_code == 0);
  CHECK_THAT(over.output, Catch::Contains("warning: reference-grid: the spill list overflowed") &&
                              Catch::Contains("lost to overflow (WARNING"));
  const Run off = run_tool("stats builtin:teapot --capacity 4 --spill off");
  INFO(off.output);
  CHECK_THAT(off.output, Catch::Contains("spill list: off") && Catch::Contains("gap-fill on"));
  CHECK(run_tool("stats builtin:teapot --spill sometimes").exit_code == 2);
}

TEST_CASE("CLI: explain and stats describe the grid of a built-in scene", "[cli][grid]") {
  const Run s = run_tool("stats builtin:cornell");
  INFO(s.output);
  REQUIRE(s.exit_code == 0);
  CHECK_THAT(s.output, Catch::Contains("occupancy"));
  const Run e = run_tool("explain builtin:cornell --width 64 --height 48 --pixel 32,30");
  INFO(e.output);
  REQUIRE(e.exit_code == 0);
  CHECK_THAT(e.output, Catch::Contains("CPU reference") && Catch::Contains("0x"));
}

TEST_CASE("CLI: one vocabulary - enum help is readable, expert knobs grouped, renamed options parse", "[cli]") {
  const Run help = run_tool("render --help");
  INFO(help.output);
  REQUIRE(help.exit_code == 0);
  CHECK_THAT(help.output, Catch::Contains("--traversal paper|exact"));
  CHECK_THAT(help.output, Catch::Contains("--capacity N|auto|trace-cost|no-saturation|percentile"));
  CHECK_THAT(help.output, Catch::Contains("--gap-fill on|off"));
  CHECK_THAT(help.output, Catch::Contains("--self-hit exclude|keep"));
  CHECK_THAT(help.output, Catch::Contains("Grid (expert):"));
  CHECK_THAT(help.output, !Catch::Contains("ENUM"));
  CHECK_THAT(help.output, !Catch::Contains("->"));
  // The expert knobs come after the common set's heading, in their own group
  CHECK(help.output.find("--insertion") > help.output.find("Grid (expert):"));
  CHECK(help.output.find("--traversal") < help.output.find("Grid (expert):"));
  for (const char* old : {"--no-gap-fill", "--keep-launch-ref", "--capacity-policy"}) {
    CHECK_THAT(help.output, !Catch::Contains(old));
    const Run r = run_tool(std::string("stats builtin:cornell ") + old);
    CHECK(r.exit_code == 2);
  }
  // The new spellings take effect: a fixed capacity, a rule, gap-fill and self-hit values
  const Run fixed = run_tool("stats builtin:cornell --capacity 3 --gap-fill off --self-hit keep --revisit skip");
  INFO(fixed.output);
  CHECK(fixed.exit_code == 0);
  CHECK_THAT(fixed.output, Catch::Contains("capacity 3"));
  const Run bad = run_tool("stats builtin:cornell --capacity many");
  CHECK(bad.exit_code == 2);
  CHECK_THAT(bad.output, Catch::Contains("neither a number"));
  CHECK(run_tool("stats builtin:cornell --gap-fill maybe").exit_code == 2);
  // --width/--height on the verbs that took --size (the others are checked by "every verb has --help")
  for (const char* verb : {"portal explain", "portal bench"}) {
    const Run r = run_tool(std::string(verb) + " --help");
    CHECK_THAT(r.output, Catch::Contains("--width"));
    CHECK_THAT(r.output, Catch::Contains("--height"));
    CHECK_THAT(r.output, !Catch::Contains("--size"));
  }
  const Run portal = run_tool("portal explain --width 24 --height 12 --pixel 30,6");
  CHECK(portal.exit_code == 2);
  CHECK_THAT(portal.output, Catch::Contains("24x12"));
}

TEST_CASE("CLI: render --view pictures agree with what the grid does", "[cli][views]") {
  const fs::path out = scratch("view.png");
  auto view = [&](const std::string& args) {
    fs::remove(out);
    const Run r = run_tool("render builtin:cornell --width 48 --height 27 --threads 2 " + args + " -o " + out.string());
    INFO(args << "\n" << r.output);
    REQUIRE(r.exit_code == 0);
    CHECK(fs::file_size(out) > 0);
    return r.output;
  };
  auto count = [](const std::string& output) {  // "view NAME: K of N rays"
    // that line, not a progress line ("view NAME: 50.0% ...") a slow machine prints first
    for (size_t p = output.find("view "); p != std::string::npos; p = output.find("view ", p + 1)) {
      const size_t colon = output.find(": ", p);
      if (colon == std::string::npos) break;
      const std::string rest = output.substr(colon + 2, output.find('\n', colon) - colon - 2);
      if (rest.find('%') == std::string::npos && rest.find(" of ") != std::string::npos) return std::stoul(rest);
    }
    FAIL("no 'view NAME: K of N rays' line");
    return 0ul;
  };
  // Saturation only where the capacity is too small; gap-fill and the spill list answer only there,
  // and only when they are on.
  CHECK_THAT(view("--view saturation --capacity 2"), !Catch::Contains("max 0 per ray"));
  CHECK(count(view("--view gap-fill")) == 0);
  CHECK(count(view("--view gap-fill --capacity 2")) > 0);
  CHECK(count(view("--view gap-fill --capacity 2 --gap-fill off")) == 0);
  CHECK(count(view("--view spill --traversal exact --capacity 2")) > 0);
  CHECK(count(view("--view spill --traversal exact --capacity 2 --spill off")) == 0);
  CHECK(count(view("--view spill --traversal paper --capacity 2")) == 0);  // spill auto: off for paper
  // Cells and tests: the camera sits inside the box, so every ray visits at least one cell
  const std::string cells = view("--view cells --rays primary");
  const size_t mean = cells.find("mean ");
  REQUIRE(mean != std::string::npos);
  CHECK(std::stod(cells.substr(mean + 5)) >= 1.0);
  CHECK_THAT(cells, Catch::Contains("1296 rays"));
  // diff without the Vulkan backend: a clear message
  const Run diff = run_tool("render builtin:cornell --width 8 --height 8 --view diff -o " + out.string());
  CHECK(diff.exit_code == 2);  // a bad command line
  CHECK_THAT(diff.output, Catch::Contains("--backend vulkan"));
}

TEST_CASE("CLI: portal render --view: the divs save the voxel DDA's steps", "[cli][views][portal]") {
  const fs::path out = scratch("portal_view.png");
  auto mean = [&](const std::string& view) {
    const Run r = run_tool("portal render builtin:level --width 40 --height 20 --view " + view + " -o " + out.string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const size_t p = r.output.find("mean ");
    REQUIRE(p != std::string::npos);
    return std::stod(r.output.substr(p + 5));
  };
  const double divs = mean("divs"), voxels = mean("dda");
  CHECK(divs >= 1.0);
  CHECK(divs < voxels);  // a div holds at least one empty voxel: never more divs than voxels per ray
}

TEST_CASE("CLI: stats --slices draws the grid slice by slice", "[cli][views]") {
  const fs::path dir = scratch("slices");
  fs::remove_all(dir);
  fs::create_directories(dir);
  const Run r = run_tool("stats builtin:cornell --width 16 --height 9 --pixel 8,4 --slices " + dir.string());
  INFO(r.output);
  CHECK(r.exit_code == 0);
  CHECK(fs::exists(dir / "occupancy.png"));
  const Run missing = run_tool("stats builtin:cornell --slices /nonexistent/dir");
  CHECK(missing.exit_code == 1);
  const Run outside = run_tool("stats builtin:cornell --width 16 --height 9 --pixel 16,4 --slices " + dir.string());
  CHECK(outside.exit_code == 2);  // a pixel outside the image asked for: a bad command line
  CHECK_THAT(outside.output, Catch::Contains("outside the 16x9 image"));
}

#ifdef GRIDRT_WITH_VULKAN
TEST_CASE("CLI: render --view diff finds the shader's bounce hits bit-identical", "[cli][views][vulkan]") {
  const fs::path out = scratch("view_diff.png");
  fs::remove(out);
  const Run r = run_tool("render builtin:atrium --width 48 --height 27 --threads 2 --view diff --backend vulkan -o " +
                         out.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  CHECK(fs::exists(out));
  // The atrium's glossy floor makes bounce rays; every one of them agrees bit for bit
  CHECK_THAT(r.output, !Catch::Contains("diff: 0 rays"));
  CHECK_THAT(r.output, Catch::Contains("0 differ in floats only, 0 differ in the hit"));
}
#endif

// Non-finite numbers are refused everywhere on the command line (exit 2), except in explain's
// --ray, which exists to show how the tracer rejects such a ray.
TEST_CASE("CLI: explain --ray takes nan and inf and shows the rejection, --time nan is refused", "[cli][explain]") {
  const Run r = run_tool("explain builtin:cornell --ray=nan,0,0,0,0,1 --brief");
  INFO(r.output);
  CHECK(r.exit_code == 0);
  CHECK_THAT(r.output, Catch::Contains("REJECTED: a NaN or infinite component"));
  // Each domain rule names itself (shared::ray_domain)
  for (const auto& [ray, why] : std::vector<std::pair<std::string, std::string>>{
           {"0,0,0,1e30,1e-30,0", "direction's largest component"},
           {"0,0,0,0x1p-149,0,0", "direction's largest component"},
           {"1e12,0,0,-1,0,0", "origin component beyond 2^24"},
           {"0,0,0,0,0,1,-1,5", "tmin < 0"}}) {
    const Run d = run_tool("explain builtin:cornell --ray=" + ray + " --brief");
    INFO(ray << ": " << d.output);
    CHECK(d.exit_code == 0);
    CHECK_THAT(d.output, Catch::Contains("REJECTED: ") && Catch::Contains(why));
  }
  const Run t = run_tool("render builtin:cornell --time nan -o never.png");
  INFO(t.output);
  CHECK(t.exit_code == 2);
}

TEST_CASE("CLI: bench --rays times a chosen kind of rays on a scene without glossy materials", "[cli][bench]") {
  const fs::path json = scratch("bench_rays.json");
  // cornell has no glossy material: auto takes diffuse bounces, a kind is handed to every backend
  const Run automatic = run_tool("bench builtin:cornell --backend cpu --width 12 --height 10 --frames 1 --warmup 0");
  INFO(automatic.output);
  CHECK(automatic.exit_code == 0);
  CHECK(automatic.output.find("diffuse rays per frame") != std::string::npos);
  const Run primary = run_tool("bench builtin:cornell --backend cpu,embree --rays primary --width 12 --height 10 "
                               "--frames 1 --warmup 0 --json " + json.string());
  INFO(primary.output);
  REQUIRE(primary.exit_code == 0);
  std::ifstream f(json);
  std::string text((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
  CHECK(text.find("\"rays\": \"primary\"") != std::string::npos);
  CHECK(text.find("\"rays_per_frame\": 0") == std::string::npos);
  CHECK(text.find("\"embree\"") != std::string::npos);
  // The frame's glossy rays on a scene without them, an unknown kind: clear errors
  const Run glossy = run_tool("bench builtin:cornell --backend cpu --rays glossy --width 8 --height 8 --frames 1");
  CHECK(glossy.exit_code == 1);
  CHECK(glossy.output.find("no glossy material") != std::string::npos);
  // A kind it does not know is a bad command line (exit 2), said before any work
  const Run bad = run_tool("bench builtin:cornell --backend cpu --rays nonsense --width 8 --height 8 --frames 1");
  CHECK(bad.exit_code == 2);
  CHECK(bad.output.find("unknown kind") != std::string::npos);
  CHECK(bad.output.find("gather buffer") == std::string::npos);
  fs::remove(json);
}

TEST_CASE("CLI: stats --candidates --measure builds each candidate as chosen (the compact layout) and measures every row",
          "[cli][policy]") {
  // An outside tester's find: each candidate was rebuilt with its capacity fixed, which turned the
  // compact layout off: the atrium's image exceeded its limits and the table stopped halfway, exit 1
  const Run r = run_tool("stats builtin:atrium --traversal exact --candidates --measure --width 32 --height 18 --threads 2");
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  size_t candidates = 0;
  {
    const size_t at = r.output.find(" candidates (");
    REQUIRE(at != std::string::npos);
    const size_t start = r.output.rfind(", ", at);
    candidates = std::stoul(r.output.substr(start + 2, at - start - 2));
  }
  REQUIRE(candidates > 1);
  size_t measured = 0, chosen = 0;
  std::istringstream lines(r.output);
  for (std::string line; std::getline(lines, line);) {
    if (line.rfind("| ", 0) != 0 || line.find('x') == std::string::npos || line.find("cells") != std::string::npos) continue;
    CHECK(line.find("not built") == std::string::npos);
    measured += std::count(line.begin(), line.end(), '|') == 22;
    chosen += line.find("**chosen**") != std::string::npos;
  }
  CHECK(measured == candidates);
  CHECK(chosen == 1);
}

TEST_CASE("CLI: frames a float's step apart are refused, not repeated", "[cli]") {
  // Near 1e6 s a float's step is 1/16 s: at 60 frames a second, frames 0 and 1 fell on one time and
  // rendered the same picture twice, without a word
  const Run r = run_tool("render builtin:atrium --time 999000 --frames 4 --fps 60 --width 8 --height 8 -o " +
                         (fs::temp_directory_path() / "gridrt_repeat.png").string());
  INFO(r.output);
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.output, Catch::Contains("both fall on t = 999000") && Catch::Contains("float's step"));
  CHECK(run_tool("diff builtin:atrium --time 999000 --frames 2 --fps 60").exit_code == 2);
}

TEST_CASE("CLI: a small instance turning about a far pivot is warned of, once, and still rendered", "[cli]") {
  // An outside tester's find: the grid sized its cells for the swept box, 35,000 still triangles
  // fell into one cell and a 64 x 36 picture took 30 s instead of 1.6, without a word
  const fs::path d = fs::temp_directory_path() / "gridrt_far_pivot";
  fs::create_directories(d);
  std::ofstream(d / "tri.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string mesh = R"({"meshes": {"t": {"file": "tri.obj"}}, "instances": [{"mesh": "t"}, )";
  std::ofstream(d / "far.json") << mesh + R"({"name": "spinner", "mesh": "t", "translate": [0, 0, 0.5], )"
                                          R"("motion": {"rotate": {"axis": [0, 1, 0], "speed": 1, "pivot": [0, 0, 5000000]}}}]})";
  std::ofstream(d / "near.json") << mesh + R"({"name": "spinner", "mesh": "t", "translate": [0, 0, 0.5], )"
                                           R"("motion": {"rotate": {"axis": [0, 1, 0], "speed": 1, "pivot": [0, 0, 1]}}}]})";
  const Run far = run_tool("render " + (d / "far.json").string() + " --width 8 --height 8 -o " + (d / "far.png").string());
  INFO(far.output);
  CHECK(far.exit_code == 0);
  CHECK_THAT(far.output, Catch::Contains("instance 'spinner' sweeps a box") && Catch::Contains("times its own size"));
  size_t count = 0;
  for (size_t at = far.output.find("sweeps a box"); at != std::string::npos; at = far.output.find("sweeps a box", at + 1)) ++count;
  CHECK(count == 1);
  const Run near = run_tool("render " + (d / "near.json").string() + " --width 8 --height 8 -o " + (d / "near.png").string());
  CHECK(near.exit_code == 0);
  CHECK(near.output.find("sweeps a box") == std::string::npos);
  // A large model turning in place beside a small still one sweeps about its own size: no warning
  std::ofstream(d / "big.json") << mesh + R"({"name": "big", "mesh": "t", "scale": 5000, "translate": [10, 0, 0], )"
                                          R"("motion": {"rotate": {"axis": [0, 1, 0], "speed": 1, "pivot": [10, 0, 0]}}}]})";
  const Run big = run_tool("render " + (d / "big.json").string() + " --width 8 --height 8 -o " + (d / "big.png").string());
  INFO(big.output);
  CHECK(big.exit_code == 0);
  CHECK(big.output.find("sweeps a box") == std::string::npos);
  fs::remove_all(d);
}

// Outside sweeps' finds: `--json /dev/stdout >> log` replaced the log by the JSON (the path leads,
// through /proc, to the log, which the output's rename replaced); explain's outputs could replace
// its own scene or ray file, and two outputs naming one file were caught only when spelled alike.
TEST_CASE("CLI: explain writes /dev/stdout after its report, and refuses outputs that alias inputs or each other",
          "[cli][explain][badinput]") {
  const fs::path d = fs::temp_directory_path() / "gridrt_cli_alias";
  fs::remove_all(d);
  fs::create_directories(d);
  const fs::path log = d / "ci.log";
  std::ofstream(log) << "EARLIER LOG LINE\n";
  const Run r = run_tool("explain builtin:cornell --ray 1,1,1,0,0,1 --brief --json /dev/stdout >> " + log.string());
  CHECK(r.exit_code == 0);
  std::ifstream in(log);
  const std::string text((std::istreambuf_iterator<char>(in)), {});
  CHECK(text.rfind("EARLIER LOG LINE\n", 0) == 0);  // the log's line kept, first
  const size_t report = text.find("ray 0:"), json = text.find("{");
  CHECK(report != std::string::npos);
  CHECK(json != std::string::npos);
  CHECK(report < json);  // the JSON after the report, as printed
  std::ofstream(d / "tri.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(d / "rays.txt") << "0.2,0.2,-1,0,0,1\n";
  const std::string obj = (d / "tri.obj").string(), rays = (d / "rays.txt").string();
  for (const auto& [args, why] : std::vector<std::pair<std::string, std::string>>{
           {obj + " --ray 0.2,0.2,-1,0,0,1 --export " + obj, "an output may not replace an input"},
           {obj + " --ray-file " + rays + " --json " + (d / "." / "rays.txt").string(), "an output may not replace an input"},
           {"builtin:cornell --ray 1,1,1,0,0,1 --json " + fs::relative(d / "a.json").string() + " --html " +
                (d / "sub" / ".." / "a.json").string(),
            "both name"}}) {
    fs::create_directories(d / "sub");
    const Run a = run_tool("explain " + args);
    INFO(args << ": " << a.output);
    CHECK(a.exit_code == 2);
    CHECK_THAT(a.output, Catch::Contains(why));
  }
  // Other spellings of the process's own descriptor, and a link to it, are written to it too
  for (const std::string spelling : {"/dev//stdout", "/dev/./stdout", "/proc/thread-self/fd/1"}) {
    std::ofstream(log) << "EARLIER LOG LINE\n";
    const Run s = run_tool("explain builtin:cornell --ray 1,1,1,0,0,1 --brief --json " + spelling + " >> " + log.string());
    CHECK(s.exit_code == 0);
    std::ifstream again(log);
    const std::string kept((std::istreambuf_iterator<char>(again)), {});
    INFO(spelling);
    CHECK(kept.rfind("EARLIER LOG LINE\n", 0) == 0);
  }
  // Two outputs to one stream replace nothing: accepted; two through a link not yet made: refused
  CHECK(run_tool("explain builtin:cornell --ray 1,1,1,0,0,1 --brief --json /dev/null --svg /dev/null").exit_code == 0);
  fs::create_symlink(d / "later.json", d / "link.svg");
  const Run dangling = run_tool("explain builtin:cornell --ray 1,1,1,0,0,1 --brief --json " + (d / "later.json").string() +
                                " --svg " + (d / "link.svg").string());
  CHECK(dangling.exit_code == 2);
  // An output over any file the run read (here the mesh's texture) is refused before a byte is
  // written, however the verb names it (a review's find: render -o, sweep -o, --json of diff,
  // bench and verify replaced the scene, its .mtl or its texture)
  std::ofstream(d / "tex.mtl") << "newmtl m\nKd 1 1 1\nmap_Kd tex.ppm\n";
  std::ofstream(d / "tex.ppm", std::ios::binary) << "P6\n1 1\n255\n" << std::string("\xff\x80\x00", 3);
  std::ofstream(d / "tex.obj") << "mtllib tex.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n";
  const Run over = run_tool("render " + (d / "tex.obj").string() + " --width 8 --height 6 -o " + (d / "tex.ppm").string());
  INFO(over.output);
  CHECK(over.exit_code == 1);
  CHECK_THAT(over.output, Catch::Contains("an output may not replace an input"));
  CHECK(fs::file_size(d / "tex.ppm") == 14);
  const Run verify_over = run_tool("verify " + (d / "tex.obj").string() + " -n 4 --no-translated --json " +
                                   (d / "tex.obj").string());
  INFO(verify_over.output);
  CHECK(verify_over.exit_code == 1);
  // diff's reports: refused as soon as the scene is read, not after the whole diff (an outside sweep)
  for (const char* report : {"--junit", "--json"}) {
    const Run diff_over = run_tool("diff " + (d / "tex.obj").string() + " --width 8 --height 6 " + report + " " +
                                   (d / "tex.mtl").string());
    INFO(diff_over.output);
    CHECK(diff_over.exit_code == 1);
    CHECK_THAT(diff_over.output, Catch::Contains("an output may not replace an input"));
    CHECK_THAT(diff_over.output, !Catch::Contains("AGREE") && !Catch::Contains("DIFFER"));
  }
  // Untouched
  std::ifstream tri(obj);
  const std::string mesh((std::istreambuf_iterator<char>(tri)), {});
  CHECK(mesh == "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  fs::remove_all(d);
}

TEST_CASE("Outside sweep: the reporting verbs check their command line first and name their rays", "[cli]") {
  const fs::path d = scratch("reporting");
  fs::remove_all(d);
  // A bad --rays or --backend is a bad command line (exit 2), before any scene is loaded or
  // folder made
  for (const std::string args : {"sweep builtin:cornell --rays bogus -o ", "sweep builtin:cornell -b bogus -o ",
                                 "bench builtin:cornell -b bogus --json ", "bench builtin:cornell --rays bogus --json "}) {
    const Run r = run_tool(args + (d / "out").string());
    INFO(args << "\n" << r.output);
    CHECK(r.exit_code == 2);
    CHECK(!fs::exists(d / "out"));
  }
  // An image limit is a whole number of texels (4096.5 became 4096)
  CHECK(run_tool("sweep builtin:cornell --max-image-dimension 4096.5 -o " + (d / "out").string()).exit_code == 2);
  // The diffuse rays start from the W x H gather buffer asked for: a 40x1 buffer has at most 40
  // (a 16:9 buffer of about as many pixels gave more rays than pixels)
  {
    const Run r = run_tool("bench builtin:cornell --backend cpu --rays diffuse --width 40 --height 1 --frames 1 --warmup 0");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    const size_t at = r.output.find(" diffuse rays per frame");
    REQUIRE(at != std::string::npos);
    const size_t start = r.output.rfind(' ', at - 1);
    CHECK(std::stoul(r.output.substr(start + 1, at - start - 1)) <= 40u);
  }
  // stats --measure names the kind of rays it traced (camera rays on a scene without glossy
  // materials, the kind the trace-cost policy samples; its help said bounce rays)
  {
    const Run r = run_tool("stats builtin:cornell --candidates --measure --width 16 --height 12");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK_THAT(r.output, Catch::Contains("camera rays (the scene has no glossy material"));
    CHECK_THAT(r.output, Catch::Contains("saturated cells (worst sample)"));
  }
  // On the compact layout the moving instances' references are the spill list's, said so (they
  // read as references that "found no slot", left out of the counts)
  {
    const Run r = run_tool("stats builtin:atrium --traversal exact --threads 2");
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    CHECK_THAT(r.output, Catch::Contains("the compact layout's dynamic references") &&
                             Catch::Contains("static (the dynamic ones in the spill list above)"));
    CHECK_THAT(r.output, !Catch::Contains("found no slot"));
  }
  fs::remove_all(d);
}

TEST_CASE("Outside sweep: the grid's overrides - the command line over the file, two sizes refused", "[cli][grid]") {
  const fs::path d = scratch("overrides");
  fs::create_directories(d);
  std::ofstream(d / "tri.obj") << "v -1 -1 0\nv 1 -1 0\nv 0 1 0\nf 1 2 3\n";
  std::ofstream(d / "cs.json") << R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t"}],"grid":{"cell_size":0.5,"capacity":7}})";
  std::ofstream(d / "both.json")
      << R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t"}],"grid":{"cell_size":0.5,"resolution":[8,8,8]}})";
  // A resolution on the command line replaces the file's cell size (it was dropped without a word)
  const Run res = run_tool("stats " + (d / "cs.json").string() + " --resolution 16,16,1");
  INFO(res.output);
  REQUIRE(res.exit_code == 0);
  CHECK_THAT(res.output, Catch::Contains("grid: 16 x 16 x 1 cells"));
  // A capacity rule named on the command line replaces the file's number
  const Run rule = run_tool("stats " + (d / "cs.json").string() + " --capacity no-saturation");
  INFO(rule.output);
  REQUIRE(rule.exit_code == 0);
  CHECK_THAT(rule.output, !Catch::Contains("capacity 7"));
  const Run number = run_tool("stats " + (d / "cs.json").string());
  CHECK_THAT(number.output, Catch::Contains("capacity 7"));
  // Both sizes at one level: refused (the file's: bad input; the command line's: exit 2)
  const Run file = run_tool("stats " + (d / "both.json").string());
  INFO(file.output);
  CHECK(file.exit_code == 1);
  CHECK_THAT(file.output, Catch::Contains("\"resolution\" and \"cell_size\""));
  const Run cli = run_tool("stats builtin:cornell --resolution 8,8,8 --cell-size 0.1");
  INFO(cli.output);
  CHECK(cli.exit_code == 2);
  CHECK_THAT(cli.output, Catch::Contains("--resolution and --cell-size"));
  // --density where the file fixes the grid's size: it did nothing (an outside sweep); refused,
  // and taken again once the command line's size replaces the file's
  const Run density = run_tool("stats " + (d / "cs.json").string() + " --density 5");
  INFO(density.output);
  CHECK(density.exit_code == 2);
  CHECK_THAT(density.output, Catch::Contains("--density"));
  // --max-capacity where the automatic layout takes the compact one (no slots): refused; with a
  // capacity (the image layout) or the paper traversal it bounds slots, and the frame's gather
  // grid (the exact traversal's) does not inherit it
  const Run compact = run_tool("stats builtin:cornell --traversal exact --max-capacity 8");
  INFO(compact.output);
  CHECK(compact.exit_code == 2);
  CHECK_THAT(compact.output, Catch::Contains("compact layout"));
  CHECK(run_tool("stats builtin:cornell --traversal exact --capacity 8 --max-capacity 16").exit_code == 0);
  CHECK(run_tool("stats builtin:cornell --max-capacity 8").exit_code == 0);
  CHECK(run_tool("render builtin:cornell --width 8 --height 8 --max-capacity 8 -o " + (d / "m.png").string()).exit_code == 0);
  // --shadows on for a scene without lights (a scene file naming none; a bare mesh gets one): nothing
  // to trace (it ran, exit 0)
  std::ofstream(d / "dark.json") << R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t"}]})";
  const Run shadows = run_tool("render " + (d / "dark.json").string() + " --width 8 --height 8 --shadows on -o " +
                               (d / "s.png").string());
  INFO(shadows.output);
  CHECK(shadows.exit_code == 2);
  CHECK_THAT(shadows.output, Catch::Contains("no lights"));
  CHECK(run_tool("render " + (d / "dark.json").string() + " --width 8 --height 8 -o " + (d / "s.png").string()).exit_code == 0);
}

// An outside sweep's finds: options that did nothing in the combination given, with exit 0. Each
// is now refused as a bad command line, before any work.
TEST_CASE("Outside sweep: options that would do nothing are refused (exit 2)", "[cli]") {
  const fs::path dir = scratch("ignored");
  fs::create_directories(dir);
  const std::string out = " -o " + (dir / "x.png").string();
  for (const std::string& args :
       {"render builtin:cornell --width 8 --height 8 --fps 10" + out,
        "render builtin:cornell --width 8 --height 8 --vk-build compute" + out, std::string("stats builtin:cornell --repeat 3"),
        std::string("stats builtin:cornell --slice-axis y"),
        std::string("explain builtin:cornell --ray 2.78,2.74,2.79,0,0,-1 --width 10"),
        std::string("explain builtin:cornell --ray 2.78,2.74,2.79,0,0,-1 --frame 3"),
        "portal render builtin:level --width 16 --height 8 --mip-levels 3 --mip-distance 0" + out,
        "portal render builtin:level --width 16 --height 8 --mip-distance 4" + out,
        // a distance that rounds to 0 as the float it is kept in (0 is the default's "not given")
        "portal render builtin:level --width 16 --height 8 --mip-levels 3 --mip-distance 1e-50" + out,
        // Contradictions that exited 1, as bad input: a pixel outside the image, mip levels on an
        // instanced world, a view of the CPU's records on another backend
        std::string("explain builtin:cornell --width 64 --height 48 --pixel 64,30"),
        "portal render builtin:blocks --width 16 --height 8 --mip-levels 3" + out,
        "render builtin:cornell --width 8 --height 8 --backend portal-cpu --view cells" + out,
        "render builtin:cornell --width 8 --height 8 --backend embree --traversal exact" + out,
        // The Vulkan port's options where no Vulkan backend runs, the frame's seed on rays it does
        // not seed
        "render builtin:cornell --width 8 --height 8 --fallback-cpu" + out,
        std::string("verify builtin:cornell -n 5 --fallback-cpu"),
        std::string("bench builtin:cornell --width 8 --height 8 --frames 1 --warmup 0 --vk-build compute"),
        std::string("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --primary --frame 2"),
        std::string("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --kind shadow --frame 2"),
        // verify's translated run alone traced nothing and said OK; portal explain's pixel outside
        std::string("verify builtin:cornell -n 5 --families translated"),
        std::string("verify builtin:cornell -n 5 --families camera,translated --no-translated"),
        std::string("portal explain --width 8 --height 8 -p 9,1"),
        // --voxels on a map, --flatten on a world that is no block map, a backend portal worlds lack
        "portal render builtin:level --width 16 --height 8 --voxels 5" + out,
        "portal render builtin:level --width 16 --height 8 --flatten" + out,
        std::string("portal explain builtin:level --width 16 --height 8 -p 1,1 -b cpu"),
        // Knobs of a part that does not run, and options their verb does not read here
        std::string("stats builtin:cornell --spill-capacity 5"),  // the paper traversal: no spill list
        std::string("stats builtin:cornell --traversal exact --spill off --spill-capacity 5"),
        std::string("stats builtin:cornell --traversal exact --enlargement 2"),  // the box cell test takes no sphere
        std::string("stats builtin:cornell --width 10 --height 5"),
        std::string("diff builtin:cornell --frames 1 --fps 10 --width 8 --height 8"),
        std::string("bench builtin:cornell -b cpu --width 8 --height 8 --frames 1 --warmup 0 --shadows on --rays primary"),
        std::string("bench builtin:cornell -b vulkan --width 8 --height 8 --frames 1 --warmup 0 --fallback-cpu"),
        std::string("bench builtin:cornell -b cpu --width 8 --height 8 --frames 1 --warmup 0 --back-to-back 4"),
        std::string("verify builtin:cornell -n 5 --no-translated --offset 1,2,3"),
        std::string("verify builtin:cornell -n 5 --families camera --offset 1,2,3"),
        std::string("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --kind bounce --primary"),
        "render builtin:cornell --width 8 --height 8 --view cells --no-bounce" + out,
        "render builtin:cornell --width 8 --height 8 --view cells --shadows off" + out,
        // A bad backend or family: a bad command line, not bad input
        "render builtin:cornell --width 8 --height 8 -b bogus" + out, std::string("verify builtin:cornell -n 5 -b bogus"),
        std::string("verify builtin:cornell -n 5 --families bogus"),
        // More of them (outside sweeps): the policy's knobs where the command line fixed the grid, the compact layout's slots, the Vulkan
        // frame's bench knobs on the CPU, --strict where it is the rule, an empty value
        std::string("stats builtin:cornell --resolution 4,4,4 --density 5"),
        std::string("stats builtin:cornell --cell-size 0.5 --density 5"),
        std::string("stats builtin:cornell --resolution 4,4,4 --capacity 4 --cell-visit-cost 100"),
        std::string("stats builtin:cornell --capacity no-saturation --work-sample 8,8"),
        std::string("stats builtin:cornell --traversal exact --layout compact --max-capacity 8"),
        // Knobs another option turned off, a CPU build's order for a device's build, seeds wrapped
        "render builtin:cornell --width 8 --height 8 --gap-fill off --gap-fill-distance 2" + out,
        std::string("stats builtin:cornell --traversal exact --skip-empty off --skip-covered on"),
        std::string("stats builtin:cornell --traversal exact --layout image --skip-covered off"),
        std::string("stats builtin:cornell --traversal exact --capacity 4 --skip-covered on"),
        std::string("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --kind primary --elongation 0.5"),
        "render builtin:cornell --width 8 --height 8 -b vulkan --shuffle-seed 3" + out,
        std::string("stats builtin:cornell --insertion first-empty --shuffle-seed -1"),
        std::string("stats builtin:cornell --insertion first-empty --shuffle-seed 18446744073709551616"),
        // The command line's own values: a malformed --ray, portal export's output that is no scene file
        std::string("explain builtin:cornell --ray 0,1,3,0,0"),
        "portal export builtin:blocks -o " + (dir / "x.obj").string(),
        std::string("stats builtin:cornell --capacity 8 --max-capacity 7"),
        std::string("bench builtin:cornell -b cpu --width 8 --height 8 --frames 1 --warmup 0 --gather boxes"),
        std::string("bench builtin:cornell -b cpu --width 8 --height 8 --frames 1 --warmup 0 --counter-frames 2"),
        std::string("bench builtin:cornell -b cpu --width 8 --height 8 --frames 1 --warmup 0 --rtx"),
        std::string("verify builtin:cornell -n 5 --traversal exact --strict"),
        std::string("verify builtin:cornell -n 5 --json \"\""), std::string("stats builtin:cornell --slices \"\""),
        std::string("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --svg \"\"")}) {
    const Run r = run_tool(args);
    INFO(args << "\n" << r.output);
    CHECK(r.exit_code == 2);
    CHECK_THAT(r.output, !Catch::Contains("not expected") && !Catch::Contains("were not expected"));
  }
  // stats builds the CPU reference's grid only: it has no Vulkan options
  for (const char* args : {"stats builtin:cornell --vk-build compute", "stats builtin:cornell --fallback-cpu"}) {
    const Run r = run_tool(args);
    INFO(args << "\n" << r.output);
    CHECK(r.exit_code == 2);
  }
  // Without the option that would do nothing, each runs
  // (--frame on a pixel with a glossy bounce: the atrium's 8,6 at 16 x 9; Cornell has none, where
  // --frame is refused)
  CHECK(run_tool("explain builtin:atrium --width 16 --height 9 --pixel 8,6 --frame 2 --brief").exit_code == 0);
  CHECK(run_tool("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --frame 2 --brief").exit_code == 2);
  CHECK(run_tool("render builtin:cornell --width 8 --height 8 --frames 2 --fps 10" + out).exit_code == 0);
  CHECK(run_tool("explain builtin:cornell --ray 2.78,2.74,2.79,0,0,-1 --brief").exit_code == 0);
  CHECK(run_tool("stats builtin:cornell --traversal exact --cell-test sphere --enlargement 2").exit_code == 0);
  CHECK(run_tool("stats builtin:cornell --traversal exact --spill-capacity 4096").exit_code == 0);
  CHECK(run_tool("stats builtin:cornell --traversal exact --capacity 4").exit_code == 0);
  CHECK(run_tool("stats builtin:cornell --traversal exact --skip-covered on").exit_code == 0);
  CHECK(run_tool("explain builtin:cornell --width 8 --height 8 --pixel 4,4 --kind primary --traversal paper "
                 "--elongation 0.5 --brief").exit_code == 0);
}

// Outside sweeps' finds: a block map with an empty block exported a scene no verb could load (its
// block's OBJ had no faces); a refused output of portal export left its .mtl replaced; the stats
// --slices figure was bounded by nothing (138 Mpixel, 6 GB for a 4096x4096x2 grid).
TEST_CASE("Outside sweep: portal export leaves out empty blocks, the slices figure counts against --max-pixels",
          "[cli][portal]") {
  const fs::path d = scratch("export-empty");
  fs::create_directories(d);
  {
    std::ofstream m(d / "air.map");
    m << "scale 2\nblock air\nend\nblock solid\nbox 0 0 0 2 2 2 1\nend\ntile a air\ntile s solid\nsize 5 5 1\nmap\n"
         "11111\n1E.a1\n1...1\n1s.L1\n11111\n";
  }
  const Run e = run_tool("portal export " + (d / "air.map").string() + " -o " + (d / "air.json").string());
  INFO(e.output);
  REQUIRE(e.exit_code == 0);
  CHECK_FALSE(fs::exists(d / "air_block_air.obj"));
  const Run r = run_tool("render " + (d / "air.json").string() + " --width 16 --height 8 -o " + (d / "air.png").string());
  INFO(r.output);
  CHECK(r.exit_code == 0);
  // A folder in the way of one output: refused before the .mtl is replaced
  {
    std::ofstream keep(d / "y.mtl");
    keep << "keep\n";
  }
  fs::create_directories(d / "y_tiles.obj");
  const Run y = run_tool("portal export " + (d / "air.map").string() + " -o " + (d / "y.json").string());
  INFO(y.output);
  CHECK(y.exit_code == 1);
  std::ifstream kept(d / "y.mtl");
  std::string line;
  std::getline(kept, line);
  CHECK(line == "keep");
  // The slices figure: refused past --max-pixels, named
  const Run s = run_tool("--max-pixels 100000 stats builtin:cornell --resolution 64,64,4 --slices " + d.string());
  INFO(s.output);
  CHECK(s.exit_code == 1);
  CHECK_THAT(s.output, Catch::Contains("--max-pixels"));
  CHECK(run_tool("stats builtin:cornell --resolution 64,64,4 --slices " + d.string()).exit_code == 0);
}

TEST_CASE("Outside sweep: outputs - a frame linked to another, permissions kept, pseudo-formats refused", "[cli]") {
  const fs::path dir = scratch("outputs_sweep");
  fs::remove_all(dir);
  fs::create_directories(dir);
  // Frame 0's name a link to frame 1's: the first frame was written there, then replaced
  fs::create_symlink("fr_0001.png", dir / "fr_0000.png");
  const Run r = run_tool("render builtin:teapot --width 16 --height 9 --frames 2 --fps 1 -o " + (dir / "fr.png").string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK_THAT(r.output, Catch::Contains("name one file"));
  CHECK_FALSE(fs::exists(dir / "fr_0001.png"));
  // A file replaced keeps its permissions
  const fs::path priv = dir / "private.png";
  std::ofstream(priv) << "old";
  fs::permissions(priv, fs::perms::owner_read | fs::perms::owner_write);
  CHECK(run_tool("render builtin:cornell --width 8 --height 8 -o " + priv.string()).exit_code == 0);
  CHECK(fs::status(priv).permissions() == (fs::perms::owner_read | fs::perms::owner_write));
  // A file nobody may write is refused before the render and kept as it was (it was replaced: the
  // rename needs only the folder's permission), root or not
  const fs::path locked = dir / "locked.png";
  std::ofstream(locked) << "old";
  fs::permissions(locked, fs::perms::owner_read | fs::perms::group_read | fs::perms::others_read);
  const Run ro = run_tool("render builtin:cornell --width 8 --height 8 -o " + locked.string());
  INFO(ro.output);
  CHECK(ro.exit_code == 1);
  CHECK_THAT(ro.output, Catch::Contains("read-only (mode 0444)"));
  CHECK_THAT(ro.output, !Catch::Contains("traced"));  // refused before any frame was made
  {
    std::ifstream kept(locked);
    std::string first;
    std::getline(kept, first);
    CHECK(first == "old");
  }
  // Grey and bitmap netpbm names held a colour P6 picture; a one-channel format (Zfile) failed
  // only after the render: each refused at once, nothing written
  for (const char* name : {"x.pgm", "x.pbm", "x.zfile"}) {
    const Run g = run_tool(std::string("render builtin:cornell --width 8 --height 8 -o ") + (dir / name).string());
    INFO(name << ": " << g.output);
    CHECK(g.exit_code == 2);
    CHECK_THAT(g.output, Catch::Contains("cannot write image"));
    CHECK_THAT(g.output, !Catch::Contains("traced"));
    CHECK_FALSE(fs::exists(dir / name));
  }
  // OpenImageIO's terminal and null writers write no file
  const Run t = run_tool("render builtin:cornell --width 8 --height 8 -o " + (dir / "x.term").string());
  CHECK(t.exit_code == 2);  // an -o name of no image file: the command line's
  CHECK_THAT(t.output, Catch::Contains("writes no image file"));
  fs::remove_all(dir);
}

TEST_CASE("CLI: a Vulkan render to a float image holds linear values, as the CPU's", "[cli][vulkan]") {
  // The shader's sRGB bytes were written as byte / 255 into PFM, EXR and HDR: sRGB values read as
  // linear, 94 % of pixels off (an outside review). Now decoded: within 8-bit rounding of the CPU's
  const fs::path dir = scratch("float_vulkan");
  fs::create_directories(dir);
  const auto read_pfm = [](const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::string magic;
    int w = 0, h = 0;
    float scale = 0;
    f >> magic >> w >> h >> scale;
    f.get();
    std::vector<float> v(size_t(w) * size_t(h) * 3);
    f.read(reinterpret_cast<char*>(v.data()), std::streamsize(v.size() * sizeof(float)));
    return v;
  };
  for (const char* backend : {"cpu", "vulkan"}) {
    const Run r = run_tool(std::string("render builtin:cornell --width 32 --height 24 --backend ") + backend + " -o " +
                           (dir / (std::string(backend) + ".pfm")).string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
  }
  const std::vector<float> cpu = read_pfm(dir / "cpu.pfm"), gpu = read_pfm(dir / "vulkan.pfm");
  REQUIRE(cpu.size() == gpu.size());
  REQUIRE(!cpu.empty());
  double sum = 0.0;
  for (size_t i = 0; i < cpu.size(); ++i) sum += std::abs(double(cpu[i]) - double(gpu[i]));
  CHECK(sum / double(cpu.size()) < 0.01);
  fs::remove_all(dir);
}

// An outside sweep's finds on a scene's scale: a model far smaller than the scene's extent piles
// into one cell (a teapot in a stadium), which is warned of, once; a model far smaller than a unit
// keeps a grid of its own scale (its padding was an absolute 1e-6, which put it in one cell).
TEST_CASE("Outside sweep: a crowded cell is warned of, and a tiny model keeps a grid of its own scale", "[cli][grid]") {
  const fs::path dir = scratch("crowded");
  fs::create_directories(dir);
  auto write_obj = [&](const fs::path& path, float scale, bool far) {
    std::ofstream f(path);
    // a 65 x 65 sheet of quads, 8,192 triangles in a unit square (times scale)
    const int n = 65;
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) f << "v " << scale * i / n << " " << scale * 0.01f * ((i + j) % 3) << " " << scale * j / n << "\n";
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int a = 1 + j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
        f << "f " << a << " " << b << " " << d << "\nf " << a << " " << d << " " << c << "\n";
      }
    if (far) {  // one triangle a million units away
      const int v = (n + 1) * (n + 1);
      f << "v 1e6 0 0\nv 1e6 0 1\nv 1e6 1 0\nf " << v + 1 << " " << v + 2 << " " << v + 3 << "\n";
    }
  };
  write_obj(dir / "stadium.obj", 1.0f, true);
  const Run crowded = run_tool("stats " + (dir / "stadium.obj").string() + " --traversal exact");
  INFO(crowded.output);
  CHECK(crowded.exit_code == 0);
  CHECK_THAT(crowded.output, Catch::Contains("densest cell holds") && Catch::Contains("expect slow traces"));
  // said once, however many grids the policy weighs
  CHECK(crowded.output.find("densest cell holds") == crowded.output.rfind("densest cell holds"));
  CHECK_THAT(crowded.output, Catch::Contains("far geometry"));
  // A dense model alone, 1e5 from the origin: its cells are the narrowest the domain allows there,
  // and the warning says so (it blamed far geometry and advised --resolution, which is refused
  // there: an outside sweep)
  {
    std::ofstream f(dir / "faraway.obj");
    f.precision(12);  // the coordinates' bits near 1e5
    const int n = 65;
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) f << "v " << 1e5 + double(i) / n << " " << 0.01 * ((i + j) % 3) << " " << double(j) / n << "\n";
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const int a = 1 + j * (n + 1) + i, b = a + 1, c = a + n + 1, d = c + 1;
        f << "f " << a << " " << b << " " << d << "\nf " << a << " " << d << " " << c << "\n";
      }
  }
  const Run domain = run_tool("stats " + (dir / "faraway.obj").string() + " --traversal exact");
  INFO(domain.output);
  CHECK(domain.exit_code == 0);
  CHECK_THAT(domain.output, Catch::Contains("narrowest the domain allows") && Catch::Contains("nearer the origin"));
  // The same sheet alone is not crowded, at a unit's scale and at a billionth of it
  std::string cells[2], occupancy[2];
  for (const int k : {0, 1}) {
    const fs::path obj = dir / (k == 0 ? "sheet.obj" : "tiny.obj");
    write_obj(obj, k == 0 ? 1.0f : 1.0e-9f, false);
    const Run r = run_tool("stats " + obj.string() + " --traversal exact");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    CHECK_THAT(r.output, !Catch::Contains("densest cell holds"));
    // The grid's line, "grid: X x Y x Z cells of ...": not the progress line "grid: weighing ..."
    // that a slow machine prints first (a CI rehearsal's failure)
    const size_t end = r.output.find(" cells of"), occ = r.output.find("occupancy (");
    REQUIRE(end != std::string::npos);
    REQUIRE(occ != std::string::npos);
    const size_t at = r.output.rfind("grid: ", end);
    REQUIRE(at != std::string::npos);
    cells[k] = r.output.substr(at, end - at);
    occupancy[k] = r.output.substr(occ, r.output.find('\n', occ) - occ);
  }
  // the tiny sheet's grid is the unit sheet's, scaled: the same cells, the same occupancy
  CHECK(cells[0] == cells[1]);
  CHECK(occupancy[0] == occupancy[1]);
}

TEST_CASE("Outside sweep: names that look like numbers, a scene name that is not UTF-8, an export name that would "
          "not load again",
          "[cli]") {
  const fs::path dir = scratch("names");
  fs::remove_all(dir);
  fs::create_directories(dir / "007");
  // A folder named like a number is a folder (it was refused as an octal number): given as the
  // bare name "007", relative to the working folder, as a user types it
  {
    const fs::path here = fs::current_path() / "007";
    fs::create_directories(here);
    const Run r = run_tool("sweep builtin:cornell --width 8 --height 8 --traversal exact --capacity 4 -o 007");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    CHECK(fs::exists(here / "builtin-cornell.csv"));
    fs::remove_all(here);
  }
  // ... but an option's value is judged as written, whatever the working folder holds: files named
  // 010 and nan there let --width 010 through as octal 8 and NaN into --density (a review's find);
  // the glued -o007 is a path
  {
    const fs::path f010 = fs::current_path() / "010", fnan = fs::current_path() / "nan";
    std::ofstream(f010) << "x";
    std::ofstream(fnan) << "x";
    const Run width = run_tool("render builtin:cornell --width 010 --height 8 -o " + (dir / "w.ppm").string());
    const Run density = run_tool("stats builtin:teapot --density nan");
    const Run pixel = run_tool("explain builtin:cornell --pixel 3 010 --brief");
    fs::create_directories(fs::current_path() / "007");
    const Run glued = run_tool("sweep builtin:cornell --width 8 --height 8 --traversal exact --capacity 4 -o007");
    fs::remove(f010);
    fs::remove(fnan);
    INFO(width.output << density.output << glued.output);
    CHECK(width.exit_code == 2);
    CHECK(width.output.find("may not start with 0") != std::string::npos);
    CHECK_FALSE(fs::exists(dir / "w.ppm"));
    CHECK(density.exit_code == 2);
    CHECK(density.output.find("must be finite") != std::string::npos);
    // A number too small for a normal single-precision float was read as 0 and refused as "not
    // positive" by a later check, naming the gather's grid; a negative cell size's message printed
    // DBL_MAX in its 309 digits (an outside sweep)
    const Run tiny = run_tool("stats builtin:cornell --cell-size 1e-50");
    INFO(tiny.output);
    CHECK(tiny.exit_code == 2);
    CHECK(tiny.output.find("'1e-50'") != std::string::npos);
    CHECK(tiny.output.find("1.2e-38") != std::string::npos);
    const Run negative = run_tool("stats builtin:cornell --cell-size -1");
    INFO(negative.output);
    CHECK(negative.exit_code == 2);
    CHECK(negative.output.find("must be a number above 0, not -1") != std::string::npos);
    CHECK(negative.output.find("17976931348623157") == std::string::npos);
    const Run zero_ok = run_tool("stats builtin:cornell --aabb-padding 0");
    INFO(zero_ok.output);
    CHECK(zero_ok.exit_code == 0);  // 0 itself is a number the command line takes
    CHECK(pixel.exit_code == 2);  // an option's second value too
    CHECK(glued.exit_code == 0);
    CHECK(fs::exists(fs::current_path() / "007" / "builtin-cornell.csv"));
    fs::remove_all(fs::current_path() / "007");
  }
  // A scene whose file name holds a byte that is not UTF-8: the reports say it as U+FFFD (exit 5,
  // an internal error, before), the JUnit report is well-formed
  {
    const fs::path obj = dir / "u\xff.obj";
    std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    const fs::path json = dir / "v.json";
    const Run r = run_tool("verify '" + obj.string() + "' -n 5 --families camera --json " + json.string());
    INFO(r.output);
    CHECK(r.exit_code == 0);
    REQUIRE(fs::exists(json));
    std::ifstream in(json);
    const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    CHECK(gridrt::is_utf8(text));
    CHECK(text.find("u\xef\xbf\xbd") != std::string::npos);
  }
  // portal export writes only scenes that load again: a name a scene file would expand is refused
  {
    const Run r = run_tool("portal export builtin:blocks -o '" + (dir / "${X}.json").string() + "'");
    INFO(r.output);
    CHECK(r.exit_code == 1);
    CHECK_THAT(r.output, Catch::Contains("may not start with '${'"));
    CHECK(!fs::exists(dir / "${X}.json"));
  }
  fs::remove_all(dir);
}

TEST_CASE("Outside sweep: an OBJ's free-form curves and surfaces are named as not read", "[cli][loaders]") {
  const fs::path dir = scratch("freeform");
  fs::create_directories(dir);
  std::ofstream(dir / "curves.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\ncstype bspline\ndeg 2\n"
                                       "curv 0.0 1.0 1 2 3\nparm u 0 0 0 1 1 1\nend\nsurf 0 1 0 1 1 2 3 4\nend\n";
  std::ofstream(dir / "plain.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const Run curves = run_tool("stats " + (dir / "curves.obj").string());
  INFO(curves.output);
  CHECK(curves.exit_code == 0);
  CHECK(curves.output.find("curves.obj:6: free-form geometry (2 curve(s) and surface(s)") != std::string::npos);
  const Run plain = run_tool("stats " + (dir / "plain.obj").string());
  INFO(plain.output);
  CHECK(plain.exit_code == 0);
  CHECK(plain.output.find("free-form") == std::string::npos);
}
