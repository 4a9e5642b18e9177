// gridrt: the command-line tool. Verbs: render, convert (and, with the grid, explain, stats, diff).
//
// Exit codes: 0 success, 1 a user error (bad input, limits, no device), 2 bad command line,
// 5 an internal error (a bug: please report it); diff also 3 (differs) and 4 (validation messages).
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cmath>
#include <cstdlib>
#include <cstdio>
#include <exception>
#include <set>
#include <filesystem>
#include <cstring>
#include <functional>
#include <iostream>
#include <string>
#include <utility>

#include <CLI/CLI.hpp>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/image_io.h"
#include "gridrt/common/scene.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/scene_io.h"

using namespace gridrt;

namespace gridrt::app {

std::vector<std::string> command_line;

Scene load_scene_or_default(const std::string& spec) {
  const std::string s = spec.empty() ? "builtin:" + std::string(kDefaultScene) : spec;
  const auto t0 = std::chrono::steady_clock::now();
  Scene scene = load_scene(s);
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  if (secs > 1.0) std::fprintf(stderr, "loaded %s in %.1f s\n", s.c_str(), secs);
  return scene;
}

FrameLimits& frame_limits() {
  static FrameLimits limits;
  return limits;
}

void check_frame_size(uint32_t width, uint32_t height) {
  const uint64_t pixels = uint64_t(width) * height;
  if (pixels > frame_limits().max_pixels)
    throw Error("an image of " + std::to_string(width) + " x " + std::to_string(height) + " = " + std::to_string(pixels) +
                " pixels exceeds the limit of " + std::to_string(frame_limits().max_pixels) +
                " pixels (--max-pixels; each pixel takes up to about 256 bytes of host memory for the frame's buffers)");
  // And the host's memory, before any of it is allocated: a render with a raised --max-pixels grew
  // to 7 GB over 24 s past --max-host-mib (an outside sweep). About 256 bytes a pixel: the gather
  // buffer, the rays and hits of a trace, the picture and its encoded copy
  require_host_memory(pixels * 256, "an image of " + std::to_string(width) + " x " + std::to_string(height) +
                                         " pixels (its frame buffers)",
                      "lower --width and --height");
}

void check_output_path(const std::string& path) {
  namespace fs = std::filesystem;
  const fs::path p(path);
  const fs::path dir = p.has_parent_path() ? p.parent_path() : fs::path(".");
  if (!is_folder(dir.string())) {
    std::error_code ec;
    throw Error("cannot write '" + path + "': " +
                (fs::exists(dir, ec) ? "'" + dir.string() + "' is not a folder"
                                     : "folder '" + dir.string() + "' does not exist"));
  }
  if (is_folder(p.string())) throw Error("cannot write '" + path + "': it is a folder");
}

void check_image_output(const std::string& path) {
  check_output_path(path);
  try {
    check_image_extension(path);
  } catch (const Error& e) {
    throw OptionsError(e.what());
  }
}

namespace {

// Every number on the command line must be finite: CLI11's range and positivity checks let NaN
// through (every comparison with NaN is false), and "1e999" converts to infinity. A token
// (or the value after '=', or an element of a comma list) that reads in full as a number and is
// not a finite float is rejected before parsing.
// Also a value glued to a short option (-tnan: it passed), and a number written with a leading
// zero (010), which CLI11 reads as octal for an integer (--width 010 made 8 pixels): both found by
// an outside sweep. Returns the token and what is wrong with it, or empty strings.
// How many values `name` (as written: -x, --name) takes as an option of `app` or of any of its
// subcommands (the most of any; 0: a flag or no such option).
int option_values(const CLI::App& app, const std::string& name) {
  int n = 0;
  if (const CLI::Option* o = app.get_option_no_throw(name)) n = std::max(n, o->get_items_expected_max());
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    n = std::max(n, option_values(*sub, name));
  return n;
}

// Whether `name` is a comma-list option of `app` or of any of its subcommands.
bool option_is_list(const CLI::App& app, const std::string& name) {
  if (const CLI::Option* o = app.get_option_no_throw(name); o && o->get_delimiter() == ',') return true;
  for (const CLI::App* sub : app.get_subcommands([](const CLI::App*) { return true; }))
    if (option_is_list(*sub, name)) return true;
  return false;
}

// A comma list with an empty item (4,,8 or a leading or trailing comma): CLI11 drops the empty
// item, so --capacity 4,,8 ran two values without a word (an outside sweep's find).
bool has_empty_item(const std::string& list) {
  return list.empty() || list.front() == ',' || list.back() == ',' || list.find(",,") != std::string::npos;
}

std::pair<std::string, std::string> bad_number_argument(const CLI::App& app, int argc, char** argv) {
  const auto bad_part = [](const std::string& part) -> std::string {
    if (part.empty()) return "";
    char* stop = nullptr;
    const double v = std::strtod(part.c_str(), &stop);
    if (stop && *stop == '\0' && stop != part.c_str() && !(std::isfinite(v) && std::fabs(v) <= 3.4e38))
      return "numbers on the command line must be finite (no nan, inf or overflow)";
    if (stop && *stop == '\0' && stop != part.c_str() && v != 0.0 && std::fabs(v) < 1.17549435e-38)
      return "numbers on the command line must be 0 or at least 1.2e-38 in magnitude (smaller ones are no normal "
             "single-precision number: they would be read as 0 or a subnormal)";
    const size_t d = (part[0] == '+' || part[0] == '-') ? 1 : 0;
    if (part.size() > d + 1 && part[d] == '0' &&
        part.find_first_not_of("0123456789", d) == std::string::npos)
      return "a number may not start with 0 (it would be read as octal): write it without the leading zeros";
    return "";
  };
  const auto bad_value = [&](const std::string& a) -> std::string {
    size_t start = 0;
    while (start <= a.size()) {
      size_t end = a.find(',', start);
      if (end == std::string::npos) end = a.size();
      if (std::string why = bad_part(a.substr(start, end - start)); !why.empty()) return why;
      start = end + 1;
    }
    return "";
  };
  // Options whose value is a file or folder name, which may look like a number ("007", "inf": an
  // outside sweep's folders were refused as octal or infinite)
  static const std::set<std::string> paths{"-o", "--output", "--output-dir", "--slices", "--json", "--junit", "--svg",
                                           "--html", "--export", "--ray-file"};
  int values_left = 0;  // tokens still to come that are the last option's values (--pixel 3 010)
  bool list = false;    // the last option is a comma list
  const std::string empty_item = "a comma list may not have an empty item (4,,8, or a leading or trailing comma): write 4,8";
  for (int i = 1; i < argc; ++i) {
    std::string a = argv[i];
    const bool option_value = values_left > 0 && a.rfind("-", 0) != 0;
    values_left = option_value ? values_left - 1 : 0;
    if (option_value && list && a.find(',') != std::string::npos && has_empty_item(a)) return {argv[i], empty_item};
    if (!option_value) list = false;
    if (a.size() > 1 && a[0] == '-' && a.find('=') == std::string::npos) {
      const int n = option_values(app, a);
      values_left = n > 16 ? 1 << 20 : n;  // a list option: every token up to the next option
      list = option_is_list(app, a);
    }
    if (const size_t eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos &&
                                       option_is_list(app, a.substr(0, eq))) {
      const std::string v = a.substr(eq + 1);
      if (v.find(',') != std::string::npos && has_empty_item(v)) return {argv[i], empty_item};
    }
    // explain --ray takes inf and nan on purpose: it shows how the tracer rejects such a ray
    if (a == "--ray" || paths.count(a)) {
      ++i;
      values_left = 0;
      continue;
    }
    if (a.rfind("--ray=", 0) == 0) continue;
    if (const size_t eq = a.find('='); eq != std::string::npos && paths.count(a.substr(0, eq))) continue;
    // -oNAME: a path option's value glued on
    if (a.size() > 2 && a[0] == '-' && a[1] != '-' && paths.count(a.substr(0, 2))) continue;
    // A file or folder that exists is a name, not a number (a scene named "1e999"), where it stands
    // as a positional argument: an option's value is judged as written (a file named 010 in the
    // working folder let --width 010 through as octal 8, and one named nan NaN into --density:
    // an outside review's find)
    if (std::error_code ec; !option_value && std::filesystem::exists(a, ec)) continue;
    if (const size_t eq = a.find('='); a.rfind("--", 0) == 0 && eq != std::string::npos) a = a.substr(eq + 1);
    if (std::string why = bad_value(a); !why.empty()) return {argv[i], why};
    // -tVALUE: a short option with its value glued on
    if (a.size() > 2 && a[0] == '-' && std::isalpha(static_cast<unsigned char>(a[1])))
      if (std::string why = bad_value(a.substr(2)); !why.empty()) return {argv[i], why};
  }
  return {"", ""};
}

}  // namespace

}  // namespace gridrt::app

namespace {

// Standard output written in full, or exit 1: the verbs whose product is their text (stats,
// explain) exited 0 with none of it written to a full disk (an outside sweep)
int stdout_status() {
  std::cout.flush();
  errno = 0;
  if (std::fflush(stdout) == 0 && !std::ferror(stdout) && !std::cout.fail()) return 0;
  // (the failed write's errno is gone by now: stdio keeps only its error flag)
  std::fprintf(stderr, "gridrt: error: cannot write to standard output%s%s\n", errno ? ": " : "",
               errno ? std::strerror(errno) : " (a full disk, or a pipe whose reader has gone)");
  return 1;
}

}  // namespace

int main(int argc, char** argv) {
  // A write to a closed pipe or past the file-size limit returns its error (EPIPE, EFBIG), which
  // every write checks, rather than ending the process by a signal with no word and a temporary
  // file left behind (an outside sweep)
  std::signal(SIGPIPE, SIG_IGN);
  std::signal(SIGXFSZ, SIG_IGN);
  CLI::App app{
      "gridrt: ray tracing without ray-tracing hardware. The fixed-capacity grid of\n"
      "\"Hybrid ray/voxel tracing with fixed-capacity grids\" as a CPU reference (the spec) and a\n"
      "Vulkan port, with Embree as the ground truth."};
  app.require_subcommand(1);
  app.set_version_flag("--version", "gridrt 0.1.0");
  app::add_render_command(app);
  app::add_convert_command(app);
  app::add_explain_command(app);
  app::add_grid_commands(app);
  app::add_diff_command(app);
  app::add_bench_command(app);
  app::add_portal_command(app);
  app::add_sweep_command(app);
#ifdef GRIDRT_HAVE_VERIFY
  app::add_verify_command(app);
#endif
  // Resource limits (safe_io.h, commands.h), before or after the verb: every verb (and the
  // portal's verbs) passes the options it does not know up to the app (a subcommand copies its
  // parent's fallthrough when it is made, so it is set on each made above).
  app.fallthrough();
  const std::function<void(CLI::App*)> fall_through = [&](CLI::App* cmd) {
    for (CLI::App* sub : cmd->get_subcommands([](CLI::App*) { return true; })) {
      sub->fallthrough();
      fall_through(sub);
    }
  };
  fall_through(&app);
  // An empty value names nothing: `--json ""` wrote no file and said nothing, `--slices ""` drew
  // nothing (an outside sweep). Every option that takes a value refuses an empty one (exit 2).
  const CLI::Validator non_empty(
      [](std::string& v) { return v.empty() ? std::string("an empty value names nothing") : std::string(); }, "");
  const std::function<void(CLI::App*)> refuse_empty = [&](CLI::App* cmd) {
    for (CLI::Option* opt : cmd->get_options([](const CLI::Option* o) { return o->get_type_size() != 0; }))
      opt->check(non_empty);
    for (CLI::App* sub : cmd->get_subcommands([](CLI::App*) { return true; })) refuse_empty(sub);
  };
  InputLimits& limits = input_limits();
  app.add_option_function<double>(
         "--max-input-mib", [&limits](double mib) { limits.max_file_bytes = uint64_t(mib * 1024.0 * 1024.0); },
         "Largest input file (scene, model, buffer, texture) in MiB (default 4096)")
      ->check(CLI::Range(0.001, 1.0e6))->group("Limits");
  app.add_option("--max-texture-pixels", limits.max_texture_pixels,
                 "Largest texture in pixels, checked from the image's header before decoding (default 67108864)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))->group("Limits");
  app.add_option_function<double>(
         "--max-host-mib", [&limits](double mib) { limits.max_host_bytes = uint64_t(mib * 1024.0 * 1024.0); },
         "Most host memory the decoded textures, the grids' plans and the CPU builds may take, in MiB, beyond what "
         "the process holds before the first of them (the program and the scene read so far) (default: what the "
         "machine has free), checked before they allocate")
      ->check(CLI::Range(1.0, 1.0e9))->group("Limits");
  app.add_option("--max-triangles", limits.max_triangles, "Most triangles in a scene, over all instances (default 33554432)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))->group("Limits");
  app.add_option("--max-pixels", app::frame_limits().max_pixels,
                 "Largest rendered image (width x height) in pixels (default 33554432)")
      ->check(CLI::Range(uint64_t(1), uint64_t(1) << 32))->group("Limits");
  refuse_empty(&app);
  if (const auto [bad, why] = app::bad_number_argument(app, argc, argv); !bad.empty()) {
    std::fprintf(stderr, "gridrt: error: '%s': %s\n", bad.c_str(), why.c_str());
    return 2;
  }
  app::command_line.assign(argv, argv + argc);
  guard_inputs(true);  // no output replaces a file this run read (the scene, its textures, a ray file)
  try {
    app.parse(argc, argv);
    return stdout_status();
  } catch (const CLI::ParseError& e) {
    const int code = app.exit(e);  // prints help, version or the parse error
    // A pair option (X,Y or W,H) takes the word after it when its comma form gave fewer than its
    // count: "-p 1,1 SCENE" read SCENE as a third coordinate, and CLI11's message said only "At
    // Most 2 required but received 3" (an outside sweep)
    if (dynamic_cast<const CLI::ArgumentMismatch*>(&e) != nullptr &&
        std::string(e.what()).find("received") != std::string::npos)
      std::fprintf(stderr, "gridrt: a pair option (X,Y or W,H) also takes the word after it: give the scene (or any "
                           "positional) before it, or another option between them\n");
    return code == 0 ? stdout_status() : 2;
  } catch (const app::Differs& e) {
    std::fprintf(stderr, "gridrt: %s\n", e.what());
    return 3;
  } catch (const app::ExitStatus& e) {
    return e.code;
  } catch (const OptionsError& e) {  // options that contradict one another: the command line's
    std::fprintf(stderr, "gridrt: error: %s\n", e.what());
    return 2;
  } catch (const Error& e) {
    std::fprintf(stderr, "gridrt: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    // A resource limit, not a bug: the limits above bound what files and options may ask for,
    // so this means the machine has less memory than they allow.
    std::fprintf(stderr, "gridrt: error: out of memory (lower --max-pixels, --max-triangles, --memory-budget or "
                         "--max-texture-pixels)\n");
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "gridrt: internal error: %s\n", e.what());
    return 5;
  }
}
