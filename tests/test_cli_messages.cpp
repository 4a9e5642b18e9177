// test_cli_messages.cpp: options that do nothing in the combination given are refused with the
// command line's exit code, messages say what happened (sizes, times, empty intervals, the
// llvmpipe estimate, names with control bytes, non-UTF-8 bytes of a file), and outputs go only
// where they were asked to: an outside sweep's finds, each seen wrong before its fix.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/run_tool.h"

namespace fs = std::filesystem;
using Catch::Contains;
using gridrt::test::Run;
using gridrt::test::run_tool;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / "gridrt_test_cli_messages";
  fs::create_directories(dir);
  return dir / name;
}

void write(const fs::path& p, const std::string& text) {
  std::ofstream f(p, std::ios::binary);
  f << text;
}

}  // namespace

TEST_CASE("CLI: bench refuses the frame's options where no frame runs, and --gather-lists without the compute gather",
          "[cli][bench][vulkan]") {
  const std::string base = "bench builtin:cornell --width 8 --height 8 --frames 1 --warmup 0 --backend vulkan ";
  // The Cornell box has no glossy material: --rays auto traces a list of diffuse rays, no frame
  for (const char* knob : {"--compact-rays", "--gather raster", "--gather-lists scan", "--back-to-back 2"}) {
    const Run r = run_tool(base + knob);
    INFO(knob << "\n" << r.output);
    CHECK(r.exit_code == 2);
    CHECK_THAT(r.output, Contains("has no glossy material") && Contains("does nothing"));
  }
  const Run lists = run_tool(base + "--gather boxes --gather-lists scan");
  INFO(lists.output);
  CHECK(lists.exit_code == 2);
  CHECK_THAT(lists.output, Contains("--gather-lists") && Contains("--gather boxes has none"));
}

TEST_CASE("CLI: bench prints the threads it runs with", "[cli][bench]") {
  const Run r = run_tool("bench builtin:cornell --width 8 --height 8 --frames 1 --warmup 0 --backend cpu --threads 1");
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  CHECK_THAT(r.output, Contains("| CPU, 1 threads |"));
}

TEST_CASE("CLI: sweep refuses a paper traversal's knob with the exact traversal alone, one value too", "[cli][sweep]") {
  for (const char* knob : {"--revisit skip", "--gap-fill off", "--elongation 3"}) {
    const Run r = run_tool("sweep builtin:cornell -o " + scratch("sweep").string() +
                           " --width 8 --height 8 --traversal exact " + knob);
    INFO(knob << "\n" << r.output);
    CHECK(r.exit_code == 2);
    CHECK_THAT(r.output, Contains("knob of the paper traversal"));
  }
}

TEST_CASE("CLI: explain names an empty interval, the scene time in full and control bytes of names", "[cli][explain]") {
  // tmin 5 > tmax 1: the ray meets the box, but nothing can be hit
  const Run empty = run_tool("explain builtin:cornell --ray 1,1,1,0,0,1,5,1 --brief");
  INFO(empty.output);
  REQUIRE(empty.exit_code == 0);
  CHECK_THAT(empty.output, Contains("interval is empty (tmin 5 >= tmax 1)"));
  CHECK_THAT(empty.output, !Contains("does not meet the grid box"));
  CHECK_THAT(empty.output, !Contains("misses the grid box"));  // its setup step too (a later sweep)
  CHECK_THAT(empty.output, Contains("no part of the ray's interval (tmin, tmax) lies in the grid box"));
  // The time as given, not to 6 digits
  const Run t = run_tool("explain " + std::string(GRIDRT_DATA_DIR) + "/scenes/teapot.json -t 123456.7 --width 8 --height 8 -p 4,4 --brief");
  INFO(t.output);
  REQUIRE(t.exit_code == 0);
  CHECK_THAT(t.output, Contains("t = 123456.703"));
  // An instance named with a line break and an escape: one line each, escaped
  const fs::path scene = scratch("names.json");
  write(scene, R"({"meshes": {"m": {"builtin": "teapot"}},
                   "instances": [{"name": "two\nlines\u001b[31m", "mesh": "m"}]})");
  const Run n = run_tool("explain " + scene.string() + " --width 16 --height 16 -p 8,8");
  INFO(n.output);
  REQUIRE(n.exit_code == 0);
  CHECK_THAT(n.output, Contains("\"two\\x0Alines\\x1B[31m\""));
  CHECK_THAT(n.output, !Contains("two\nlines"));
}

TEST_CASE("CLI: explain --export to a character device writes no materials file beside it", "[cli][explain]") {
  const bool before = fs::exists("/dev/null.mtl");
  const Run r = run_tool("explain builtin:cornell --width 40 --height 30 -p 20,15 --brief --export /dev/null");
  INFO(r.output);
  const bool made = !before && fs::exists("/dev/null.mtl");
  if (made) fs::remove("/dev/null.mtl");  // what the old code did: do not leave it behind
  CHECK(r.exit_code == 0);
  CHECK_FALSE(made);
  CHECK_THAT(r.output, Contains("a stream: without its materials"));
}

TEST_CASE("CLI: stats --slices checks its pixel before the build", "[cli][stats]") {
  const fs::path dir = scratch("slices");
  fs::create_directories(dir);
  const Run r = run_tool("stats builtin:cornell --slices " + dir.string() + " -p 50,50 --width 10 --height 10");
  INFO(r.output);
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.output, Contains("lies outside the 10x10 image"));
  CHECK_THAT(r.output, !Contains("triangles in"));  // no report printed before the refusal
}

TEST_CASE("CLI: sizes in limit messages to two decimals, with their bytes", "[cli][limits]") {
  // A 1,600,024-byte OBJ (1.53 MiB) over --max-input-mib 1
  const fs::path obj = scratch("big.obj");
  {
    std::ofstream f(obj, std::ios::binary);
    f << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
    const std::string pad(1600024 - 32, '#');
    f << pad << "\n";
  }
  const Run r = run_tool("--max-input-mib 1 stats " + obj.string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK_THAT(r.output, Contains("1.53 MiB (" + std::to_string(fs::file_size(obj)) + " bytes)"));
}

TEST_CASE("CLI: a glTF parser's message shows the file's non-ASCII bytes escaped", "[cli][gltf]") {
  const fs::path g = scratch("bad.gltf");
  write(g, std::string("{\"asset\": \x8F\xFE") + "}");
  const Run r = run_tool("stats " + g.string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  bool raw = false;
  for (const char c : r.output) raw = raw || static_cast<unsigned char>(c) >= 0x80;
  CHECK_FALSE(raw);
  CHECK_THAT(r.output, Contains("\\x8F"));
}

TEST_CASE("CLI: render --view counts the figure's title, bar and legend against --max-pixels", "[cli][render]") {
  fs::remove(scratch("wide.png"));
  const Run r = run_tool("render builtin:cornell --view cells --scale 16 --width 16384 --height 1 -o " +
                         scratch("wide.png").string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK_THAT(r.output, Contains("exceeds the limit") && Contains("--max-pixels"));
  CHECK_FALSE(fs::exists(scratch("wide.png")));
}

TEST_CASE("CLI: portal render's output without an image extension is the command line's error, as render's",
          "[cli][portal]") {
  const Run grid = run_tool("render builtin:cornell --width 8 --height 8 -o " + scratch("noext").string());
  const Run portal = run_tool("portal render builtin:level --width 8 --height 8 -o " + scratch("noext").string());
  INFO(grid.output << "\n" << portal.output);
  CHECK(grid.exit_code == 2);
  CHECK(portal.exit_code == 2);
  CHECK_THAT(portal.output, Contains("no file extension"));
}

TEST_CASE("CLI: portal export names the materials and meshes it writes beside the scene", "[cli][portal]") {
  const fs::path out = scratch("exported.json");
  const Run r = run_tool("portal export builtin:blocks -o " + out.string());
  INFO(r.output);
  REQUIRE(r.exit_code == 0);
  const std::string stem = (out.parent_path() / out.stem()).string();
  CHECK_THAT(r.output, Contains(stem + ".mtl") && Contains(stem + "_*.obj"));
  CHECK(fs::exists(stem + ".mtl"));
}

TEST_CASE("CLI: the portal build's arrays are checked against --max-host-mib before they are made", "[cli][portal][limits]") {
  const Run r = run_tool("--max-host-mib 100 portal render builtin:cornell --voxels 200 --width 8 --height 8 -o " +
                         scratch("portal.png").string());
  INFO(r.output);
  CHECK(r.exit_code == 1);
  CHECK_THAT(r.output, Contains("the portal build's arrays for") && Contains("--max-host-mib"));
  // A world within the limit is built
  const Run small = run_tool("--max-host-mib 100 portal render builtin:cornell --voxels 32 --width 8 --height 8 -o " +
                             scratch("portal.png").string());
  INFO(small.output);
  CHECK(small.exit_code == 0);
}

TEST_CASE("CLI: explain --ray refuses the exact traversal's knobs with the paper traversal, as stats does",
          "[cli][explain]") {
  // --ray traces the options' grid alone: the knob changed no byte of the account
  for (const char* knob : {"--skip-empty off", "--mailbox on", "--skip-covered off"}) {
    const Run r = run_tool("explain builtin:teapot --traversal paper --ray 0,0.3,3,0,0,-1 --brief " + std::string(knob));
    INFO(knob << "\n" << r.output);
    CHECK(r.exit_code == 2);
    CHECK_THAT(r.output, Contains("knob of the exact traversal"));
  }
  // The same ray with the exact traversal takes them
  CHECK(run_tool("explain builtin:teapot --traversal exact --ray 0,0.3,3,0,0,-1 --brief --skip-empty off").exit_code == 0);
}

TEST_CASE("CLI: --max-image-dimension on the compact layout is refused, and sweep's CSV says it does not apply",
          "[cli][grid][sweep]") {
  // The compact layout has no image: the grid was the same with the limit at 2
  const Run r = run_tool("stats builtin:teapot --traversal exact --max-image-dimension 2");
  INFO(r.output);
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.output, Contains("--max-image-dimension bounds the image layout's 3D image"));
  CHECK(run_tool("stats builtin:teapot --traversal exact --layout image --max-image-dimension 4096").exit_code == 0);
  // sweep: a compact row's max_dim is "-", and the configurations the build refused are listed
  // in the table (12 configurations, 10 rows, and only stderr said why)
  const fs::path dir = scratch("sweep-dim");
  fs::remove_all(dir);
  const Run s = run_tool("sweep builtin:cornell -o " + dir.string() +
                         " --width 8 --height 8 --traversal exact --capacity auto,percentile --max-image-dimension 2,4096");
  INFO(s.output);
  REQUIRE(s.exit_code == 0);
  std::ifstream csv(dir / "builtin-cornell.csv");
  std::string line, text;
  std::getline(csv, line);  // the header
  size_t rows = 0, dash = 0;
  while (std::getline(csv, line)) {
    ++rows;
    dash += line.find(",-,") != std::string::npos;
  }
  CHECK(rows >= 2);
  CHECK(dash >= 1);  // the compact rows (auto)
  std::ifstream md(dir / "builtin-cornell.md");
  text.assign(std::istreambuf_iterator<char>(md), {});
  // A percentile grid within a 2-texel image is refused for any scene (its slot axis needs more)
  CHECK_THAT(text, Contains("configurations skipped (not in the table or the CSV)"));
  CHECK_THAT(text, Contains("dim=2"));
}

TEST_CASE("CLI: a pair option that takes the scene after it says so", "[cli][explain]") {
  const Run r = run_tool("explain -p 1,1 builtin:cornell");
  INFO(r.output);
  CHECK(r.exit_code == 2);
  CHECK_THAT(r.output, Contains("give the scene (or any positional) before it"));
}

TEST_CASE("CLI: a ray's value beyond a float's range is named so, not as something else than a number", "[cli][explain]") {
  const Run r = run_tool("explain builtin:cornell --ray 0,1,2,0,0,1e39 --brief");
  INFO(r.output);
  CHECK(r.exit_code != 0);
  CHECK_THAT(r.output, Contains("is beyond a float's range"));
  CHECK_THAT(run_tool("explain builtin:cornell --ray 0,1,2,0,0,x1 --brief").output, Contains("is not a float"));
}

TEST_CASE("CLI: a scene's name with control bytes, verify's rays over the host budget, a glTF link loop, a generated "
          "level's seed past 32 bits",
          "[cli][badinput]") {
  // A scene's "name" with an escape sequence and a line break went to the terminal raw
  const fs::path tri = scratch("name_tri.obj");
  write(tri, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const fs::path scene = scratch("name_ctrl.json");
  write(scene, "{\"name\": \"a\\u001b[31mred\\n../etc\", \"meshes\": {\"t\": {\"file\": \"" + tri.filename().string() +
                   "\"}}, \"instances\": [{\"mesh\": \"t\"}]}");
  const Run named = run_tool("stats " + scene.string());
  INFO(named.output);
  CHECK(named.exit_code == 0);
  CHECK_THAT(named.output, Contains("a\\x1B[31mred\\x0A../etc"));
  CHECK(named.output.find('\x1b') == std::string::npos);
  // verify's rays are checked against --max-host-mib before they are made (-n 10,000,000 took 2.1 GB)
  const Run rays = run_tool("verify " + tri.string() + " -n 10000000 --families degenerate --max-host-mib 300");
  INFO(rays.output);
  CHECK(rays.exit_code == 1);
  CHECK_THAT(rays.output, Contains("10000000 rays a family") && Contains("lower -n"));
  // A glTF buffer that is a loop of symbolic links: named, not "File not found"
  const fs::path a = scratch("loop_a.bin"), b = scratch("loop_b.bin");
  fs::remove(a);
  fs::remove(b);
  fs::create_symlink(b.filename(), a);
  fs::create_symlink(a.filename(), b);
  const fs::path gltf = scratch("loop.gltf");
  write(gltf, R"({"asset": {"version": "2.0"}, "buffers": [{"uri": "loop_a.bin", "byteLength": 36}],
    "bufferViews": [{"buffer": 0, "byteLength": 36}],
    "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3", "min": [0, 0, 0], "max": [1, 1, 0]}],
    "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}], "nodes": [{"mesh": 0}], "scenes": [{"nodes": [0]}]})");
  const Run loop = run_tool("stats " + gltf.string());
  INFO(loop.output);
  CHECK(loop.exit_code == 1);
  CHECK_THAT(loop.output, Contains("symbolic links"));
  // A generated level's seed past 32 bits: the message says what a number may be
  const Run seed = run_tool("portal render gen:5x5x1:99999999999999999999999 --width 8 --height 8 -o " +
                            scratch("seed.png").string());
  INFO(seed.output);
  CHECK(seed.exit_code == 1);
  CHECK_THAT(seed.output, Contains("at most 4294967295"));
}

TEST_CASE("CLI: a grid of 2^31 cells or more is refused before anything is allocated", "[cli][badinput]") {
  // 4096x4096x256 cells (2^32) wrapped to 0 in the 32-bit cell count: the plan took 17 GB, then
  // wrote past its occupancy map (an outside sweep)
  for (const char* res : {"4096,4096,256", "16384,16384,8"}) {
    const Run r = run_tool(std::string("stats builtin:cornell --traversal exact --memory-budget 100000 --resolution ") + res);
    INFO(r.output);
    CHECK(r.exit_code != 0);
    CHECK_THAT(r.output, Contains("more than a grid may have"));
  }
}

TEST_CASE("CLI: triangles below the domain's floor in a scene of ordinary size are named in a warning", "[cli][badinput]") {
  // A closed cube 1e-18 across inside a box 2 units across: the scene's box passed the 2^-40
  // floor, and a ray through the cube passed through it without a word (an outside sweep); a
  // cube 1e-12 across is within the floor and draws no warning
  for (const double side : {1e-18, 1e-12}) {
    const fs::path obj = scratch(side < 1e-15 ? "tiny18.obj" : "tiny12.obj");
    std::ofstream f(obj);
    f << "v -1 -1 -1\nv 1 -1 -1\nv -1 1 -1\n";  // a triangle of the box: the scene is 2 across
    for (int k = 0; k < 8; ++k)
      f << "v " << (k & 1 ? side : 0.0) << " " << (k & 2 ? side : 0.0) << " " << (k & 4 ? side : 0.0) << "\n";
    f << "f 1 2 3\n";
    // the cube's 12 triangles (vertices 4..11)
    const int q[6][4] = {{0, 1, 3, 2}, {4, 6, 7, 5}, {0, 4, 5, 1}, {2, 3, 7, 6}, {0, 2, 6, 4}, {1, 5, 7, 3}};
    for (const auto& s : q) {
      f << "f " << 4 + s[0] << " " << 4 + s[1] << " " << 4 + s[2] << "\n";
      f << "f " << 4 + s[0] << " " << 4 + s[2] << " " << 4 + s[3] << "\n";
    }
    f.close();
    const Run r = run_tool("stats " + obj.string() + " --traversal exact");
    INFO(r.output);
    CHECK(r.exit_code == 0);
    if (side < 1e-15) {
      CHECK_THAT(r.output, Contains("12 triangle(s) have every side below 2^-40"));
    } else {
      CHECK_THAT(r.output, !Contains("below 2^-40"));
    }
  }
}
