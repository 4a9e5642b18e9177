// The gridrt tool end to end: exit codes, messages, and no image left behind on bad input.
#include <catch2/catch.hpp>

#include <array>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>

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
  for (const char* verb : {"render", "convert", "explain", "stats", "bench", "diff", "portal render", "portal explain"}) {
    const Run r = run_tool(std::string(verb) + " --help");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    CHECK_THAT(r.output, Catch::Contains("Usage"));
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
      {"render builtin:cornell --backend warp-drive", "warp-drive", 1},
      {"render builtin:cornell -o /nonexistent-dir/x.ppm", "/nonexistent-dir", 1},
      {"render builtin:cornell -o " + scratch("x.notanimage").string(), "x.notanimage", 1},
      {"render scene.unknown", "unknown extension", 1},
      {"convert builtin:cornell -o " + scratch("x.png").string(), "gridscene", 1},
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
  const Run e = run_tool("portal explain --size 24,12 --pixel 12,6");
  INFO(e.output);
  REQUIRE(e.exit_code == 0);
  CHECK_THAT(e.output, Catch::Contains("(agrees)"));
  const Run bad = run_tool("portal explain --size 24,12 --pixel 30,6");
  CHECK(bad.exit_code == 1);
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
