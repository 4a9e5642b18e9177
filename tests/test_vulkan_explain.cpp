// gridrt explain --backend vulkan end to end: the shader's own record beside the reference's,
// aligned, as text and JSON, with the validation layer on (any message fails the run).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <vector>

#include <nlohmann/json.hpp>

#include "tests/run_tool.h"
#include "gridrt/vulkan/context.h"

using gridrt::test::run_tool;

TEST_CASE("Explain: --backend vulkan sets the shader's record beside the reference's", "[vulkan][cli][explain]") {
  // The tool's runs with the validation layer: any message fails them
  setenv("GRIDRT_VALIDATION", "1", 1);
  struct Unset {
    ~Unset() { unsetenv("GRIDRT_VALIDATION"); }
  } unset;
  // A pixel's primary ray: the exact traversal, as the frame's gather
  const gridrt::test::Run t = run_tool("explain builtin:cornell --width 32 --height 24 --pixel 16,12 --backend vulkan");
  INFO(t.output);
  REQUIRE(t.exit_code == 0);
  CHECK_THAT(t.output, Catch::Contains("== Vulkan (") && Catch::Contains("traversal exact"));
  CHECK_THAT(t.output, Catch::Contains("identical: all ") && Catch::Contains("agree bit for bit"));
  // Any ray, as JSON: the two records and their alignment, every row paired and equal
  const std::filesystem::path json = std::filesystem::temp_directory_path() / "gridrt_vulkan_explain.json";
  std::filesystem::remove(json);
  const gridrt::test::Run j = run_tool("explain builtin:cornell --ray 2.78,2.74,2.79,0x1p-1,-1,0.25 --backend vulkan "
                                       "--json " + json.string());
  INFO(j.output);
  REQUIRE(j.exit_code == 0);
  std::ifstream in(json);
  const nlohmann::json doc = nlohmann::json::parse(in);
  const nlohmann::json& ray = doc["rays"][0];
  REQUIRE(ray["shader"]["events"].size() == ray["reference"]["events"].size());
  CHECK(ray["alignment"]["identical"] == true);
  CHECK(ray["alignment"]["rows"].size() == ray["reference"]["events"].size());
  for (const auto& row : ray["alignment"]["rows"]) CHECK(row[2] == true);
  // An outside sweep's find: rays from the grid box's edge pointing out of it had t_end -0 on the
  // CPU and +0 in the shader (min of -0 and +0); the setup now makes every zero +0
  const gridrt::test::Run z = run_tool("explain builtin:cornell --traversal exact "
                                       "--ray=-0x1.6e7a32p-8,0x1.60b3aap+2,1,-1,1,0 --backend vulkan");
  INFO(z.output);
  REQUIRE(z.exit_code == 0);
  CHECK_THAT(z.output, Catch::Contains("t_end 0 [0x00000000]") && Catch::Contains("agree bit for bit"));
}

TEST_CASE("Explain: --backend vulkan with the mailbox - the skipped re-tests on both backends alike, --mailbox off "
          "tests them",
          "[vulkan][cli][explain][mailbox]") {
  setenv("GRIDRT_VALIDATION", "1", 1);
  struct Unset {
    ~Unset() { unsetenv("GRIDRT_VALIDATION"); }
  } unset;
  // A primary ray of the atrium through the foliage: triangles met again in later cells
  // (covered cells off: their runs would take the re-tests away before the mailbox sees them)
  const std::string ray =
      "explain builtin:atrium --width 160 --height 90 --pixel 120,60 --backend vulkan --brief --skip-covered off";
  const gridrt::test::Run on = run_tool(ray + " --mailbox on");
  INFO(on.output);
  REQUIRE(on.exit_code == 0);
  CHECK_THAT(on.output, Catch::Contains("mailbox on") && Catch::Contains(": mailboxed"));
  CHECK_THAT(on.output, Catch::Contains("identical: all ") && Catch::Contains("agree bit for bit"));
  const gridrt::test::Run off = run_tool(ray + " --mailbox off");
  INFO(off.output);
  REQUIRE(off.exit_code == 0);
  CHECK_THAT(off.output, !Catch::Contains("mailbox"));
  CHECK_THAT(off.output, Catch::Contains("identical: all ") && Catch::Contains("agree bit for bit"));
}

TEST_CASE("Outside sweep: sweep and bench report the figures they measured, and only those", "[vulkan][cli]") {
  namespace fs = std::filesystem;
  const fs::path d = fs::temp_directory_path() / "gridrt_report_figures";
  fs::remove_all(d);
  fs::create_directories(d);
  // sweep: the Vulkan row's grid_mib is everything the grid keeps, as the CPU row's (it was the
  // image alone), and the CSV keeps the figures' digits (times of 0.00 beside a rate made of them)
  {
    const gridrt::test::Run r = run_tool("sweep builtin:teapot -b cpu,vulkan,cpu --width 16 --height 12 --traversal exact "
                                         "--triangle-test moller --capacity 8,8 -o " + (d / "sweep").string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    std::ifstream f(d / "sweep" / "builtin-teapot.csv");
    std::string header, line;
    std::getline(f, header);
    std::vector<std::vector<std::string>> rows;
    while (std::getline(f, line)) {
      std::vector<std::string> cells;
      std::stringstream s(line);
      for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
      rows.push_back(cells);
    }
    std::vector<std::string> names;
    {
      std::stringstream s(header);
      for (std::string c; std::getline(s, c, ',');) names.push_back(c);
    }
    auto col = [&](const std::string& n) { return size_t(std::find(names.begin(), names.end(), n) - names.begin()); };
    // cpu named twice, 8 named twice (08 is refused: a leading zero): one CPU row and one Vulkan row
    REQUIRE(rows.size() == 2);
    CHECK(rows[0][col("backend")] == "cpu");
    CHECK(rows[1][col("backend")] == "vulkan");
    CHECK(rows[0][col("capacity_knob")] == "8");
    CHECK(rows[0][col("grid_mib")] == rows[1][col("grid_mib")]);
    for (const auto& row : rows) {
      const double ms = std::stod(row[col("trace_ms")]), rate = std::stod(row[col("mrays_per_s")]);
      CHECK(ms > 0.0);
      CHECK(rate > 0.0);
    }
  }
  // bench on lavapipe (the host clock): the phases it did not time are null in the JSON and "-"
  // in the table, not zeros, and grid_mib means what the CPU backend's means
  {
    const fs::path json = d / "bench.json";
    const gridrt::test::Run r = run_tool("bench builtin:atrium -b cpu,vulkan --width 24 --height 16 --frames 1 --warmup 0 "
                                         "--json " + json.string());
    INFO(r.output);
    REQUIRE(r.exit_code == 0);
    std::ifstream f(json);
    const nlohmann::json j = nlohmann::json::parse(f);
    const nlohmann::json& v = j["backends"]["vulkan"];
    if (v["clock"].get<std::string>().rfind("host", 0) == 0) {
      CHECK(v["mrays_per_s"].is_null());
      CHECK(v["build_warm_ms"].is_null());
      CHECK(!v.contains("trace_ms"));
      CHECK(!v.contains("gather_ms"));
      CHECK(v["frame_ms"].get<double>() > 0.0);
      CHECK_THAT(r.output, Catch::Contains("| - | - | - | - |"));
    }
    CHECK(v["grid_mib"].get<double>() == Approx(j["backends"]["cpu"]["grid_mib"].get<double>()));
    CHECK(v["storage_mib"].get<double>() <= v["grid_mib"].get<double>());
  }
  fs::remove_all(d);
}
