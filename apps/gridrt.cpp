// gridrt: the command-line tool.
#include <CLI/CLI.hpp>
#include <cstdio>

int main(int argc, char** argv) {
  CLI::App app{"gridrt: fixed-capacity grid ray tracing, CPU reference and Vulkan"};
  app.require_subcommand(1);
  CLI11_PARSE(app, argc, argv);
  return 0;
}
