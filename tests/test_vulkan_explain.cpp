// gridrt explain --backend vulkan end to end: the shader's own record beside the reference's,
// aligned, as text and JSON, with the validation layer on (any message fails the run).
#include <catch2/catch.hpp>

#include <cstdlib>
#include <filesystem>
#include <fstream>

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
