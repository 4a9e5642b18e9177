// gridrt sweep: what accuracy costs in time. For each scene and each configuration of a
// grid over the knobs, on the glossy-bounce rays of the paper's frame (a gather buffer made by
// primary rays through the exact grid, as the other grid verbs do): accuracy against the Embree
// oracle and time (build, update, trace; rays/s; memory). Writes per scene a CSV file, a Markdown
// table and a PNG plot of agreement against trace time with the Pareto front marked.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <unistd.h>
#include <fstream>
#include <map>
#include <sstream>
#include <thread>

#include "apps/backends.h"
#include "gridrt/common/util.h"
#include "apps/commands.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/image_io.h"
#include "gridrt/common/plot.h"
#include "gridrt/reference/compare.h"
#include "gridrt/reference/grid.h"
#include "gridrt/plan/policy.h"
#ifdef GRIDRT_HAVE_EMBREE
#include "verify/rays.h"
#  include "gridrt/common/embree/embree_tracer.h"
#endif
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/grid.h"
#endif

namespace gridrt::app {
namespace {

using reference::GridOptions;

// The knobs swept, each a list of values as typed (validated before any work).
struct SweepOptions {
  std::vector<std::string> scenes;
  std::vector<std::string> backends{"cpu"};
  uint32_t width = 240, height = 135;
  std::string out = "sweep";
  uint32_t repeat = 3;  // trace timings: the median of this many runs
  std::vector<std::string> traversal{"paper", "exact"};
  std::vector<std::string> triangle_test{"moller", "watertight"};
  std::vector<std::string> capacity{"auto", "no-saturation", "percentile"};
  std::vector<std::string> enlargement{"1.25"};
  std::vector<std::string> elongation{"0.5"};
  std::vector<std::string> padding{"auto"};
  std::vector<std::string> repeats{"merge"};
  std::vector<uint32_t> work_sample;
  std::vector<std::string> gap_fill{"on"};
  std::vector<std::string> spill{"auto"};
  std::vector<std::string> launch{"exclude"};
  std::vector<std::string> max_dim{"4096"};
  std::string rays = "auto";  // auto (glossy, else diffuse), glossy, primary, diffuse, random, a family
  BackendOptions backend_options;
};

// One point of the grid of knobs.
struct Config {
  std::string traversal, triangle_test, capacity, launch, gap_fill, spill, repeats = "merge";
  float enlargement = 1.25f, elongation = 0.5f;
  std::optional<float> padding;  // none: automatic
  uint32_t max_dim = 4096;
  bool operator==(const Config&) const = default;
  std::string padding_text() const {
    if (!padding) return "auto";
    std::ostringstream s;
    s << *padding;
    return s.str();
  }
  std::string label() const {
    std::ostringstream s;
    s << traversal << " " << triangle_test << " cap=" << capacity << " enl=" << enlargement << " pad=" << padding_text();
    if (traversal == "paper") s << " elo=" << elongation << " rev=" << repeats << " gap=" << gap_fill;
    s << " spill=" << spill << " self=" << launch << " dim=" << max_dim;
    return s.str();
  }
};

std::string gnum(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", v);
  return b;
}

// A knob's value: a decimal number in [lo, hi] (read in double precision: 1e-40, below a float's
// normal range, is a number in [0, 16], stored as the float it rounds to). A bad value is a bad
// command line (exit 2).
float parse_float(const std::string& knob, const std::string& v, float lo, float hi) {
  char* end = nullptr;
  const double f = std::strtod(v.c_str(), &end);  // an underflow is 0 or subnormal, an overflow +-HUGE_VAL
  if (v.empty() || std::isspace(static_cast<unsigned char>(v[0])) || *end != '\0' || !(f >= lo && f <= hi))
    throw CLI::ValidationError("--" + knob, "'" + v + "' is not a number in [" + gnum(lo) + ", " + gnum(hi) + "]");
  return float(f);
}

void check_member(const std::string& knob, const std::vector<std::string>& values,
                  const std::vector<std::string>& allowed) {
  if (values.empty()) throw CLI::ValidationError("--" + knob, "the list is empty");
  for (const std::string& v : values)
    if (std::find(allowed.begin(), allowed.end(), v) == allowed.end()) {
      std::string known;
      for (const std::string& a : allowed) known += (known.empty() ? "" : ", ") + a;
      throw CLI::ValidationError("--" + knob, "unknown value '" + v + "' (known: " + known + ")");
    }
}

// The most configurations one sweep runs (the product of its knob lists' lengths).
constexpr uint64_t kMaxSweepConfigurations = 10000;

// Every configuration of the grid of knobs; exact traversal ignores elongation and gap-fill, so
// it takes only their first values (no duplicate rows); a value given twice in a list counts once.
std::vector<Config> configurations(const SweepOptions& o) {
  check_member("traversal", o.traversal, {"paper", "exact"});
  check_member("triangle-test", o.triangle_test, {"moller", "watertight"});
  check_member("gap-fill", o.gap_fill, {"on", "off"});
  check_member("spill", o.spill, {"auto", "on", "off"});
  check_member("self-hit", o.launch, {"exclude", "keep"});
  check_member("revisit", o.repeats, {"merge", "skip", "retest"});
  for (const auto* list : {&o.capacity, &o.enlargement, &o.elongation, &o.padding, &o.max_dim})
    if (list->empty()) throw CLI::ValidationError("sweep", "a knob's list is empty");
  for (const std::string& c : o.capacity)
    if (c != "auto" && c != "trace-cost" && c != "no-saturation" && c != "percentile" &&
        (c.empty() || c.find_first_not_of("0123456789") != std::string::npos || !(std::strtod(c.c_str(), nullptr) >= 1.0 && std::strtod(c.c_str(), nullptr) <= 1024.0)))
      throw CLI::ValidationError("--capacity", "'" + c + "' is neither a number of slots in [1, 1024] nor auto, "
                                               "trace-cost, no-saturation or percentile (as for the other verbs)");
  // The product of the lists' lengths, bounded before anything is made (each configuration builds
  // a grid and traces the rays: a sweep of millions would only exhaust memory and time)
  uint64_t product = 1;
  for (const size_t n : {o.traversal.size(), o.triangle_test.size(), o.capacity.size(), o.enlargement.size(),
                         o.padding.size(), o.elongation.size(), o.repeats.size(), o.gap_fill.size(), o.spill.size(),
                         o.launch.size(), o.max_dim.size()})
    product = std::min<uint64_t>(product * uint64_t(n), uint64_t(1) << 40);
  if (product > kMaxSweepConfigurations)
    throw CLI::ValidationError("sweep", "the knob lists make " + std::to_string(product) +
                                            " configurations; at most " + std::to_string(kMaxSweepConfigurations) +
                                            " a sweep (each builds a grid and traces every ray): shorten the lists");
  // The paper traversal's knobs with the exact traversal alone: its configurations take the first
  // value and the others were dropped without a word (an outside sweep)
  if (std::find(o.traversal.begin(), o.traversal.end(), "paper") == o.traversal.end())
    for (const auto& [name, n] : {std::pair{"--elongation", o.elongation.size()}, std::pair{"--revisit", o.repeats.size()},
                                  std::pair{"--gap-fill", o.gap_fill.size()}})
      if (n > 1)
        throw CLI::ValidationError(name, "is a knob of the paper traversal's segments and gap-fill; with --traversal "
                                         "exact alone its values make no configurations of their own (add paper to "
                                         "--traversal, or give one value)");
  std::vector<Config> out;
  bool dropped_enlargement = false, dropped_padding = false;  // what left configurations out
  for (const std::string& tr : o.traversal)
    for (const std::string& tt : o.triangle_test)
      for (const std::string& cap : o.capacity)
        for (const std::string& en : o.enlargement)
          for (const std::string& pa : o.padding)
          for (size_t ei = 0; ei < o.elongation.size(); ++ei)
          for (size_t ri = 0; ri < o.repeats.size(); ++ri)
            for (size_t gi = 0; gi < o.gap_fill.size(); ++gi)
              for (const std::string& sp : o.spill)
              for (const std::string& la : o.launch)
                for (const std::string& md : o.max_dim) {
                  if (tr == "exact" && (ei > 0 || gi > 0 || ri > 0)) continue;
                  Config c;
                  if (pa != "auto") c.padding = parse_float("aabb-padding", pa, 0.0f, 16.0f);
                  c.repeats = o.repeats[ri];
                  c.traversal = tr;
                  c.triangle_test = tt;
                  // A number of slots spelled any way (8, 08) is one value: its decimal form
                  c.capacity = cap.find_first_not_of("0123456789") == std::string::npos
                                   ? std::to_string(std::strtoul(cap.c_str(), nullptr, 10))
                                   : cap;
                  c.enlargement = parse_float("enlargement", en, 0.0f, 16.0f);
                  // Below 1 the plane test drops triangles at cells' corners: the paper's knob; the
                  // exact traversal refuses it (plan::choose_grid), so the sweep leaves it out there
                  if (tr == "exact" && c.enlargement < 1.0f) {
                    dropped_enlargement = true;
                    continue;
                  }
                  // So is an AABB padding of 0 (a triangle on a cell face left out of the cell across it)
                  if (tr == "exact" && c.padding && !(*c.padding > 0.0f)) {
                    dropped_padding = true;
                    continue;
                  }
                  c.elongation = parse_float("elongation", o.elongation[ei], 0.0f, 16.0f);
                  c.gap_fill = o.gap_fill[gi];
                  c.spill = sp;
                  c.launch = la;
                  const float dim = parse_float("max-image-dimension", md, 2.0f, 65536.0f);
                  if (dim != std::floor(dim))
                    throw CLI::ValidationError("--max-image-dimension", "'" + md + "' is not a whole number of texels");
                  c.max_dim = uint32_t(dim);
                  if (std::find(out.begin(), out.end(), c) == out.end()) out.push_back(c);
                }
  // Named by what dropped them (the enlargement was named for a padding's refusal: an outside sweep)
  if (out.empty() && dropped_padding && !dropped_enlargement)
    throw CLI::ValidationError("--aabb-padding", "every configuration asks the exact traversal for an AABB padding "
                                                 "of 0, which it refuses (the paper traversal's knob)");
  if (out.empty())
    throw CLI::ValidationError(dropped_padding ? "--enlargement, --aabb-padding" : "--enlargement",
                               std::string("every configuration asks the exact traversal for an enlargement below 1") +
                                   (dropped_padding ? " or an AABB padding of 0" : "") +
                                   ", which it refuses (the paper traversal's knobs)");
  return out;
}

BackendOptions backend_options_for(const SweepOptions& o, const Config& c) {
  BackendOptions b = o.backend_options;
  GridOptions& g = b.grid;
  if (o.work_sample.size() == 2) {
    if (o.work_sample[0] == 0 || o.work_sample[1] == 0 || uint64_t(o.work_sample[0]) * o.work_sample[1] > 256u * 144u)
      throw Error("--work-sample: " + std::to_string(o.work_sample[0]) + "," + std::to_string(o.work_sample[1]) +
                  " must be at least 1,1 and at most 36864 pixels (e.g. 256,144)");
    g.work_sample_width = o.work_sample[0];
    g.work_sample_height = o.work_sample[1];
  }
  g.traversal = c.traversal == "exact" ? reference::Traversal::exact : reference::Traversal::paper;
  g.triangle_test = c.triangle_test == "watertight" ? GridOptions::TriangleTest::watertight : GridOptions::TriangleTest::moller;
  if (c.capacity == "percentile") {
    // The original rule: the 0.99 percentile of the cells' counts, clamped to [4, 64]
    g.capacity_policy = GridOptions::CapacityPolicy::percentile;
    g.max_capacity = 64;
  } else if (c.capacity == "no-saturation") {
    g.capacity_policy = GridOptions::CapacityPolicy::no_saturation;
  } else if (c.capacity == "trace-cost") {
    g.capacity_policy = GridOptions::CapacityPolicy::trace_cost;
  } else if (c.capacity != "auto") {
    g.capacity = uint32_t(std::stoul(c.capacity));
  }
  g.capacity_policy_given = c.capacity != "auto" && !g.capacity;  // a rule named: over the file's capacity
  g.sphere_enlargement = c.enlargement;
  g.aabb_padding = c.padding;
  g.elongation = c.elongation;
  g.repeats = c.repeats == "skip"     ? GridOptions::Repeats::skip
              : c.repeats == "retest" ? GridOptions::Repeats::retest
                                      : GridOptions::Repeats::merge;
  g.gap_fill = c.gap_fill == "on";
  g.spill = c.spill == "on" ? GridOptions::Spill::on : c.spill == "off" ? GridOptions::Spill::off : GridOptions::Spill::automatic;
  g.exclude_launch_ref = c.launch == "exclude";
  g.max_image_dimension = c.max_dim;
  return b;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Accuracy of one tracer's hits against the oracle's.
struct Accuracy {
  size_t rays = 0, differ = 0, ties = 0, holes = 0, false_hits = 0, gap_fill = 0;
  uint32_t max_tie_ulps = 0;             // the largest |t - t_oracle| in ulps over the ties
  double median_dt = 0.0, max_dt = 0.0;  // |t - t_oracle| over rays with the same triangle
  double agree() const { return rays ? 100.0 * double(rays - differ) / double(rays) : 100.0; }
};

// A differing ray is a tie when both hit, at distances within kTieUlps of each other (the one
// definition, classify_difference's too).
using reference::kTieUlps;

Accuracy accuracy(std::span<const Hit> want, std::span<const Hit> got) {
  Accuracy a;
  a.rays = want.size();
  std::vector<double> dts;
  for (size_t i = 0; i < want.size(); ++i) {
    const Hit& w = want[i];
    const Hit& g = got[i];
    if (g.flags & shared::kHitGapFill) ++a.gap_fill;
    const bool wm = is_miss(w), gm = is_miss(g);
    if (wm && gm) continue;
    if (!wm && gm) {
      ++a.holes, ++a.differ;
      continue;
    }
    if (wm && !gm) {
      ++a.false_hits, ++a.differ;
      continue;
    }
    if (w.instance != g.instance || w.triangle != g.triangle) {
      ++a.differ;
      const uint32_t ulps = reference::ulp_distance(w.t, g.t);
      if (!(g.flags & shared::kHitGapFill) && ulps <= kTieUlps) ++a.ties, a.max_tie_ulps = std::max(a.max_tie_ulps, ulps);
      continue;
    }
    dts.push_back(std::abs(double(g.t) - double(w.t)));
  }
  if (!dts.empty()) {
    a.max_dt = *std::max_element(dts.begin(), dts.end());
    std::nth_element(dts.begin(), dts.begin() + ptrdiff_t(dts.size() / 2), dts.end());
    a.median_dt = dts[dts.size() / 2];
  }
  return a;
}

struct Row {
  size_t index = 0;
  Config config;
  std::string backend, grid;
  uint32_t capacity = 0;
  uint64_t saturated = 0;
  bool spill_on = false;
  uint64_t spill_stored = 0, spill_overflow = 0;  // after the build
  double build_ms = 0, update_ms = 0, trace_ms = 0, mrays = 0, grid_mib = 0;
  Accuracy acc;
  // Differing rays by cause (reference::classify_difference; CPU rows only), and the measured work
  std::array<size_t, 9> why{};
  bool classified = false;  // `why` was counted (a CPU row): the CSV leaves a Vulkan row's causes empty
  float padding = 0.0f;  // the AABB padding the grid was built with
  // Whether --max-image-dimension shaped the grid: not on the compact layout the trace-cost policy
  // chose (no image, and no limit weighed: max_dim "-"), as the other verbs refuse it there
  bool image_limit = true;
  reference::WorkEstimate work;
};

// The causes column: "skip 12, win 3, ..." (only the non-zero ones).
std::string causes(const Row& r) {
  using D = reference::Difference;
  const std::pair<D, const char*> names[] = {{D::skipped_cell, "skip"}, {D::window, "win"},  {D::dropped, "drop"},
                                             {D::reported_early, "early"}, {D::tested, "test"}, {D::grid_nearer, "near"},
                                             {D::gap_fill, "gap"}, {D::tie, "tie"}};
  std::string s;
  for (const auto& [d, name] : names)
    if (r.why[size_t(d)]) s += (s.empty() ? "" : ", ") + std::string(name) + " " + std::to_string(r.why[size_t(d)]);
  return s.empty() ? "-" : s;
}

// ---- The plot: agreement against trace time (common/plot.h) ----

// The CSV's measured figures: six significant digits, so that small times are not rounded to
// 0.00 beside a rate made from them (the Markdown rounds for reading)
std::string data(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.6g", v);
  return b;
}

std::string fmt(double v, int digits) {
  char b[32];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

// Pareto front: rows no other row beats in both trace time (lower) and agreement (higher).
std::vector<bool> pareto(const std::vector<Row>& rows) {
  std::vector<bool> front(rows.size(), true);
  for (size_t i = 0; i < rows.size(); ++i)
    for (size_t j = 0; j < rows.size(); ++j)
      if (j != i && rows[j].trace_ms <= rows[i].trace_ms && rows[j].acc.agree() >= rows[i].acc.agree() &&
          (rows[j].trace_ms < rows[i].trace_ms || rows[j].acc.agree() > rows[i].acc.agree()))
        front[i] = false;
  return front;
}

// The plot written to `path`; false (and said) where this build draws none.
bool plot_agreement(const std::string& path, const std::string& title, const std::vector<Row>& rows) {
  if (!plot::available()) {
    std::printf("  plot: skipped (this build has no OpenImageIO or no DejaVu font)\n");
    return false;
  }
  plot::Canvas cv(760, 545);
  double tmax = 0.0, amin = 100.0;
  for (const Row& r : rows) tmax = std::max(tmax, r.trace_ms), amin = std::min(amin, r.acc.agree());
  tmax = tmax > 0.0 ? tmax * 1.1 : 1.0;
  amin = std::max(0.0, std::floor(amin - 1.0));
  plot::Axes ax(cv, 90, 50, 730, 440, 0.0, tmax, amin, 100.0);
  ax.draw("trace time, ms (median)", "agreement with Embree, %");
  cv.text(90, 24, "Accuracy against trace time: " + title, plot::colors::black, 16, plot::Align::left, true);
  // The Pareto front, then every point with its row number (front points red)
  const std::vector<bool> front = pareto(rows);
  std::vector<size_t> f;
  for (size_t i = 0; i < rows.size(); ++i)
    if (front[i]) f.push_back(i);
  std::sort(f.begin(), f.end(), [&](size_t a, size_t b) { return rows[a].trace_ms < rows[b].trace_ms; });
  for (size_t k = 1; k < f.size(); ++k)
    cv.line(ax.x(rows[f[k - 1]].trace_ms), ax.y(rows[f[k - 1]].acc.agree()), ax.x(rows[f[k]].trace_ms),
            ax.y(rows[f[k]].acc.agree()), plot::colors::red, 2);
  for (size_t i = 0; i < rows.size(); ++i) {
    const int x = ax.x(rows[i].trace_ms), y = ax.y(rows[i].acc.agree());
    const glm::vec3 c = front[i] ? plot::colors::red : plot::colors::blue;
    cv.marker(x, y, 3, c);
    cv.text(x + 6, y - 6, std::to_string(rows[i].index), c, 11);
  }
  plot::draw_legend(cv, 90, 496,
                    {{plot::colors::red, "Pareto front (no row is both faster and more accurate)"},
                     {plot::colors::blue, "other configurations (numbers: the rows of the table)"}},
                    12);
  cv.write(path);
  return true;
}

// A CSV field: quoted where it holds a comma, a quote or a line break (RFC 4180), quotes doubled.
std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string out = "\"";
  for (char c : text) out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string file_stem(const std::string& scene) {
  std::string s = std::filesystem::path(scene).stem().string();
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_') c = '-';
  return s.empty() ? "scene" : s;
}

void write_outputs(const std::string& dir, const std::string& stem, const std::string& title,
                   const std::vector<Row>& rows, const std::string& header) {
  const std::vector<bool> front = pareto(rows);
  {
    std::ostringstream csv;  // written atomically and checked below (safe_io.h)
    csv << "index,scene,backend,traversal,triangle_test,capacity_knob,enlargement,aabb_padding,elongation,revisit,"
           "gap_fill,spill,self_hit,max_dim,grid,capacity,saturated_cells,spill_entries,spill_overflow,rays,differ,ties,"
           "max_tie_ulps,holes,false_hits,gap_fill_hits,agree_pct,median_dt,max_dt,build_ms,update_ms,trace_ms,"
           "mrays_per_s,grid_mib,pareto,cells_per_ray,tests_per_ray,why_skipped_cell,why_window,why_dropped,"
           "why_reported_early,why_tested,why_grid_nearer,why_gap_fill,why_tie\n";
    for (size_t i = 0; i < rows.size(); ++i) {
      const Row& r = rows[i];
      const Config& c = r.config;
      csv << r.index << "," << csv_field(title) << "," << r.backend << "," << c.traversal << "," << c.triangle_test << ","
          << c.capacity << "," << c.enlargement << "," << r.padding << "," << c.elongation << "," << c.repeats << ","
          << c.gap_fill << "," << (r.spill_on ? "on" : "off") << "," << c.launch << "," << (r.image_limit ? std::to_string(c.max_dim) : std::string("-")) << "," << r.grid
          << "," << r.capacity << "," << r.saturated << "," << r.spill_stored << "," << r.spill_overflow << ","
          << r.acc.rays << "," << r.acc.differ << "," << r.acc.ties << "," << r.acc.max_tie_ulps << "," << r.acc.holes
          << "," << r.acc.false_hits << ","
          << r.acc.gap_fill << "," << fmt(r.acc.agree(), 3) << "," << r.acc.median_dt << "," << r.acc.max_dt << ","
          << data(r.build_ms) << "," << data(r.update_ms) << "," << data(r.trace_ms) << "," << data(r.mrays)
          << "," << data(r.grid_mib) << "," << (front[i] ? 1 : 0) << "," << fmt(r.work.cells, 2) << ","
          << fmt(r.work.tests, 2);
      using D = reference::Difference;
      for (D d : {D::skipped_cell, D::window, D::dropped, D::reported_early, D::tested, D::grid_nearer, D::gap_fill,
                  D::tie})
        csv << "," << (r.classified ? std::to_string(r.why[size_t(d)]) : std::string());  // empty: not classified
      csv << "\n";
    }
    write_file_atomically(dir + "/" + stem + ".csv", "CSV table", csv.str());
  }
  std::ostringstream md;
  md << header << "\n\n"
     << "| # | backend | traversal | test | capacity | enl | pad | elo | revisit | gap-fill | spill | self-hit | grid | "
        "cap | sat. cells | spilled | agree % | differ | ties (max ulps) | holes | false hits | gap-fill hits | "
        "median dt | max dt | build ms | update ms | trace ms | Mrays/s | MiB | cells/ray | tests/ray | causes | front |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        "---|---|---|---|---|\n";
  char dt[64];
  for (size_t i = 0; i < rows.size(); ++i) {
    const Row& r = rows[i];
    const Config& c = r.config;
    const bool paper = c.traversal == "paper";
    std::snprintf(dt, sizeof dt, "%.1e | %.1e", r.acc.median_dt, r.acc.max_dt);
    md << "| " << r.index << " | " << r.backend << " | " << c.traversal << " | " << c.triangle_test << " | "
       << c.capacity << " | " << c.enlargement << " | " << (c.padding ? "" : "auto ") << r.padding << " | "
       << (paper ? fmt(c.elongation, 2) : "-") << " | " << (paper ? c.repeats : "-") << " | "
       << (paper && !r.spill_on ? c.gap_fill : "-") << " | " << (r.spill_on ? "on" : "off") << " | " << c.launch
       << " | " << r.grid << " | " << r.capacity << " | " << r.saturated << " | "
       << (r.spill_on ? std::to_string(r.spill_stored) + (r.spill_overflow ? " (+" + std::to_string(r.spill_overflow) + " lost)" : "")
                      : "-")
       << " | " << fmt(r.acc.agree(), 2) << " | " << r.acc.differ << " | " << r.acc.ties
       << (r.acc.ties ? " (" + std::to_string(r.acc.max_tie_ulps) + ")" : "") << " | "
       << r.acc.holes << " | " << r.acc.false_hits << " | " << r.acc.gap_fill << " | " << dt << " | "
       << fmt(r.build_ms, 1) << " | " << fmt(r.update_ms, 1) << " | " << fmt(r.trace_ms, 1) << " | "
       << fmt(r.mrays, 2) << " | " << fmt(r.grid_mib, 1) << " | " << fmt(r.work.cells, 1) << " | "
       << fmt(r.work.tests, 1) << " | " << causes(r) << " | " << (front[i] ? "*" : "") << " |\n";
  }
  write_file_atomically(dir + "/" + stem + ".md", "Markdown table", md.str());
  std::printf("  table: %s/%s.md, data: %s/%s.csv\n", dir.c_str(), stem.c_str(), dir.c_str(), stem.c_str());
}

#ifdef GRIDRT_HAVE_EMBREE
// A scene's rays for the sweep: the glossy bounce rays of its frame's gather buffer (only the used
// ones), or (--rays, or auto without glossy materials) rays of another kind; `kind` names them.
std::vector<Ray> sweep_rays(const SweepOptions& o, const Scene& scene, EmbreeTracer& embree, std::string& kind) {
  // The gather buffer and its glossy bounce rays (only the used ones are traced and timed)
  GatherBuffer gather;
  {
    reference::ReferenceGridTracer tracer(plan::gather_options(grid_options_for(o.backend_options, scene)));
    tracer.build(scene, 0.0f);
    Progress progress("gather buffer (" + scene.name + ")", size_t(o.width) * o.height);
    ProgressTracer traced(tracer, progress);
    gather = make_gather(scene, traced, scene.frame_camera(), o.width, o.height, 0.0f);
  }
  std::vector<Ray> rays;
  if (o.rays == "auto" || o.rays == "glossy")
    for (const Ray& r : bounce_rays(scene, gather, 0))
      if (!is_unused(r)) rays.push_back(r);
  if (rays.empty() && o.rays == "glossy") throw Error("sweep: " + scene.name + " has no glossy bounce rays in its frame");
  kind = "glossy bounce";
  if (rays.empty()) {
    // Any scene: the chosen kind of rays (auto without glossy materials: diffuse bounces)
    kind = o.rays == "auto" ? "diffuse" : o.rays;
    GridOptions aim = grid_options_for(o.backend_options, scene);
    aim.traversal = reference::Traversal::exact;
    reference::ReferenceGridTracer aimer(aim);
    aimer.build(scene, 0.0f);
    rays = verify::rays_of_kind(kind, scene, aimer.data(), embree, o.width, o.height);
    // A scene with glossy materials none of which the camera sees has no glossy bounce rays
    // either: said as it is (it read "has no glossy material")
    if (o.rays == "auto")
      std::printf("sweep: %s %s: %s rays instead\n", scene.name.c_str(),
                  Features::for_scene(scene).glossy ? "has glossy materials, but its frame makes no glossy bounce ray"
                                                    : "has no glossy material",
                  kind.c_str());
    if (rays.empty()) throw Error("sweep: " + scene.name + " gives no " + kind + " rays");
  }
  return rays;
}

// A grid of the compact layout chosen by the trace-cost policy: no image, no image limit weighed.
bool compact_by_trace_cost(const shared::GridParams& built, const reference::GridOptions& go) {
  return (built.flags & shared::kGridCompact) != 0u &&
         go.capacity_policy == reference::GridOptions::CapacityPolicy::trace_cost;
}

// One configuration on one backend: build, update, trace (median of --repeat), the grid's figures
// and the accuracy against Embree's hits `want`. False (with a message) where the build refuses it.
bool measure_row(const SweepOptions& o, const Scene& scene, const std::vector<Ray>& rays, const std::vector<Hit>& want,
                 const std::string& backend, const Config& c, Row& row, std::string& why_skipped) {
  row.config = c;
  row.backend = backend;
  const BackendOptions bo = backend_options_for(o, c);
  std::unique_ptr<Tracer> tracer;
  auto t0 = std::chrono::steady_clock::now();
  try {
    tracer = make_backend(backend, bo, scene);
    t0 = std::chrono::steady_clock::now();
    tracer->build(scene, 0.0f);
    row.build_ms = ms_since(t0);
  } catch (const Error& e) {
    std::fprintf(stderr, "gridrt sweep: %s, %s: skipped: %s\n", scene.name.c_str(), c.label().c_str(), e.what());
    why_skipped = e.what();
    return false;
  }
  t0 = std::chrono::steady_clock::now();
  tracer->update(0.0f);
  row.update_ms = ms_since(t0);
  std::vector<Hit> got(rays.size());
  std::vector<double> times;
  for (uint32_t k = 0; k < std::max(1u, o.repeat); ++k) {
    t0 = std::chrono::steady_clock::now();
    tracer->trace(rays, got);
    times.push_back(ms_since(t0));
  }
  row.trace_ms = median(times);
  row.mrays = row.trace_ms > 0.0 ? double(rays.size()) / (row.trace_ms * 1e3) : 0.0;
  const AccelDump dump = tracer->dump();
  row.grid_mib = double(dump.texels.size()) * 4.0 / (1 << 20);
  const reference::GridOptions go = grid_options_for(bo, scene);
  if (auto* ref = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get())) {
    const reference::GridStats s = ref->stats();
    row.grid_mib = double(s.memory.total()) / (1 << 20);  // everything the grid keeps, either layout
    row.saturated = s.saturated_static + s.saturated_dynamic;
    row.spill_on = s.spill_on;
    row.spill_stored = s.spill_stored;
    row.spill_overflow = s.spill_overflow;
    row.capacity = s.capacity;
    row.grid = std::to_string(s.cells.x) + "x" + std::to_string(s.cells.y) + "x" + std::to_string(s.cells.z);
    row.padding = ref->params().aabb_padding;
    row.image_limit = !compact_by_trace_cost(ref->params(), go);
  }
#ifdef GRIDRT_HAVE_VULKAN
  if (auto* vk = dynamic_cast<vulkan::VulkanGridTracer*>(tracer.get())) {
    // Host times on lavapipe; timestamps where the device has them
    if (vk->timings().build_ms > 0.0) row.build_ms = vk->timings().build_ms;
    const shared::GridParams g = reference::choose_grid(scene, 0.0f, go);
    const shared::SpillHeader& sh = vk->spill_header();
    row.spill_on = (vk->params().flags & shared::kGridSpill) != 0u;
    row.spill_stored = std::min(sh.count, sh.capacity);
    row.spill_overflow = row.spill_on && sh.count > sh.capacity ? sh.count - sh.capacity : 0u;
    row.capacity = g.capacity;
    row.padding = g.aabb_padding;
    row.grid_mib = double(vk->memory().total()) / (1 << 20);  // everything the grid keeps, as the CPU row's
    row.grid = std::to_string(g.cells.x) + "x" + std::to_string(g.cells.y) + "x" + std::to_string(g.cells.z);
    // Saturated cells from the image's status texels; the compact layout has no slots to fill (its
    // dump is the offsets and references: reading it as an image ran past it, an outside sweep's
    // crash) and no saturated cell
    const shared::GridParams& built = vk->params();
    row.image_limit = !compact_by_trace_cost(built, go);
    if ((built.flags & shared::kGridCompact) == 0u && dump.kind == "grid")
      for (uint32_t z = 0; z < built.cells.z; ++z)
        for (uint32_t y = 0; y < built.cells.y; ++y)
          for (uint32_t x = 0; x < built.cells.x; ++x)
            row.saturated +=
                dump.texels[shared::texel_index(shared::cell_status_texel(built, {x, y, z}), dump.extent)] != 0u;
  }
#endif
  row.acc = accuracy(want, got);
  row.work = reference::measured_work(rays, got);
  if (auto* ref = dynamic_cast<reference::ReferenceGridTracer*>(tracer.get())) {
    for (size_t i = 0; i < rays.size(); ++i)
      row.why[size_t(reference::classify_difference(ref->data(), rays[i], got[i], want[i]))] += 1;
    row.classified = true;
  }
  return true;
}
#endif

void run_sweep(const SweepOptions& o) {
#ifndef GRIDRT_HAVE_EMBREE
  throw Error("sweep needs the Embree oracle, which this build does not have");
#else
  if (o.scenes.empty()) throw Error("sweep: name at least one scene");
  // The command line is checked before any work (exit 2): the backends, the rays' kind, the knobs
  if (o.backends.empty()) throw OptionsError("--backend: the list is empty");
  for (const std::string& b : o.backends)
    if (b != "cpu" && b != "vulkan") throw OptionsError("--backend: '" + b + "' cannot be swept (cpu, vulkan)");
  if (!verify::is_ray_kind(o.rays)) throw OptionsError("--rays: unknown kind '" + o.rays + "' (" + verify::ray_kind_list() + ")");
  check_frame_size(o.width, o.height);
  const std::vector<Config> configs = configurations(o);
  // A backend named twice is swept once (its rows would repeat)
  std::vector<std::string> backends;
  for (const std::string& b : o.backends)
    if (std::find(backends.begin(), backends.end(), b) == backends.end()) backends.push_back(b);
  // A limit above the Vulkan device's, as every other verb refuses it (the sweep built an image
  // wider than the device allows: an outside sweep)
  if (std::find(backends.begin(), backends.end(), "vulkan") != backends.end())
    if (const uint32_t limit = vulkan_max_image_dimension(); limit != 0)
      for (const Config& c : configs)
        if (c.max_dim > limit)
          throw OptionsError("--max-image-dimension " + std::to_string(c.max_dim) +
                             " exceeds the Vulkan device's maxImageDimension3D (" + std::to_string(limit) +
                             "): give at most that for --backend vulkan");
  // Every scene file there before the first is swept (a missing second one was found after the
  // first's outputs were written)
  for (const std::string& spec : o.scenes)
    if (!spec.empty() && spec.rfind("builtin:", 0) != 0)
      if (const std::string why = why_missing(spec); !why.empty()) throw Error("sweep: scene '" + spec + "': " + why);
  {
    std::error_code ec;
    std::filesystem::create_directories(o.out, ec);
    if (!is_folder(o.out))
      throw Error("sweep: cannot use '" + o.out + "' as the output folder: " +
                  (ec ? ec.message() : std::string("it exists and is not a folder")));
  }
  std::printf("sweep: %zu configurations x %zu backend(s) per scene, %ux%u gather buffer, trace medians of %u\n",
              configs.size(), backends.size(), o.width, o.height, o.repeat);
  std::map<std::string, int> stems_used;
  for (const std::string& spec : o.scenes) {
    const Scene scene = load_scene_or_default(spec);
    EmbreeTracer embree(0);
    embree.build(scene, 0.0f);
    std::string kind;
    const std::vector<Ray> rays = sweep_rays(o, scene, embree, kind);
    std::vector<Hit> want(rays.size());
    auto t0 = std::chrono::steady_clock::now();
    embree.trace(rays, want);
    const double embree_ms = ms_since(t0);
    std::printf("%s: %llu triangles, %zu %s rays; Embree traces them in %.1f ms\n", scene.name.c_str(),
                (unsigned long long)scene.triangle_count(), rays.size(), kind.c_str(), embree_ms);

    std::vector<Row> rows;
    std::vector<std::string> skipped;  // configurations the build refused, with why (the tables say so)
    Progress progress("sweep " + scene.name, configs.size() * backends.size());
    for (const std::string& backend : backends)
      for (const Config& c : configs) {
        Row row;
        row.index = rows.size();
        std::string why;
        if (!measure_row(o, scene, rays, want, backend, c, row, why)) {
          skipped.push_back(backend + ", " + c.label() + ": " + why);
          progress.advance();
          continue;
        }
        rows.push_back(row);
        progress.advance();
      }
    progress.finish();
    // A backend that measured nothing (no Vulkan device, every configuration refused) is an
    // error, not an empty table with exit 0 (an outside sweep's find)
    for (const std::string& backend : backends)
      if (std::none_of(rows.begin(), rows.end(), [&](const Row& r) { return r.backend == backend; }))
        throw Error("sweep: " + scene.name + ": the " + backend +
                    " backend measured no configuration (each was skipped, the reasons above)");
    // Two scenes of one name (a/quad.obj, b/quad.obj) write apart: the second as quad-2
    // A name no earlier scene took: "x" twice gives "x-2", unless a scene is named "x-2" itself
    // (an outside sweep's find: the second x.obj's tables replaced those of x-2.obj)
    const std::string base = file_stem(spec);
    std::string stem = base;
    for (int n = 2; stems_used.count(stem); ++n) stem = base + "-" + std::to_string(n);
    stems_used[stem] = 1;
    std::ostringstream header;
    header << "Scene `" << scene.name << "`: " << scene.triangle_count() << " triangles, " << rays.size()
           << " " << kind << " rays of a " << o.width << "x" << o.height << " gather buffer (frame 0, t = 0); Embree "
           << fmt(embree_ms, 1) << " ms on " << std::thread::hardware_concurrency()
           << " hardware threads. agree = same triangle or both miss; ties = differing rays whose t is within "
           << kTieUlps << " ulps of Embree's; dt = |t - t_embree| over same-triangle hits; times: medians, host clock.";
    // Configurations the build refused are not rows: the table says how many and why (an outside
    // sweep: 12 configurations, 10 rows, and only stderr said so)
    if (!skipped.empty()) {
      header << "\n\n" << skipped.size() << " of " << configs.size() * backends.size()
             << " configurations skipped (not in the table or the CSV):";
      for (const std::string& s : skipped) header << "\n- " << s;
    }
    std::printf("%s\n", header.str().c_str());
    // The three files checked before any is written: a refused plot left the tables replaced
    for (const char* ext : {".csv", ".md", ".png"}) check_output_allowed(o.out + "/" + stem + ext, "sweep output");
    // And written as a set: the plot first under a name of its own, then the tables, then the
    // plot renamed over its place; a failed write leaves the earlier set whole (a full disk after
    // the tables left them beside the last run's plot: an outside sweep)
    const std::string png = o.out + "/" + stem + ".png";
    const std::string staged = o.out + "/." + stem + ".sweep-" + std::to_string(getpid()) + ".png";
    const bool plotted = plot_agreement(staged, scene.name, rows);
    try {
      write_outputs(o.out, stem, scene.name, rows, header.str());
    } catch (...) {
      std::error_code ignored;
      if (plotted) std::filesystem::remove(staged, ignored);
      throw;
    }
    if (plotted) {
      // Put in its place as every output is (write_file_atomically: the file a link names, its
      // permissions kept; a plain rename replaced the link and reset them: a review's find)
      std::string bytes;
      try {
        bytes = read_input_file(staged, "plot");
      } catch (...) {
        std::error_code ignored;
        std::filesystem::remove(staged, ignored);
        throw;
      }
      std::error_code ignored;
      std::filesystem::remove(staged, ignored);
      write_file_atomically(png, "plot", bytes);
      std::printf("  plot: %s\n", png.c_str());
    }
  }
#endif
}

}  // namespace

void add_sweep_command(CLI::App& app) {
  auto o = std::make_shared<SweepOptions>();
  CLI::App* cmd = app.add_subcommand(
      "sweep", "Accuracy against Embree vs time over a grid of the grid's knobs, per scene: CSV, Markdown, PNG plot");
  cmd->add_option("scenes", o->scenes, "Scene files, meshes or builtin:NAME")->required();
  cmd->add_option("--backend,-b", o->backends, "Backends: cpu, vulkan (comma separated)")->delimiter(',');
  add_image_size(cmd, o->width, o->height, "of the gather buffer");
  cmd->add_option("-o,--output-dir", o->out, "Output folder, not a file (per scene: NAME.csv, NAME.md, NAME.png)")
      ->capture_default_str();
  cmd->add_option("--rays", o->rays,
                  "The rays swept: auto (the frame's glossy bounce rays, else diffuse bounces), glossy, primary, "
                  "diffuse, or a verify family (random, surface, edge, ...); about WIDTH x HEIGHT of them");
  cmd->add_option("--repeat", o->repeat, "Trace each configuration this many times (median)")
      ->check(CLI::Range(1u, 1000u));
  cmd->add_option("--traversal", o->traversal, "Knob values: paper,exact")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--triangle-test", o->triangle_test, "Knob values: moller,watertight")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--capacity", o->capacity,
                  "Knob values: auto (the default rule), trace-cost, no-saturation (no saturation where the "
                  "limits allow), percentile (the original 0.99 percentile clamped to 64), or "
                  "a number of slots (the same values as the other verbs' --capacity)")
      ->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--enlargement", o->enlargement, "Knob values: sphere enlargement")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--elongation", o->elongation, "Knob values: segment elongation (paper)")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--aabb-padding", o->padding, "Knob values: cells added on each side of a triangle's AABB (build), or auto (the default)")
      ->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--revisit", o->repeats, "Knob values: merge,skip,retest (paper: consecutive samples in one cell)")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--gap-fill", o->gap_fill, "Knob values: on,off (paper)")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--spill", o->spill, "Knob values: auto,on,off (the spill list; auto: on for exact)")
      ->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--self-hit", o->launch, "Knob values: exclude,keep (the launch triangle)")->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--max-image-dimension", o->max_dim, "Knob values: image limit (4096 lavapipe, 16384 NVIDIA)")
      ->delimiter(',')->type_name("A,B,..")->group("Knobs");
  cmd->add_option("--threads", o->backend_options.grid.threads, "CPU threads (0: all)")
      ->check(CLI::Range(0u, kMaxThreads))->group("Grid");
  // The fixed expert knobs of every configuration, grouped as on the other verbs
  constexpr const char* kExpert = "Grid (expert)";
  cmd->add_option_function<float>(
         "--density",
         [o](float d) { o->backend_options.grid.density = d, o->backend_options.grid.density_given = true; },
         "Target cells per triangle")
      ->check(CLI::Range(1.0e-3f, 1.0e3f))
      ->group(kExpert);
  cmd->add_option("--cell-visit-cost", o->backend_options.grid.cell_visit_cost,
                  "trace-cost policy: the cost of visiting a cell, in reference tests (default: 1.6 for the exact "
                  "traversal, fitted on the GPU; 1 for the paper's)")
      ->check(CLI::Range(0.0f, 1.0e6f))
      ->group(kExpert);
  cmd->add_option("--saturation-cost", o->backend_options.grid.saturation_cost,
                  "trace-cost policy: the cost of a ray whose answer the grid changes, in reference tests")
      ->check(CLI::Range(0.0f, 1.0e12f))  // as the other verbs' (a negative cost was taken)
      ->group(kExpert);
  cmd->add_option("--work-sample", o->work_sample, "trace-cost policy: the sample's gather buffer W,H")
      ->delimiter(',')
      ->expected(2)
      ->type_name("W,H")
      ->group(kExpert);
  cmd->callback([o, cmd] {
    // The paper traversal's knobs with the exact traversal alone, even one value each: its CSV rows
    // recorded the value as if it applied (an outside sweep; render refuses them too)
    if (std::find(o->traversal.begin(), o->traversal.end(), "paper") == o->traversal.end())
      for (const char* name : {"--elongation", "--revisit", "--gap-fill"})
        if (cmd->count(name) > 0)
          throw OptionsError(std::string(name) + " is a knob of the paper traversal's segments and gap-fill; with "
                             "--traversal exact alone it does nothing (add paper to --traversal, or leave it out)");
    // A bad command line before any work (an outside sweep: the work sample was judged after the
    // scene loaded, exit 1)
    if (o->work_sample.size() == 2 &&
        (o->work_sample[0] == 0 || o->work_sample[1] == 0 || uint64_t(o->work_sample[0]) * o->work_sample[1] > 256u * 144u))
      throw CLI::ValidationError("--work-sample", std::to_string(o->work_sample[0]) + "," +
                                                      std::to_string(o->work_sample[1]) +
                                                      " must be at least 1,1 and at most 36864 pixels (e.g. 256,144)");
    run_sweep(*o);
  });
}

}  // namespace gridrt::app
