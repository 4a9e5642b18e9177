// policy.cpp: the ray sample and the work estimates of the trace-cost capacity policy (policy.h).
#include "gridrt/plan/policy.h"

#include <bit>
#include <algorithm>
#include <array>
#include <atomic>
#include <optional>

#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/transform.h"
#include "gridrt/common/shared/triangle.h"
#include "gridrt/common/invocations.h"
#include "gridrt/common/progress.h"

namespace gridrt::plan {

using namespace gridrt::shared;

void for_each_placed_triangle(const Scene& scene, size_t instance, float time, const GridParams& g,
                              const std::function<void(const PlacedTriangle&)>& f) {
  const Instance& inst = scene.instances[instance];
  const Mesh& mesh = scene.meshes[inst.mesh];
  const Affine m = to_affine(inst.transform_at(time));
  PlacedTriangle p;
  for (uint32_t t = 0; t < mesh.triangle_count(); ++t) {
    const glm::uvec3 tri = mesh.triangles[t];
    p.index = t;
    p.v0 = transform_point(m, mesh.positions[tri.x]);
    p.v1 = transform_point(m, mesh.positions[tri.y]);
    p.v2 = transform_point(m, mesh.positions[tri.z]);
    if (triangle_zero_area(p.v0, p.v1, p.v2)) continue;
    p.n = triangle_normal(p.v0, p.v1, p.v2);
    triangle_cell_range(g, p.v0, p.v1, p.v2, p.lo, p.hi);
    f(p);
  }
}

void for_each_triangle_cell(const Scene& scene, size_t instance, float time, const GridParams& g,
                            const std::function<void(uint32_t, size_t)>& f,
                            const std::function<void(const PlacedTriangle&)>& before) {
  for_each_placed_triangle(scene, instance, time, g, [&](const PlacedTriangle& p) {
    if (before) before(p);
    for (uint32_t z = p.lo.z; z <= p.hi.z; ++z)
      for (uint32_t y = p.lo.y; y <= p.hi.y; ++y)
        for (uint32_t x = p.lo.x; x <= p.hi.x; ++x)
          if (triangle_overlaps_cell(g, p.v0, p.v1, p.v2, p.n, {x, y, z}))
            f(p.index, (size_t(z) * g.cells.y + y) * g.cells.x + x);
  });
}

namespace {

// The compact grid that finds where the sample rays end: every cell's references in one list
// (CSR: cell c holds refs[first[c] .. first[c+1])), no capacity, so nothing is dropped; the exact
// DDA of shared/grid.h, the configured triangle test, alpha keying and the launch triangle
// excluded, as the reference's exact traversal with no saturated cell would find them.
class SampleCaster : public Tracer {
 public:
  SampleCaster(const GridParams& g, const GridOptions& o) : g_(g), o_(o) {}
  std::string name() const override { return "policy-sample"; }
  bool built() const override { return scene_ != nullptr; }
  void update_to(float) override {}

  void build_scene(const Scene& scene, float time) override {
    scene_ = &scene;
    offset_.clear();
    tris_.clear();
    for (const Instance& inst : scene.instances) {
      const Mesh& mesh = scene.meshes[inst.mesh];
      const Affine m = to_affine(inst.transform_at(time));
      offset_.push_back(uint32_t(tris_.size()));
      for (const glm::uvec3& t : mesh.triangles)
        tris_.push_back({transform_point(m, mesh.positions[t.x]), transform_point(m, mesh.positions[t.y]),
                         transform_point(m, mesh.positions[t.z])});
    }
    const size_t ncells = size_t(g_.cells.x) * g_.cells.y * g_.cells.z;
    // Two passes over the triangles' AABB range cells (at most the work bound's): a line on stderr
    // where they take over a second (large or overlapping triangles)
    Progress progress("grid: the policy's sample grid", 2 * std::max<uint64_t>(1, range_cells(scene, time, g_)));
    uint64_t tested = 0;
    const auto tick = [&](const PlacedTriangle& p) {
      tested += uint64_t(p.hi.x - p.lo.x + 1) * (p.hi.y - p.lo.y + 1) * (p.hi.z - p.lo.z + 1);
      if (tested >= 65536) {
        progress.advance(tested);
        tested = 0;
      }
    };
    first_.assign(ncells + 1, 0u);
    for (size_t i = 0; i < scene.instances.size(); ++i)
      for_each_triangle_cell(scene, i, time, g_, [&](uint32_t, size_t c) { ++first_[c + 1]; }, tick);
    for (size_t c = 0; c < ncells; ++c) first_[c + 1] += first_[c];
    refs_.assign(first_[ncells], kBlank);
    std::vector<uint32_t> fill(first_.begin(), first_.end() - 1);
    for (size_t i = 0; i < scene.instances.size(); ++i)
      for_each_triangle_cell(scene, i, time, g_,
                             [&](uint32_t t, size_t c) { refs_[fill[c]++] = ref_pack(uint32_t(i), t); }, tick);
    progress.finish();
  }

  const std::array<vec3, 3>& triangle(uint32_t instance, uint32_t t) const { return tris_[offset_[instance] + t]; }

  // Every ray, within the sample's work bound (trace_within); the rays past it are misses.
  void trace_closest(std::span<const Ray> rays, std::span<Hit> hits) override { trace_within(rays, hits); }

  // The rays in strided chunks (chunk k: rays k, k + K, k + 2K, ..., K chunks of about
  // kSampleChunk), chunk after chunk, until the triangle tests of a call pass kSampleTestBudget:
  // whatever the scene, a sample costs about that many tests at most (300,000 copies of one
  // triangle made every sample ray test them all: minutes before the grid was chosen, without a
  // word; an outside sweep). Any prefix of the chunks is spread over the whole ray list (the whole
  // image for a gather), and the prefix depends on the counts alone, not on the threads' timing.
  // Returns which rays were cast; the others' hits are misses.
  std::vector<uint8_t> trace_within(std::span<const Ray> rays, std::span<Hit> hits) {
    const size_t n = rays.size();
    std::vector<uint8_t> cast_flags(n, 0);
    Hit miss{};
    miss.t = sh_infinity();
    miss.instance = kNoInstance;
    std::fill(hits.begin(), hits.end(), miss);
    const size_t chunks = (n + kSampleChunk - 1) / kSampleChunk;
    uint64_t tests = 0;
    for (size_t k = 0; k < chunks && tests <= kSampleTestBudget; ++k) {
      const uint32_t count = uint32_t((n - k + chunks - 1) / chunks);  // rays k, k + chunks, ... below n
      std::atomic<uint64_t> chunk_tests{0};
      run_invocations(count, thread_count(o_), std::nullopt, [&](uint32_t j) {
        const size_t i = k + size_t(j) * chunks;
        uint64_t t = 0;
        hits[i] = cast(rays[i], t);
        cast_flags[i] = 1;
        chunk_tests.fetch_add(t, std::memory_order_relaxed);
      }, 16);
      tests += chunk_tests.load();
    }
    return cast_flags;
  }

 private:
  // Whether the alpha mask keeps the hit at barycentrics (u, v) of triangle t of instance i.
  bool alpha_keeps_hit(uint32_t i, uint32_t t, float u, float v) const {
    if (!o_.alpha_keying) return true;
    const Mesh& mesh = scene_->meshes[scene_->instances[i].mesh];
    if (mesh.materials.empty() || mesh.uvs.empty()) return true;
    const Material& mat = scene_->materials[mesh.materials[t]];
    if (!mat.alpha_keyed()) return true;
    const Texture& tex = scene_->textures[size_t(mat.alpha_texture)];
    const glm::uvec3 idx = mesh.triangles[t];
    const vec2 uv = interpolate_uv(mesh.uvs[idx.x], mesh.uvs[idx.y], mesh.uvs[idx.z], u, v);
    const uvec2 xy = alpha_texel_coords(uv, tex.width, tex.height);
    return alpha_keeps(tex.rgba[4 * (size_t(xy.y) * tex.width + xy.x) + 3]);
  }

  Hit cast(const Ray& given, uint64_t& tests) const {
    Ray ray = given;
    ray.dir = traced_direction(given.dir);  // as scene_trace walks it
    Hit h{};
    h.t = sh_infinity();
    h.instance = kNoInstance;
    RaySetup rs;
    if (!ray_valid(ray.org, ray.dir, ray.tmin, ray.tmax) || !ray_setup(g_, ray.org, ray.dir, ray.tmin, ray.tmax, rs))
      return h;
    const vec3 inv = dda_inverse_direction(ray.dir);
    DdaWalk w = dda_walk_begin(g_, ray.org, ray.dir, rs.t_start);
    float best = sh_infinity();
    uint best_ref = kBlank;
    for (uint k = 0u; k < g_.max_segments; ++k) {
      dda_walk_exits(g_, ray.org, ray.dir, inv, 0u, w);
      const float t_exit = w.t_exit;
      const size_t c = (size_t(w.cell.z) * g_.cells.y + w.cell.y) * g_.cells.x + w.cell.x;
      for (uint32_t s = first_[c]; s < first_[c + 1]; ++s) {
        const uint ref = refs_[s];
        if (o_.exclude_launch_ref && ref == ray.launch_ref) continue;
        const uint32_t i = ref_instance(ref), t = ref_triangle(ref);
        const std::array<vec3, 3>& v = tris_[offset_[i] + t];
        TriangleTest r;
        const float stol = ray.launch_ref != kNoRef ? surface_rule_tol(ray.org) : -1.0f;  // the surface rule
        ++tests;
        if (triangle_test(g_.triangle_test, ray.org, ray.dir, v[0], v[1], v[2], rs.t_lo, ray.tmax, best, stol, r) !=
            kTestAccepted)
          continue;
        const float th = moller_trumbore_t(r);
        const vec2 bc = triangle_barycentrics(g_.triangle_test, ray.org, ray.dir, watertight_ray(ray.dir), v[0], v[1], v[2]);
        if (!alpha_keeps_hit(i, t, bc.x, bc.y)) continue;
        if (!(th < best || (th == best && ref < best_ref))) continue;
        best = th;
        best_ref = ref;
        h.u = bc.x;
        h.v = bc.y;
        h.flags = r.det < 0.0f ? kHitBackFace : 0u;
      }
      if (best_ref != kBlank && best <= t_exit) break;
      if (t_exit >= rs.t_end || !dda_walk_next(g_, ray.org, ray.dir, inv, w)) break;
    }
    if (best_ref == kBlank) {
      h.u = h.v = 0.0f;
      h.flags = 0u;
      return h;
    }
    h.t = best;
    h.instance = ref_instance(best_ref);
    h.triangle = ref_triangle(best_ref);
    return h;
  }

  GridParams g_;
  GridOptions o_;
  const Scene* scene_ = nullptr;
  std::vector<uint32_t> offset_;              // per instance: its first triangle in tris_
  std::vector<std::array<vec3, 3>> tris_;     // world-space vertices at the build's time
  std::vector<uint32_t> first_, refs_;        // CSR cell lists
};

}  // namespace

WorkSample work_sample(const Scene& scene, float time, const GridParams& base, const GridOptions& o) {
  GridParams g = base;
  g.traversal = kTraversalExact;
  SampleCaster caster(g, o);
  // Its own step: the scene and time were checked by the grid's build (Tracer::build), once
  caster.build_scene(scene, time);
  const Camera camera = scene.frame_camera();
  const uint32_t w = std::max(1u, o.work_sample_width), h = std::max(1u, o.work_sample_height);
  const GatherBuffer gather = make_gather(scene, caster, camera, w, h, time);
  WorkSample s;
  for (uint32_t frame = 0; frame < std::max(1u, o.work_sample_frames) && s.rays.size() < o.work_sample_rays; ++frame)
    for (const Ray& r : bounce_rays(scene, gather, frame))
      if (!is_unused(r)) s.rays.push_back(r);
  if (s.rays.empty()) {
    // No glossy material: the grid traces camera rays (the CPU render's primary rays)
    s.bounce = false;
    s.rays = camera_rays(camera, w, h);
  }
  std::vector<Hit> hits(s.rays.size());
  const std::vector<uint8_t> cast = caster.trace_within(s.rays, hits);
  // Only the rays cast within the work bound (all of them but in scenes where a ray tests
  // thousands of triangles)
  size_t kept = 0;
  for (size_t i = 0; i < s.rays.size(); ++i)
    if (cast[i]) {
      s.rays[kept] = s.rays[i];
      hits[kept] = hits[i];
      ++kept;
    }
  s.rays.resize(kept);
  hits.resize(kept);
  s.t_end.resize(hits.size());
  s.hit.resize(hits.size());
  s.launch.resize(hits.size());
  for (size_t i = 0; i < hits.size(); ++i) {
    s.t_end[i] = is_miss(hits[i]) ? sh_infinity() : hits[i].t;
    if (!is_miss(hits[i])) s.hit[i] = caster.triangle(hits[i].instance, hits[i].triangle);
    const uint ref = s.rays[i].launch_ref;
    if (ref != kNoRef && ref_instance(ref) < scene.instances.size())
      s.launch[i] = caster.triangle(ref_instance(ref), ref_triangle(ref));
  }
  return s;
}

bool for_each_visit(const GridParams& g, const Ray& given,
                    const std::function<bool(uvec3 cell, uint k, uint last, float t_report, bool tested)>& f,
                    const std::function<uint32_t(uvec3 cell)>& skip) {
  Ray ray = given;
  ray.dir = traced_direction(given.dir);  // as scene_trace walks it
  RaySetup rs;
  if (!ray_valid(ray.org, ray.dir, ray.tmin, ray.tmax) || !ray_setup(g, ray.org, ray.dir, ray.tmin, ray.tmax, rs))
    return false;
  if (g.traversal == kTraversalExact) {
    // trace_exact's DDA
    const vec3 inv = dda_inverse_direction(ray.dir);
    DdaWalk w = dda_walk_begin(g, ray.org, ray.dir, rs.t_start);
    for (uint k = 0u; k < g.max_segments; ++k) {
      const uint d = skip ? skip(w.cell) : 0u;
      dda_walk_exits(g, ray.org, ray.dir, inv, d > 0u ? d - 1u : 0u, w);
      if (!f(w.cell, k, k, w.t_exit, d == 0u) || w.t_exit >= rs.t_end || !dda_walk_next(g, ray.org, ray.dir, inv, w))
        break;
    }
    return true;
  }
  // trace_paper's segments: samples at midpoints, repeats merged (or skipped, or re-tested)
  uvec3 prev = uvec3(0xFFFFFFFFu);
  uint k = 0u;
  while (k < g.max_segments) {
    if (segment_begin(rs, k) >= rs.t_end) break;
    const uvec3 cell = segment_cell(g, ray.org, ray.dir, rs, k);
    if (cell == prev && g.repeats == kRepeatSkip) {
      if (!f(cell, k, k, segment_end(rs, k), false)) break;
      k += 1u;
      continue;
    }
    prev = cell;
    const uint last = segment_visit_last(g, ray.org, ray.dir, rs, k, cell);
    if (!f(cell, k, last, segment_end(rs, last), true)) break;
    k = last + 1u;
  }
  return true;
}

SkipDistances::SkipDistances(const GridParams& g, const TrialCounts& counts, std::span<const uint32_t> box_words)
    : g_(g), table_(skip_table_words(g), 0u), boxes_(box_words.begin(), box_words.end()) {
  // The summed-volume table (1-based: index 0 along an axis is "before the grid"), as the build's
  // three passes make it, in one sweep: running sums along x, then y, then z
  const uvec3 n = g.cells;
  for (uint32_t z = 0; z < n.z; ++z)
    for (uint32_t y = 0; y < n.y; ++y) {
      uint32_t sum = 0u;
      for (uint32_t x = 0; x < n.x; ++x) {
        sum += counts.fixed[(size_t(z) * n.y + y) * n.x + x] > 0u ? 1u : 0u;
        table_[skip_table_index(g, uvec3(x, y, z) + 1u)] = sum;
      }
    }
  for (uint32_t axis = 1; axis < 3; ++axis)
    for (uint32_t z = 1; z <= n.z; ++z)
      for (uint32_t y = 1; y <= n.y; ++y)
        for (uint32_t x = 1; x <= n.x; ++x) {
          const uvec3 c(x, y, z);
          uvec3 prev = c;
          prev[axis] -= 1u;
          if (prev[axis] > 0u) table_[skip_table_index(g, c)] += table_[skip_table_index(g, prev)];
        }
}

uint32_t SkipDistances::box_mask(const Ray& ray, const RaySetup& rs) const {
  // The dynamic boxes the ray's walk can reach (the trace's skip_box_mask)
  const vec3 dir = traced_direction(ray.dir);  // as scene_trace walks it
  const vec3 inv = dda_inverse_direction(dir);
  const uvec3 k0 = dda_walk_begin(g_, ray.org, dir, rs.t_start).cell;
  uint32_t mask = 0u;
  const uint32_t boxes = boxes_.empty() ? 0u : boxes_[0];
  for (uint32_t b = 0u; b < boxes; ++b) {
    const uint32_t w = skip_box_word(b);
    if (skip_box_reached(g_, ray.org, dir, inv, k0, rs.t_end, uvec3(boxes_[w], boxes_[w + 1], boxes_[w + 2]),
                         uvec3(boxes_[w + 4], boxes_[w + 5], boxes_[w + 6])))
      mask |= 1u << b;
  }
  return mask;
}

uint32_t SkipDistances::operator()(uvec3 c, uint32_t mask) const {
  // The static distance, lowered to the distance to every dynamic box the walk can reach (the
  // trace's skip_distance)
  uint32_t d = skip_static_distance(g_, table_, c);
  for (uint32_t m = mask; m != 0u && d > 0u; m &= m - 1u) {
    const uint32_t w = skip_box_word(uint32_t(std::countr_zero(m)));
    d = std::min(d, skip_box_distance(c, uvec3(boxes_[w], boxes_[w + 1], boxes_[w + 2]),
                                      uvec3(boxes_[w + 4], boxes_[w + 5], boxes_[w + 6])));
  }
  return d;
}

WorkEstimate estimate_work(const GridParams& g, const TrialCounts& counts, const WorkSample& sample,
                           std::span<const uint32_t> skip_boxes) {
  WorkEstimate w;
  w.rays = sample.rays.size();
  if (w.rays == 0) return w;
  const bool exact = g.traversal == kTraversalExact;
  std::optional<SkipDistances> skip_field;
  std::function<uint32_t(uvec3)> skip;
  uint32_t box_mask = 0u;  // the ray's (SkipDistances::box_mask)
  if (exact && (g.flags & kGridSkipEmpty) != 0u) {
    skip_field.emplace(g, counts, skip_boxes);
    skip = [&](uvec3 c) { return (*skip_field)(c, box_mask); };
  }
  const bool gap_fill = !exact && (g.flags & kGridGapFill) != 0u;
  // With the spill list a saturated cell's dropped references are tested too (test_spilled): no
  // reference is lost, and no gap-fill runs
  const bool spill = (g.flags & kGridSpill) != 0u;
  uint64_t cells = 0, tests = 0, at_risk = 0, spilled = 0;
  double lost = 0.0, skipped = 0.0;
  for (size_t i = 0; i < sample.rays.size(); ++i) {
    const Ray& ray = sample.rays[i];
    const float t_hit = sample.t_end[i];
    RaySetup rs;
    const bool meets = ray_setup(g, ray.org, ray.dir, ray.tmin, ray.tmax, rs);
    if (skip_field && meets) box_mask = skip_field->box_mask(ray, rs);
    // The hit triangle W: the cells the build offers it (its padded range, the cell test)
    const std::array<vec3, 3>& w_tri = sample.hit[i];
    const vec3 n = triangle_normal(w_tri[0], w_tri[1], w_tri[2]);
    uvec3 lo = uvec3(1u), hi = uvec3(0u);
    if (sh_finite(t_hit) && !triangle_zero_area(w_tri[0], w_tri[1], w_tri[2])) triangle_cell_range(g, w_tri[0], w_tri[1], w_tri[2], lo, hi);
    // The launch triangle: the trace skips it uncounted where a visited cell holds it
    const std::array<vec3, 3>& l_tri = sample.launch[i];
    const vec3 ln = triangle_normal(l_tri[0], l_tri[1], l_tri[2]);
    uvec3 llo = uvec3(1u), lhi = uvec3(0u);
    if ((g.flags & kGridExcludeLaunchRef) != 0u && !triangle_zero_area(l_tri[0], l_tri[1], l_tri[2]))
      triangle_cell_range(g, l_tri[0], l_tri[1], l_tri[2], llo, lhi);
    bool risk = false, voxel = false, offered = false, past = false;
    double missed = 1.0;  // the probability that no visit so far kept W with a window covering t_hit
    double lost_here = -1.0;  // set where the walk ends with a loss
    for_each_visit(g, ray, [&](uvec3 cell, uint k, uint last, float t_report, bool tested) {
      const bool reach = exact ? t_hit <= t_report : t_hit < t_report;  // the hit lies before the report bound
      if (!tested) {
        cells += exact ? 1u : 0u;  // a skip step is a visit of the exact trace; the paper's skipped repeat is none
        return !(reach && missed == 0.0);
      }
      const uint32_t c = counts.now(cell);
      cells += 1;
      tests += spill ? c : std::min(c, g.capacity);
      if (c > 0u && all(greaterThanEqual(cell, llo)) && all(lessThanEqual(cell, lhi)) &&
          triangle_overlaps_cell(g, l_tri[0], l_tri[1], l_tri[2], ln, cell))
        tests -= 1;
      const bool saturated = c > g.capacity;
      if (saturated) {
        risk = true;
        spilled += c - g.capacity;
      }
      // W offered to this cell and tested against a window covering t_hit: kept unless dropped
      const float t_lo = exact ? rs.t_lo : max(rs.t_lo, segment_elongated_begin(g, rs, k));
      const float t_hi = exact ? ray.tmax : min(ray.tmax, segment_elongated_end(g, rs, last));
      const bool covers = all(greaterThanEqual(cell, lo)) && all(lessThanEqual(cell, hi)) && t_lo < t_hit &&
                          t_hit < t_hi && triangle_overlaps_cell(g, w_tri[0], w_tri[1], w_tri[2], n, cell);
      if (covers) {
        offered = true;
        missed *= saturated && !spill ? double(c - g.capacity) / double(c) : 0.0;
      }
      // Reported here once found; past the hit, a visit that cannot find W ends the ray (another
      // triangle, or nothing)
      if (reach && missed == 0.0) return false;
      if (past && !covers) {
        lost_here = missed;
        return false;
      }
      past = past || reach;
      // Gap-fill: a saturated cell passed beyond the launch surface ends the ray with a voxel
      if (saturated && gap_fill) {
        const float t_mid = segment_t(rs, float(k + last + 1u) * 0.5f);
        vec2 values;
        if (gap_fill_left_surface(point_at(ray.org, ray.dir, t_mid), ray.org, ray.launch_normal, g.gap_fill_r2,
                                  values) &&
            t_mid > rs.t_lo && t_mid < ray.tmax) {
          voxel = !past;
          lost_here = past ? missed : 1.0;
          return false;
        }
      }
      return true;
    }, skip);
    at_risk += risk;
    if (lost_here >= 0.0) lost += lost_here;
    else if (sh_finite(t_hit)) lost += missed;
    if (!voxel && sh_finite(t_hit) && !offered) skipped += 1.0;
  }
  const double n = double(w.rays);
  w.cells = double(cells) / n;
  w.tests = double(tests) / n;
  w.at_risk = double(at_risk) / n;
  w.lost = lost / n;
  w.skipped = skipped / n;
  w.spilled = double(spilled) / n;
  return w;
}

float cell_visit_cost(const GridOptions& o) {
  if (o.cell_visit_cost) return *o.cell_visit_cost;
  return o.traversal == Traversal::exact ? kExactCellVisitCost : kPaperCellVisitCost;
}

double work_cost(const WorkEstimate& w, const GridOptions& o) {
  return w.tests + double(cell_visit_cost(o)) * w.cells + double(o.saturation_cost) * w.lost;
}

WorkEstimate measured_work(std::span<const Ray> rays, std::span<const Hit> hits) {
  WorkEstimate w;
  uint64_t cells = 0, tests = 0, gap = 0;
  for (size_t i = 0; i < rays.size(); ++i) {
    if (is_unused(rays[i])) continue;
    w.rays += 1;
    cells += hits[i].cells;
    tests += hits[i].tests;
    gap += (hits[i].flags & kHitGapFill) != 0u;
  }
  if (w.rays == 0) return w;
  w.cells = double(cells) / double(w.rays);
  w.tests = double(tests) / double(w.rays);
  w.lost = double(gap) / double(w.rays);
  return w;
}

}  // namespace gridrt::plan
