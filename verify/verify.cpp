#include "verify/verify.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <functional>
#include <mutex>
#include <sstream>
#include <thread>

#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/progress.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/reference/compare.h"

namespace gridrt::verify {

namespace sh = gridrt::shared;

namespace {

void parallel_for(size_t n, unsigned threads, const std::function<void(size_t)>& body) {
  const unsigned t = threads ? threads : std::max(1u, std::thread::hardware_concurrency());
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t i; (i = next.fetch_add(1)) < n;) body(i);
  };
  std::vector<std::thread> pool;
  for (unsigned k = 1; k < t; ++k) pool.emplace_back(work);
  work();
  for (std::thread& th : pool) th.join();
}

// Whether t is well-conditioned: kappa = (|org| + max |v_i| + t |dir|) / (t |dir| |cos|) <= kWellConditioned,
// with cos the angle between the ray and the plane. Rounding every input coordinate by a relative u
// moves the exact t by at most about kappa u t (the plane moves by at most the vertices' rounding
// at the hit point, the origin's and the direction's rounding likewise): kappa is the problem's
// condition number, whatever the triangle's shape.
bool well_conditioned(const Ray& r, const std::array<glm::vec3, 3>& t, double exact_t) {
  return condition_number(r, t, exact_t) <= kWellConditioned;
}

}  // namespace

FamilyResult verify_rays(const std::string& name, const FamilyRays& fr, Tracer& tracer, const Topology& topo,
                         const reference::GridData& grid, EmbreeTracer& embree, const VerifyOptions& o) {
  FamilyResult res;
  res.name = name;
  res.rays = fr.rays.size();
  res.attempts = fr.attempts;
  std::vector<Hit> got(fr.rays.size()), want(fr.rays.size());
  tracer.trace(fr.rays, got);
  const uint64_t rejected_before = embree.rejected_rays();
  embree.trace(fr.rays, want);
  res.embree_rejected = embree.rejected_rays() - rejected_before;
  Referee referee(grid, topo, embree);
  std::vector<Judgement> judged(fr.rays.size());
  std::vector<uint32_t> ulps(fr.rays.size(), UINT32_MAX), ulps_e(fr.rays.size(), UINT32_MAX);
  // A line on stderr past a second: the exact referee takes up to about a second a ray where
  // thousands of triangles meet at a point (a cone of 2,000 slivers: minutes without a word, an
  // outside sweep)
  Progress progress("verify: " + name + " rays judged exactly", fr.rays.size());
  parallel_for(fr.rays.size(), o.threads, [&](size_t i) {
    const Ray& r = fr.rays[i];
    judged[i] = referee.judge(r, got[i], want[i], fr.aimed[i]);
    progress.advance();
    // t against the exact t of the same triangle (well-conditioned exact hits)
    const auto ulps_of = [&](const Hit& h) -> uint32_t {
      if (is_miss(h) || (h.flags & (sh::kHitGapFill | sh::kHitRejected))) return UINT32_MAX;
      const size_t k = topo.index_of(sh::ref_pack(h.instance, h.triangle));
      if (k == SIZE_MAX) return UINT32_MAX;
      const ExactTest e = referee.test(r, sh::ref_pack(h.instance, h.triangle));
      if (!e.hit || !well_conditioned(r, topo.tri[k], e.t)) return UINT32_MAX;
      return reference::ulp_distance(h.t, exact_t_float(e));
    };
    ulps[i] = ulps_of(got[i]);
    ulps_e[i] = ulps_of(want[i]);
  });
  progress.finish();
  double sum = 0.0;
  for (size_t i = 0; i < fr.rays.size(); ++i) {
    const Ray& r = fr.rays[i];
    if (sh::ray_domain(r.org, r.dir, r.tmin, r.tmax) != sh::kDomainOk) ++res.outside;
    if (!is_miss(got[i]) && std::isnan(got[i].t)) ++res.nan_t;
    res.verdicts[size_t(judged[i].verdict)] += 1;
    if (ulps[i] != UINT32_MAX) {
      ++res.t_checked;
      sum += ulps[i];
      res.max_ulps = std::max(res.max_ulps, ulps[i]);
    }
    if (ulps_e[i] != UINT32_MAX) res.max_ulps_embree = std::max(res.max_ulps_embree, ulps_e[i]);
  }
  // Examples: the failures first, then the other differences (near, Embree wrong)
  for (int pass = 0; pass < 2; ++pass)
    for (size_t i = 0; i < fr.rays.size() && res.examples.size() < o.examples; ++i) {
    const Ray& r = fr.rays[i];
    const Verdict v = judged[i].verdict;
    const bool failure = v == Verdict::grid_wrong || v == Verdict::crack;
    if (v != Verdict::agree && v != Verdict::tie && failure == (pass == 0)) {
      Example ex;
      ex.ray = i;
      ex.verdict = judged[i].verdict;
      ex.why = judged[i].why;
      ex.ray_hex = reference::hex_ray(r);
      ex.got_hex = reference::hex_hit(got[i]);
      ex.want_hex = reference::hex_hit(want[i]);
      res.examples.push_back(ex);
    }
  }
  res.mean_ulps = res.t_checked ? sum / double(res.t_checked) : 0.0;
  (void)grid;
  return res;
}

FamilyResult verify_family(Family f, const Scene& scene, Tracer& tracer, const reference::GridData& grid,
                           const Topology& topo, EmbreeTracer& embree, const VerifyOptions& o) {
  const FamilyRays fr = make_family(f, scene, grid, topo, embree, o.family);
  return verify_rays(to_string(f), fr, tracer, topo, grid, embree, o);
}

namespace {

FamilyResult merge(const std::string& name, const std::vector<FamilyResult>& parts) {
  FamilyResult m;
  m.name = name;
  double sum = 0.0;
  for (const FamilyResult& p : parts) {
    m.rays += p.rays;
    m.outside += p.outside;
    m.embree_rejected += p.embree_rejected;
    for (size_t v = 0; v < kVerdicts; ++v) m.verdicts[v] += p.verdicts[v];
    m.attempts += p.attempts;
    m.t_checked += p.t_checked;
    sum += p.mean_ulps * double(p.t_checked);
    m.max_ulps = std::max(m.max_ulps, p.max_ulps);
    m.max_ulps_embree = std::max(m.max_ulps_embree, p.max_ulps_embree);
    m.nan_t += p.nan_t;
    for (const Example& e : p.examples)
      if (m.examples.size() < 3) m.examples.push_back(e);
  }
  m.mean_ulps = m.t_checked ? sum / double(m.t_checked) : 0.0;
  return m;
}

std::vector<FamilyResult> run_all(const Scene& scene, const reference::GridOptions& grid_options,
                                  const TracerFactory& make, const VerifyOptions& o,
                                  const std::vector<Family>& families) {
  reference::ReferenceGridTracer ref(grid_options);
  ref.build(scene, 0.0f);
  std::unique_ptr<Tracer> tracer = make(scene);
  tracer->build(scene, 0.0f);
  EmbreeTracer embree(o.threads);
  embree.build(scene, 0.0f);
  const Topology topo = make_topology(ref.data());
  std::vector<FamilyResult> out;
  for (Family f : families) out.push_back(verify_family(f, scene, *tracer, ref.data(), topo, embree, o));
  return out;
}

}  // namespace

std::vector<FamilyResult> verify_scene(const Scene& scene_in, const reference::GridOptions& grid_options,
                                       const TracerFactory& make, const VerifyOptions& o) {
  const Scene scene = without_alpha(scene_in);
  if (o.translated)  // before any family runs, not after minutes of them
    if (const std::string problem = translated_problem(scene, o.offset, &grid_options); !problem.empty())
    {
      char moved[96];
      std::snprintf(moved, sizeof moved, "(%g, %g, %g)", double(o.offset.x), double(o.offset.y), double(o.offset.z));
      throw Error("verify: the translated run: moved by " + std::string(moved) + ", " + problem +
                  " (the scene is too small for a float's step there: a smaller --offset, or --no-translated)");
    }
  std::vector<FamilyResult> out = run_all(scene, grid_options, make, o, o.families);
  if (o.translated) {
    const Scene moved = translated(scene, o.offset);
    std::vector<Family> fams;
    for (Family f : {Family::camera, Family::random, Family::surface, Family::edge, Family::vertex})
      if (std::find(o.families.begin(), o.families.end(), f) != o.families.end()) fams.push_back(f);
    if (!fams.empty()) out.push_back(merge("translated", run_all(moved, grid_options, make, o, fams)));
  }
  return out;
}

std::string to_table(const std::vector<FamilyResult>& results) {
  std::ostringstream os;
  char line[512];
  std::snprintf(line, sizeof line, "%-11s %7s %7s %7s %6s %6s %8s %8s %6s %7s %7s %9s %9s\n", "family", "rays", "agree",
                "tie", "near", "crack", "grid_wr", "embr_wr", "unres", "outside", "emb_rej", "max_ulp_t", "embree_ulp");
  os << line;
  FamilyResult all = merge("total", results);
  std::vector<FamilyResult> rows = results;
  rows.push_back(all);
  for (const FamilyResult& r : rows) {
    std::snprintf(line, sizeof line, "%-11s %7zu %7zu %7zu %6zu %6zu %8zu %8zu %6zu %7zu %7zu %9u %9u\n", r.name.c_str(),
                  r.rays, r.count(Verdict::agree), r.count(Verdict::tie), r.count(Verdict::near),
                  r.count(Verdict::crack), r.count(Verdict::grid_wrong), r.count(Verdict::embree_wrong),
                  r.count(Verdict::unresolved), r.outside,
                  r.embree_rejected, r.max_ulps, r.max_ulps_embree);
    os << line;
  }
  for (const FamilyResult& r : results)
    for (const Example& e : r.examples)
      os << "  " << r.name << " ray " << e.ray << ": " << to_string(e.verdict) << " (" << e.why << ")\n    ray  "
         << e.ray_hex << "\n    grid   " << e.got_hex << "\n    embree " << e.want_hex << "\n";
  return os.str();
}

nlohmann::json to_json(const std::vector<FamilyResult>& results) {
  nlohmann::json j = nlohmann::json::array();
  for (const FamilyResult& r : results) {
    nlohmann::json f{{"family", r.name},       {"rays", r.rays},
                     {"outside_domain", r.outside}, {"embree_rejected", r.embree_rejected},
                     {"attempts", r.attempts}, {"t_checked", r.t_checked},
                     {"max_ulps_t", r.max_ulps}, {"mean_ulps_t", r.mean_ulps},
                     {"max_ulps_t_embree", r.max_ulps_embree}, {"nan_t", r.nan_t}};
    for (size_t v = 0; v < kVerdicts; ++v) f[to_string(Verdict(v))] = r.verdicts[v];
    nlohmann::json ex = nlohmann::json::array();
    for (const Example& e : r.examples)
      ex.push_back({{"ray", e.ray}, {"verdict", to_string(e.verdict)}, {"why", e.why}, {"ray_bits", e.ray_hex},
                    {"grid", e.got_hex}, {"embree", e.want_hex}});
    f["examples"] = ex;
    j.push_back(f);
  }
  return j;
}

}  // namespace gridrt::verify
