// run_tool.h: run the gridrt tool (GRIDRT_TOOL, set by tests/CMakeLists.txt) with arguments and
// take its exit code and its stdout and stderr together; the tests of the command line use it.
#pragma once

#include <catch2/catch.hpp>

#include <array>
#include <cstdio>
#include <string>
#include <sys/wait.h>

namespace gridrt::test {

struct Run {
  int exit_code;       // -1 when the tool did not exit normally (a crash)
  std::string output;  // stdout and stderr together
};

inline Run run_tool(const std::string& args) {
  const std::string cmd = std::string(GRIDRT_TOOL) + " " + args + " 2>&1";
  FILE* pipe = popen(cmd.c_str(), "r");
  REQUIRE(pipe != nullptr);
  std::string out;
  std::array<char, 4096> buf{};
  while (size_t n = fread(buf.data(), 1, buf.size(), pipe)) out.append(buf.data(), n);
  const int status = pclose(pipe);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

}  // namespace gridrt::test
