// cmd_verify.cpp: `gridrt verify SCENE`: a tracer against Embree on the adversarial ray families,
// every difference judged by the exact referee (verify/verify.h). Prints a table per family;
// --json FILE writes it as JSON. Exit codes: 0 no wrong answer, no crack, no NaN t (or the paper
// traversal, whose differences are reported, not failed, unless --strict); 1 bad input; 2 command
// line; 3 the tracer is wrong or cracks.
#include <algorithm>
#include <cstdio>
#include <cerrno>
#include <cmath>
#include <cstdlib>
#include <memory>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/safe_io.h"
#include "verify/verify.h"

namespace gridrt::app {

namespace {

struct VerifyCliOptions {
  std::string scene;
  std::string backend = "cpu";
  BackendOptions backend_options;
  std::vector<std::string> families;
  size_t rays = 4000;
  uint64_t seed = 1;
  bool no_translated = false;
  std::vector<float> offset;
  std::string json;
  bool strict = false;
};

// The host memory a ray of a family takes while it is verified (rays, both tracers' hits, verdicts)
constexpr uint64_t kVerifyBytesPerRay = 224;

void run_verify(const VerifyCliOptions& o) {
  if (!o.json.empty()) check_output_path(o.json);
  if (o.backend != "cpu" && o.backend != "vulkan") throw OptionsError("verify: --backend must be cpu or vulkan");
  // A family's rays, hits, Embree's hits and verdicts: about 212 bytes a ray measured (a family at
  // a time; -n 2,000,000 took 555 MB where -n 100,000 took 153 MB), checked before they are made
  // (-n 10,000,000 took 2.1 GB whatever --max-host-mib said: an outside sweep)
  require_host_memory(uint64_t(o.rays) * kVerifyBytesPerRay,
                      "verify: " + std::to_string(o.rays) + " rays a family (-n, about " +
                          std::to_string(kVerifyBytesPerRay) + " bytes a ray)",
                      "lower -n, or raise --max-host-mib");
  verify::VerifyOptions vo;
  vo.family.rays = o.rays;
  vo.family.seed = o.seed;
  vo.translated = !o.no_translated;
  if (!o.offset.empty()) vo.offset = glm::vec3(o.offset[0], o.offset[1], o.offset[2]);
  // The ray domain's origins lie within 2^24 of the world's: an offset past it moves every ray
  // out (it was told as a scene too small for a float's step there: an outside sweep)
  for (const float c : o.offset)
    if (!(std::fabs(c) <= 16777216.0f))
      throw OptionsError("--offset: " + [&] {
                           char b[32];
                           std::snprintf(b, sizeof b, "%g", double(c));
                           return std::string(b);
                         }() + " lies beyond 2^24 (16777216) from the origin, outside the ray "
                         "domain's origins (docs/SPEC.md \"Domain\"): give a smaller offset");
  if (!o.families.empty()) {
    vo.families.clear();
    for (size_t k = 0; k < o.families.size(); ++k) {
      const std::string& f = o.families[k];
      // A family named twice ran twice and counted its rays twice in the total (an outside sweep)
      if (std::find(o.families.begin(), o.families.begin() + std::ptrdiff_t(k), f) != o.families.begin() + std::ptrdiff_t(k))
        throw OptionsError("--families names '" + f + "' twice: name each family once");
      if (f == "translated") {
        vo.translated = true;
        continue;
      }
      const auto fam = verify::family_from_string(f);
      if (!fam) throw OptionsError("--families: unknown family '" + f + "' (" + verify::family_list() + ", translated)");
      vo.families.push_back(*fam);
    }
    vo.translated = vo.translated && std::find(o.families.begin(), o.families.end(), "translated") != o.families.end();
    // The translated run traces the other families on the moved scene: alone it traced nothing and
    // said OK (an outside sweep)
    const bool asked = std::find(o.families.begin(), o.families.end(), "translated") != o.families.end();
    if (asked && vo.families.empty())
      throw OptionsError("--families translated traces the other families on the moved scene: name one or more of " +
                         verify::family_list() + " too");
    if (asked && o.no_translated)
      throw OptionsError("--families translated and --no-translated contradict each other: give one");
    // It traces camera, random, surface, edge and vertex rays on the moved scene: named with only
    // other families it traced nothing, without a word (an outside sweep)
    const auto moved = [](verify::Family f) {
      using F = verify::Family;
      return f == F::camera || f == F::random || f == F::surface || f == F::edge || f == F::vertex;
    };
    if (asked && std::none_of(vo.families.begin(), vo.families.end(), moved))
      throw OptionsError("--families translated traces the camera, random, surface, edge and vertex families on the "
                         "moved scene: name one of them too");
  }
  // --offset places the translated run's scene: without that run it did nothing (an outside sweep)
  if (!o.offset.empty() && !vo.translated)
    throw OptionsError("--offset moves the translated run's scene, which is off here (--no-translated, or --families "
                       "without translated): leave it out");
  const Scene scene = load_scene_or_default(o.scene);
  if (!o.json.empty()) check_output_allowed(o.json, "JSON report");  // not over an input: refused now, not after
  // The translated run by default only where the moved scene is still a scene; asked for by name,
  // verify_scene refuses it with the reason.
  BackendOptions bo = o.backend_options;
  resolve_image_limit(bo, o.backend == "vulkan");
  const reference::GridOptions go = grid_options_for(bo, scene);
  const bool translated_asked = std::find(o.families.begin(), o.families.end(), "translated") != o.families.end();
  if (vo.translated && !translated_asked) {
    if (const std::string problem = verify::translated_problem(scene, vo.offset, &go); !problem.empty()) {
      std::printf("verify: the translated run is skipped: moved by (%g, %g, %g), %s\n", vo.offset.x, vo.offset.y,
                  vo.offset.z, problem.c_str());
      vo.translated = false;
    }
  }
  const bool exact = go.traversal == reference::Traversal::exact;
  // The exact traversal fails on them anyway: --strict did nothing there (an outside sweep)
  if (o.strict && o.backend_options.grid.traversal == reference::Traversal::exact)  // the command line's
    throw OptionsError("--strict fails the paper traversal on wrong answers and cracks, as the exact traversal always "
                       "is: with --traversal exact it does nothing (leave it out)");
  std::printf("verify: %s, %s backend, %s traversal, %s triangle test; %zu rays per family, seed %llu\n",
              scene.name.c_str(), o.backend.c_str(), exact ? "exact" : "paper",
              go.triangle_test == reference::GridOptions::TriangleTest::moller       ? "moller"
              : go.triangle_test == reference::GridOptions::TriangleTest::watertight ? "watertight"
                                                                                     : "auto",
              o.rays, (unsigned long long)o.seed);
  // The referee judges geometry: masks are left out of every tracer, and said to be
  const size_t keyed = size_t(std::count_if(scene.materials.begin(), scene.materials.end(),
                                             [](const Material& m) { return m.alpha_keyed(); }));
  if (keyed)
    std::printf("verify: %zu alpha-keyed material(s) traced without their masks: the referee judges geometry, so alpha "
                "keying is not verified here (gridrt diff and the tests hold it to the reference and Embree)\n",
                keyed);
  const std::string backend = o.backend;
  // The backend that ran: with --fallback-cpu and no usable device, the CPU reference, and the
  // report says so (it labelled those results "vulkan": an outside sweep)
  std::string ran = o.backend;
  const auto make = [&](const Scene& s) {
    std::unique_ptr<Tracer> t = make_backend(backend, bo, s);
    if (backend == "vulkan" && t->name().rfind("vulkan", 0) != 0) ran = "cpu (no usable Vulkan device: --fallback-cpu)";
    return t;
  };
  const std::vector<verify::FamilyResult> results = verify::verify_scene(scene, go, make, vo);
  if (ran != o.backend) std::printf("verify: the results below are the %s's, not the Vulkan port's\n", ran.c_str());
  std::fputs(verify::to_table(results).c_str(), stdout);
  // A family that judged no ray (none made, or all outside the domain: a tiny scene's cells
  // narrower than their coordinates' ulps) checked nothing, and the OK below must not hide it
  // (an outside sweep). The degenerate family is outside by design.
  std::vector<std::string> idle;
  for (const verify::FamilyResult& r : results)
    if (r.name != "degenerate" && r.rays == r.outside) idle.push_back(r.name);
  if (!idle.empty()) {
    std::string names;
    for (const std::string& n : idle) names += (names.empty() ? "" : ", ") + n;
    std::printf("verify: note: %zu famil%s judged no ray (none made, or all outside the domain): %s\n", idle.size(),
                idle.size() == 1 ? "y" : "ies", names.c_str());
  }
  size_t failures = 0;
  for (const verify::FamilyResult& r : results) failures += r.failures();
  if (!o.json.empty()) {
    nlohmann::json j{{"scene", scene.name},
                     {"backend", ran},
                     {"traversal", exact ? "exact" : "paper"},
                     {"rays_per_family", o.rays},
                     {"seed", o.seed},
                     {"families", verify::to_json(results)},
                     {"failures", failures}};
    write_file_atomically(o.json, "JSON report", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  }
  if (failures > 0 && (exact || o.strict)) {
    std::printf("verify: FAIL: %zu wrong answers, cracks or NaN t\n", failures);
    std::fflush(stdout);
    std::exit(3);
  }
  // A family asked for by name that judged no ray checked nothing the user asked for: an error, not
  // an OK with a note (an outside sweep: `--families edge,translated --offset 3e6,0,0` on a cube,
  // whose moved copy is a scene, judged no translated ray and said OK)
  std::string named_idle;
  for (const std::string& n : idle)
    if (std::find(o.families.begin(), o.families.end(), n) != o.families.end())
      named_idle += (named_idle.empty() ? "" : ", ") + n;
  if (!named_idle.empty()) {
    std::fflush(stdout);
    throw Error("verify: asked for by name, judged no ray (none made, or all outside the domain): " + named_idle +
                "; nothing of it was checked (another scene, --offset or --seed, or leave it out)");
  }
  std::printf("verify: %s%s\n", failures ? "differences reported (paper traversal)" : "OK: no wrong answer, no crack",
              !failures && !idle.empty() ? " (on the families that judged rays)" : "");
}

}  // namespace

void add_verify_command(CLI::App& app) {
  auto o = std::make_shared<VerifyCliOptions>();
  CLI::App* cmd = app.add_subcommand(
      "verify",
      "A tracer against Embree on adversarial ray families, every difference judged by an exact referee "
      "(exit 3 where the exact traversal is wrong or cracks)");
  add_scene_argument(cmd, o->scene);
  cmd->add_option("--backend,-b", o->backend, "cpu or vulkan");
  cmd->add_option("--families", o->families,
                  "Ray families (comma separated; default all): " + verify::family_list() + ", translated")
      ->delimiter(',');
  cmd->add_option("-n,--rays-per-family", o->rays, "Rays per family")->check(CLI::Range(size_t(1), size_t(10000000)));
  // (a negative or too large value wrapped around without a word: an outside sweep)
  cmd->add_option("--seed", o->seed, "Seed of the ray generation")->check(whole_number_u64());
  cmd->add_flag("--no-translated", o->no_translated, "Skip the run on the scene moved far from the origin");
  cmd->add_option("--offset", o->offset, "Offset X,Y,Z of the translated run (default 1e5,-5e4,7.5e4)")
      ->delimiter(',')->expected(3);
  add_json_option(cmd, o->json, "the results");
  cmd->add_flag("--strict", o->strict, "Fail on wrong answers and cracks with the paper traversal too");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o, cmd] {
    check_vulkan_options_apply(cmd, o->backend == "vulkan");
    check_traversal_options(cmd, o->backend_options, /*trace_grid_only=*/true);
    run_verify(*o);
  });
}

}  // namespace gridrt::app
