// gridrt_replay: every file of the corpus folders through the fuzz targets' entry point
// (fuzz_entry.h), in the normal build (gcc) and under the asan preset. A file named bad_* must
// give a clean Error, ok_* must load, any other (fuzzer finds, random corruption) may do either;
// nothing may crash or throw anything but gridrt::Error.
//   gridrt_replay DIR... [--verbose]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <string>
#include <vector>

#include <unistd.h>

#include "gridrt/common/scene.h"
#include "tests/fuzz/fuzz_entry.h"

namespace fs = std::filesystem;
using namespace gridrt;

int main(int argc, char** argv) {
  std::vector<fs::path> files;
  bool verbose = false;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--verbose") { verbose = true; continue; }
    if (fs::is_regular_file(a)) { files.emplace_back(a); continue; }
    for (const auto& e : fs::recursive_directory_iterator(a)) {
      fuzz::Kind k;
      if (e.is_regular_file() && fuzz::kind_of(e.path().string(), k)) files.push_back(e.path());
    }
  }
  std::sort(files.begin(), files.end());
  const fs::path scratch = fs::temp_directory_path() / ("gridrt-replay-" + std::to_string(::getpid()));
  fs::create_directories(scratch);
  int failures = 0, errors = 0, loaded = 0;
  for (const fs::path& f : files) {
    fuzz::Kind kind;
    fuzz::kind_of(f.string(), kind);
    const std::string name = f.filename().string();
    const bool want_error = name.rfind("bad_", 0) == 0, want_load = name.rfind("ok_", 0) == 0;
    std::string outcome;
    bool ok = true;
    const auto t0 = std::chrono::steady_clock::now();
    try {
      fuzz::load_input(f.string(), kind, scratch.string());
      ++loaded;
      outcome = "loaded";
      ok = !want_error;
    } catch (const Error& e) {
      ++errors;
      outcome = std::string("error: ") + e.what();
      ok = !want_load;
    } catch (const std::exception& e) {
      outcome = std::string("NOT A CLEAN ERROR (") + typeid(e).name() + "): " + e.what();
      ok = false;
    }
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (!ok) ++failures;
    if (verbose || !ok)
      std::printf("%s %s (%.2f s): %s\n", ok ? "ok  " : "FAIL", f.string().c_str(), secs, outcome.c_str());
  }
  std::error_code ec;
  fs::remove_all(scratch, ec);
  std::printf("%zu files: %d loaded, %d clean errors, %d wrong outcomes, 0 crashes (this line is reached)\n",
              files.size(), loaded, errors, failures);
  return failures == 0 ? 0 : 1;
}
