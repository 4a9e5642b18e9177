// gridrt diff: the CPU reference against the Vulkan port, for a person and for CI. Grid images
// (sorted: texel for texel; first-empty: every cell's slots as a multiset of its candidates), the
// spill list, every hit record of the camera rays and of the glossy bounce off the reference's
// gather buffer, over frames (a build, then updates), with the validation layer listening.
//
// Exit codes: 0 agree, 1 bad input (no such scene, no device, ...), 2 bad command line, 3 the port
// differs, 4 the validation layer reported something (whatever the comparison found).
// --json FILE and --junit FILE write reports, each atomically (a temporary file renamed over FILE).
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <optional>
#include <set>
#include <sstream>

#include <nlohmann/json.hpp>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/reference/compare.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/context.h"
#  include "gridrt/vulkan/frame.h"
#  include "gridrt/vulkan/grid.h"
#endif

namespace gridrt::app {

#ifdef GRIDRT_HAVE_VULKAN
namespace {

namespace sh = gridrt::shared;
using nlohmann::json;

struct DiffOptions {
  std::string scene;
  uint32_t width = 160, height = 90;
  float time = 0.0f;
  BackendOptions backend_options;
  uint32_t frames = 3;
  float fps = 30.0f;
  uint32_t ulps_t = 0;   // float fields of otherwise equal hits may differ by this many ulps in t
  float abs_uv = 0.0f;   // ... and by this much in u and v (absolute)
  bool gpu_frame = false;  // also the GPU frame's own passes: gather, bounce rays, trace
  uint32_t sort_bits = 0;  // the GPU frame's bounce rays sorted by this many key bits before their trace (0: off)
  std::string traces = "together";  // the GPU frame's bounce and shadow traces in one dispatch, or apart
  ShadowMode shadows = ShadowMode::automatic;  // the GPU frame's shadow pass (auto: iff the scene has lights)
  std::string validation = "on";  // on, best-practices, off
  std::string json_path, junit_path;
  std::string explain_flags;  // the grid flags given, for the printed explain command
  std::string inject;         // testing the reports: "texel" or "hit" changes one of the port's values
};

// One check of the run: a JUnit test case, a JSON entry.
struct Check {
  std::string name;
  bool ok = true;
  std::string detail;   // what was compared (passed or not)
  std::string failure;  // the first difference
};

// The first difference found, where a person starts looking.
struct FirstDifference {
  std::string what;     // "texel", "cell", "spill", "hit", "gpu-frame"
  uint32_t frame = 0;
  std::optional<glm::uvec3> cell;  // scene cell (x, y, z), not the image's texel order
  std::optional<glm::uvec2> pixel;
  std::string ray_kind;  // "primary" or "bounce"
  std::string text;
  std::string explain;   // a gridrt explain command that shows it
};

std::string cell_text(const glm::uvec3& c) {
  return "(" + std::to_string(c.x) + ", " + std::to_string(c.y) + ", " + std::to_string(c.z) + ")";
}

std::string shell_quote(const std::string& s) {
  if (!s.empty() && s.find_first_not_of("abcdefghijklmnopqrstuvwxyzABCDEFGHIJKLMNOPQRSTUVWXYZ0123456789_-.,/:+=") ==
                        std::string::npos)
    return s;
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

std::string explain_command(const DiffOptions& o, uint32_t x, uint32_t y, bool primary, float time, uint32_t frame) {
  std::ostringstream os;
  os << "gridrt explain " << shell_quote(o.scene.empty() ? "builtin:atrium" : o.scene) << " --pixel " << x << ","
     << y << " --width " << o.width << " --height " << o.height;
  if (time != 0.0f) {  // every digit a float needs: the frame's own time, not one 9 ulps away
    char t[32];
    std::snprintf(t, sizeof t, "%.9g", double(time));
    os << " --time " << t;
  }
  // A later frame's bounce: its glossy directions are seeded by the frame's number
  if (!primary && frame > 0) os << " --frame " << frame;
  os << o.explain_flags;
  // explain --primary traces the gather's grid unless a traversal is given: the diff's primary
  // rays are its own traversal's (the command pointed at another trace: an outside sweep)
  if (primary && o.explain_flags.find("--traversal") == std::string::npos)
    os << " --traversal " << (o.backend_options.grid.traversal == reference::Traversal::exact ? "exact" : "paper");
  os << " --backend vulkan" << (primary ? " --primary" : "");
  return os.str();
}

std::string xml_escape(const std::string& raw) {
  // Bytes that are not UTF-8 (a scene file's name may hold any) as U+FFFD: the XML must be
  // well-formed (an outside sweep's report failed xmllint)
  const std::string s = to_utf8(raw);
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default:
        if (uint8_t(c) < 0x20 && c != '\n' && c != '\t') out += ' ';
        else out += c;
    }
  }
  return out;
}

class DiffRun {
 public:
  explicit DiffRun(const DiffOptions& o) : o_(o) {}
  int run();

 private:
  void check(const std::string& name, bool ok, const std::string& detail, const std::string& failure = "") {
    checks_.push_back(Check{name, ok, detail, failure});
  }
  void first(FirstDifference d) {
    if (!first_) first_ = std::move(d);
  }
  void diff_images(uint32_t frame, float time);
  void diff_spill(uint32_t frame);
  void diff_hits(uint32_t frame, float time);
  void diff_gpu_frame(uint32_t frame, float time);
  void diff_gather_boxes(uint32_t frame, const GatherBuffer& raster);
  void write_reports(int code, double seconds);

  const DiffOptions& o_;
  Scene scene_;
  reference::GridOptions grid_;
  std::unique_ptr<vulkan::Context> ctx_;
  std::unique_ptr<vulkan::VulkanGridTracer> gpu_;
  std::unique_ptr<reference::ReferenceGridTracer> ref_;
  std::unique_ptr<vulkan::VulkanFrame> gpu_frame_;
  std::unique_ptr<vulkan::VulkanFrame> boxes_frame_;  // the compute gather without its rasterizer
  std::vector<Check> checks_;
  std::optional<FirstDifference> first_;
  std::vector<std::string> messages_;
  size_t total_rays_ = 0, total_identical_ = 0, total_discrete_ = 0, total_beyond_ = 0;
  // This frame's grids may differ by design (first-empty insertion with saturated cells: a cell
  // keeps the references that arrived first; an overflowing spill list: the entries that arrived
  // first), so may the hits of rays through them: counted and said, not held to bits
  std::string timing_;
  std::set<size_t> timing_cells_;  // this frame's cells whose contents differ by design
  size_t total_timing_ = 0;
  // Whether ray i's reference walk passes one of timing_cells_ (its hit may then differ by design)
  bool through_timing_cell(const Ray& ray) const;
};

// Grid images: sorted texel for texel; first-empty per cell as multisets. The compact layout's
// arrays (offsets and ordered runs) do not depend on the insertion's order: word for word.
void DiffRun::diff_images(uint32_t frame, float time) {
  const sh::GridParams& g = ref_->params();
  // The compact layout keeps no image: its dump is its arrays (said in the image's words before:
  // an outside sweep)
  const bool compact = (g.flags & sh::kGridCompact) != 0u;
  const std::string name = "frame " + std::to_string(frame) + (compact ? ": compact arrays" : ": grid image");
  if (grid_.insertion == reference::Insertion::sorted || (g.flags & sh::kGridCompact) != 0u) {
    const AccelDump want = ref_->dump();
    AccelDump got = gpu_->dump();
    if (o_.inject == "texel" && frame == 0 && !got.texels.empty()) {
      // The last slot of the middle cell (the compact layout's dump is its arrays: their middle word;
      // the image's index there wrote past their end, an outside sweep)
      const glm::uvec3 c = sh::image_cell(g, g.cells / 2u);
      const glm::uvec3 t = sh::slot_texel(c, g.capacity - 1u, g.capacity);
      const size_t i = (size_t(t.z) * got.extent.y + t.y) * got.extent.x + t.x;
      got.texels[i < got.texels.size() ? i : got.texels.size() / 2] ^= 1u;
    }
    const reference::TexelDiff d = reference::compare_texels(want, got);
    char line[256];
    if (compact)
      std::snprintf(line, sizeof line, "compact arrays (cell offsets and ordered references): %zu of %zu words differ",
                    d.differing.size(), d.texels);
    else
      std::snprintf(line, sizeof line, "grid image %ux%ux%u: %zu of %zu texels differ", want.extent.x, want.extent.y,
                    want.extent.z, d.differing.size(), d.texels);
    std::printf("frame %u: %s\n", frame, line);
    if (d.differing.empty()) return check(name, true, line);
    if (compact) {
      const size_t i = d.differing.front();
      char f[256];
      std::snprintf(f, sizeof f, "first: word %zu of the arrays: reference 0x%08x, vulkan 0x%08x", i, want.texels[i],
                    got.texels[i]);
      std::printf("  %s\n", f);
      check(name, false, line, f);
      first(FirstDifference{.what = "texel", .frame = frame, .text = f});
      return;
    }
    const size_t i = d.differing.front();
    const uint32_t tx = uint32_t(i % want.extent.x), ty = uint32_t((i / want.extent.x) % want.extent.y),
                   tz = uint32_t(i / (size_t(want.extent.x) * want.extent.y));
    const glm::uvec3 cell = sh::image_cell(g, glm::uvec3(tx / (g.capacity + 1), ty, tz));
    const uint32_t slot = tx % (g.capacity + 1);
    char f[384];
    std::snprintf(f, sizeof f, "first: scene cell %s %s %u (texel (%u, %u, %u)): reference 0x%08x, vulkan 0x%08x",
                  cell_text(cell).c_str(), slot == g.capacity ? "status" : "slot", slot, tx, ty, tz, want.texels[i],
                  got.texels[i]);
    std::printf("  %s\n", f);
    check(name, false, line, f);
    first(FirstDifference{.what = "texel", .frame = frame, .cell = cell, .text = f});
    (void)time;
    return;
  }
  const reference::SpillDump spill = gpu_->spill();
  const AccelDump got = gpu_->dump();
  const reference::CellCheck c =
      reference::check_cells_as_multisets(ref_->data(), got, (g.flags & sh::kGridSpill) ? &spill : nullptr);
  char line[256];
  std::snprintf(line, sizeof line, "first-empty grid: %zu of %zu cells break the multiset rule (%zu saturated)",
                c.bad.size(), c.cells, c.saturated);
  std::printf("frame %u: %s\n", frame, line);
  // Saturated cells keep the references that arrived first; the exact traversal with the spill
  // list reads the rest from the list, so its hits do not depend on it (and stay held to bits).
  // Otherwise the cells whose slots hold another choice than the reference's are noted: a ray
  // through one of them may meet another triangle by design
  if (c.saturated > 0 && (g.traversal != sh::kTraversalExact || (g.flags & sh::kGridSpill) == 0u)) {
    const AccelDump want = ref_->dump();
    for (uint32_t z = 0; z < g.cells.z; ++z)
      for (uint32_t y = 0; y < g.cells.y; ++y)
        for (uint32_t x = 0; x < g.cells.x; ++x) {
          // The cell's references as sets (slots in arrival order differ without consequence),
          // but in order where gap-fill runs: it reports the last reference read, so the same
          // references in another order give another hit (an outside sweep's find: DIFFER for
          // that, which the docs excuse)
          std::vector<uint32_t> a, b;
          for (uint32_t sl = 0; sl < g.capacity; ++sl) {
            const size_t t = sh::texel_index(sh::cell_slot_texel(g, glm::uvec3(x, y, z), sl), got.extent);
            if (t < want.texels.size()) a.push_back(want.texels[t]);
            if (t < got.texels.size()) b.push_back(got.texels[t]);
          }
          if ((g.flags & sh::kGridGapFill) == 0u) {
            std::sort(a.begin(), a.end());
            std::sort(b.begin(), b.end());
          }
          if (a != b) timing_cells_.insert((size_t(z) * g.cells.y + y) * g.cells.x + x);
        }
    if (!timing_cells_.empty())
      timing_ = std::to_string(timing_cells_.size()) +
                " saturated cell(s) whose slots kept other references than the reference's (first-empty insertion "
                "keeps whichever arrive first)";
  }
  if (c.bad.empty()) return check(name, true, line);
  const size_t i = c.bad.front();
  const glm::uvec3 cell(uint32_t(i % g.cells.x), uint32_t((i / g.cells.x) % g.cells.y),
                        uint32_t(i / (size_t(g.cells.x) * g.cells.y)));
  const std::string f = "first: scene cell " + cell_text(cell);
  std::printf("  %s\n", f.c_str());
  check(name, false, line, f);
  first(FirstDifference{.what = "cell", .frame = frame, .cell = cell, .text = f});
}

// The spill lists: the headers equal (the counter counts every dropped reference, with spill off
// too); with spill on, sorted insertion, the entries equal as multisets of (cell, ref) (the order
// of appends differs by design; first-empty spills another choice, checked per cell above).
void DiffRun::diff_spill(uint32_t frame) {
  const reference::SpillDump want = ref_->spill(), got = gpu_->spill();
  const bool sorted =
      grid_.insertion == reference::Insertion::sorted || (ref_->params().flags & sh::kGridCompact) != 0u;
  const bool on = (ref_->params().flags & sh::kGridSpill) != 0u;
  const reference::SpillDiff d = reference::compare_spill(want, got);
  const bool same_counts = want.header.count == got.header.count &&
                           want.header.static_count == got.header.static_count &&
                           want.header.capacity == got.header.capacity;
  // An overflowing list keeps on each side the entries that arrived first: only its counts compare
  const bool ok = same_counts && (!on || !sorted || d.same() || want.overflow());
  const bool compact = (ref_->params().flags & sh::kGridCompact) != 0u;
  std::string line = (compact ? std::string("spill list (the compact layout's dynamic references): ") +
                                    std::to_string(want.header.count - want.header.static_count) + " dynamic, " +
                                    std::to_string(want.header.static_count) + " static; reference "
                              : std::string("spill list ") + (on ? "on" : "off (counted only)") + ": " +
                                    std::to_string(want.header.count) + " references found no slot (" +
                                    std::to_string(want.header.static_count) + " static); reference ") +
                     std::to_string(want.header.count) + ", vulkan " + std::to_string(got.header.count) + "; " +
                     std::to_string(want.stored()) + " stored of " + std::to_string(want.header.capacity);
  if (on && sorted)
    line += d.same() ? ", entries equal as multisets of (cell, ref)"
                     : ", entries differ: " + std::to_string(d.only_want.size()) + " only in the reference, " +
                           std::to_string(d.only_got.size()) + " only in vulkan";
  if (want.overflow()) line += " (OVERFLOW: references lost)";
  if (want.overflow() || got.overflow()) {
    const sh::GridParams& g = ref_->params();
    const size_t cells = size_t(g.cells.x) * g.cells.y * g.cells.z;
    for (const auto* side : {&d.only_want, &d.only_got})
      for (const sh::SpillEntry& e : *side)
        if (e.cell < cells) timing_cells_.insert(e.cell);
    if (!timing_cells_.empty())
      timing_ = "the spill list overflowed: each side kept the entries that arrived first (" +
                std::to_string(timing_cells_.size()) + " cell(s) differ)";
  }
  std::printf("frame %u: %s\n", frame, line.c_str());
  std::string f;
  std::optional<glm::uvec3> cell;
  if (!ok) {
    const sh::GridParams& g = ref_->params();
    const std::vector<sh::SpillEntry>& side = d.only_want.empty() ? d.only_got : d.only_want;
    if (!side.empty()) {
      const size_t c = side.front().cell;
      cell = glm::uvec3(uint32_t(c % g.cells.x), uint32_t((c / g.cells.x) % g.cells.y),
                        uint32_t(c / (size_t(g.cells.x) * g.cells.y)));
      f = "first: scene cell " + cell_text(*cell) + " reference 0x" +
          [](uint32_t v) { char b[16]; std::snprintf(b, sizeof b, "%08x", v); return std::string(b); }(side.front().ref) +
          (d.only_want.empty() ? " only in vulkan" : " only in the reference");
    } else {
      f = "the headers differ" + (d.problem_got.empty() ? std::string() : ": vulkan: " + d.problem_got);
    }
    std::printf("  %s\n", f.c_str());
    first(FirstDifference{.what = "spill", .frame = frame, .cell = cell, .text = f});
  }
  check("frame " + std::to_string(frame) + ": spill list", ok, line, f);
}

bool DiffRun::through_timing_cell(const Ray& ray) const {
  if (timing_cells_.empty()) return false;
  const sh::GridParams& g = ref_->params();
  try {
    const reference::ExplainRecord rec = ref_->explain_ray(ray);
    for (const sh::ExplainEvent& e : rec.events)
      if (e.kind == sh::kEvCell || e.kind == sh::kEvCellSkipped || e.kind == sh::kEvSkip) {
        const size_t c = (size_t(e.cell.z) * g.cells.y + e.cell.y) * g.cells.x + e.cell.x;
        if (timing_cells_.count(c)) return true;
      }
  } catch (const Error&) {
  }
  return false;
}

// Every hit: the glossy bounce off the reference's gather buffer (ray i = pixel i, unused where
// the pixel has none) and the primary rays (ray w*h + i = pixel i).
void DiffRun::diff_hits(uint32_t frame, float time) {
  const uint32_t w = o_.width, h = o_.height;
  const size_t pixels = size_t(w) * h;
  const GatherBuffer gather = reference_gather(scene_, grid_, w, h, time);
  std::vector<Ray> rays = bounce_rays(scene_, gather, frame);
  const std::vector<Ray> primary = camera_rays(scene_.frame_camera(), w, h);
  rays.insert(rays.end(), primary.begin(), primary.end());
  std::vector<Hit> want(rays.size()), got(rays.size());
  {
    Progress progress("frame " + std::to_string(frame) + ": reference trace", rays.size());
    ProgressTracer traced(*ref_, progress);
    traced.trace(rays, want);
  }
  gpu_->trace(rays, got);
  if (o_.inject == "hit" && frame == 0)  // the first primary ray that hits: another triangle
    for (size_t i = pixels; i < rays.size(); ++i)
      if (!is_miss(got[i])) {
        got[i].triangle ^= 1u;
        break;
      }
  reference::HitDiff d = reference::compare_hits(want, got);
  total_rays_ += d.rays;
  total_identical_ += d.identical;
  total_discrete_ += d.discrete.size();
  // Float-only differences: within the stated bounds or not.
  std::vector<size_t> beyond_rays;
  float max_duv = 0.0f;
  for (size_t i : d.differing) {
    const Hit& a = want[i];
    const Hit& b = got[i];
    if (a.instance != b.instance || a.triangle != b.triangle || a.flags != b.flags || a.cells != b.cells ||
        a.tests != b.tests)
      continue;
    const float duv = std::max(std::abs(a.u - b.u), std::abs(a.v - b.v));
    max_duv = std::max(max_duv, duv);
    if (reference::ulp_distance(a.t, b.t) > o_.ulps_t || duv > o_.abs_uv) beyond_rays.push_back(i);
  }
  size_t beyond = beyond_rays.size();
  size_t first_beyond = 0;  // the first record beyond the float bounds, where `beyond` > 0
  if (!beyond_rays.empty()) first_beyond = beyond_rays.front();
  total_beyond_ += beyond;
  char line[512];
  std::snprintf(line, sizeof line,
                "%zu rays: %zu identical in bits; %zu differ only in floats (t within %u ulps, u/v within %.3g), %zu "
                "of them beyond the bounds (%u ulps in t, %.3g in u/v); %zu differ in the hit itself (instance, "
                "triangle, flags, cells or tests)",
                d.rays, d.identical, d.same_discrete - d.identical, d.max_ulps_t, double(max_duv), beyond, o_.ulps_t,
                double(o_.abs_uv), d.discrete.size());
  std::printf("frame %u: %s\n", frame, line);
  size_t excused = 0;
  if (!timing_.empty() && !(d.discrete.empty() && beyond == 0)) {
    // A record that differs only where its ray passes a cell whose contents differ by design is
    // said and counted, not a difference of the port; every other one still is
    const auto keep = [&](std::vector<size_t>& v) {
      std::vector<size_t> kept;
      for (size_t i : v)
        if (through_timing_cell(rays[i])) ++excused;
        else kept.push_back(i);
      const size_t dropped = v.size() - kept.size();
      v = std::move(kept);
      return dropped;
    };
    total_discrete_ -= keep(d.discrete);
    total_beyond_ -= keep(beyond_rays);
    beyond = beyond_rays.size();
    first_beyond = beyond_rays.empty() ? 0 : beyond_rays.front();
    total_timing_ += excused;
    if (excused)
      std::printf("frame %u: %zu hit record(s) not held to bits: their rays pass %s\n", frame, excused, timing_.c_str());
  }
  const bool ok = d.discrete.empty() && beyond == 0;
  std::string f;
  if (!ok) {
    const size_t i = !d.discrete.empty() ? d.discrete.front() : first_beyond;
    const bool bounce = i < pixels;
    const size_t p = i % pixels;
    const uint32_t x = uint32_t(p % w), y = uint32_t(p / w);
    const sh::GridParams& g = ref_->params();
    // The scene cell of the hit the reference reports (or the port's, where the reference misses)
    const Hit& at = !is_miss(want[i]) ? want[i] : got[i];
    std::optional<glm::uvec3> cell;
    if (!is_miss(at) && std::isfinite(at.t)) cell = sh::cell_of_point(g, rays[i].org + at.t * rays[i].dir);
    f = std::string("first: pixel (") + std::to_string(x) + ", " + std::to_string(y) + "), " +
        (bounce ? "bounce" : "primary") + " ray" +
        (cell ? ", the " + std::string(!is_miss(want[i]) ? "reference's" : "port's") + " hit in scene cell " +
                    cell_text(*cell)
              : std::string(", both miss")) +
        ": " + reference::hex_ray(rays[i]) + "\n  reference " + reference::hex_hit(want[i]) + "\n  vulkan    " +
        reference::hex_hit(got[i]);
    FirstDifference fd{.what = "hit", .frame = frame, .cell = cell, .pixel = glm::uvec2(x, y),
                       .ray_kind = bounce ? "bounce" : "primary", .text = f,
                       .explain = explain_command(o_, x, y, !bounce, time, frame)};
    std::printf("  %s\n  shown by: %s\n", f.c_str(), fd.explain.c_str());
    if (!first_) {
      // The accounts of the first difference; one that cannot be made (a ray of more events than
      // the explain buffer holds) is said, and the difference still ends the run with exit 3
      try {
        const reference::ExplainRecord a = ref_->explain_ray(rays[i]);
        const reference::ExplainRecord b = gpu_->explain_ray(rays[i]);
        std::printf("== reference's account ==\n%s\n== shader's account ==\n%s\n", reference::to_text(a).c_str(),
                    reference::to_text(b).c_str());
      } catch (const Error& e) {
        std::printf("  (no step-by-step account of it: %s)\n", e.what());
      }
    }
    first(std::move(fd));
  }
  check("frame " + std::to_string(frame) + ": hit records", ok,
        excused ? std::string(line) + "; " + std::to_string(excused) + " not held to bits (" + timing_ + ")" : std::string(line),
        f);
}

// The compute gather's rasterizer (bins, tiles, pixels rejected by its edge functions, tiles culled
// by depth) against the same gather testing every pixel of every triangle's box: the gather
// buffers identical in bits (the rasterizer only skips pairs the ray test rejects or that lose).
void DiffRun::diff_gather_boxes(uint32_t frame, const GatherBuffer& raster) {
  if (!boxes_frame_)
    boxes_frame_ = std::make_unique<vulkan::VulkanFrame>(
        *gpu_, scene_,
        vulkan::FrameOptions{.width = o_.width, .height = o_.height, .shadows = shadows_for(o_.shadows, scene_),
                             .gather = vulkan::GatherMode::boxes});
  boxes_frame_->render(frame);
  const GatherBuffer boxes = boxes_frame_->download_gather();
  size_t differ = 0;
  std::optional<size_t> first_pixel;
  for (size_t p = 0; p < boxes.size(); ++p) {
    const bool same = raster.launch_ref[p] == boxes.launch_ref[p] && raster.valid[p] == boxes.valid[p] &&
                      std::memcmp(&raster.hit[p].t, &boxes.hit[p].t, sizeof(float)) == 0 &&
                      std::memcmp(&raster.position[p], &boxes.position[p], sizeof(glm::vec3)) == 0 &&
                      std::memcmp(&raster.normal[p], &boxes.normal[p], sizeof(glm::vec3)) == 0 &&
                      std::memcmp(&raster.uv[p], &boxes.uv[p], sizeof(glm::vec2)) == 0 &&
                      raster.material[p] == boxes.material[p];
    if (!same && differ++ == 0) first_pixel = p;
  }
  const uint32_t w = o_.width;
  std::string f;
  if (first_pixel)
    f = "first: pixel (" + std::to_string(*first_pixel % w) + ", " + std::to_string(*first_pixel / w) +
        "): rasterizer ref " + std::to_string(raster.launch_ref[*first_pixel]) + " t " +
        std::to_string(raster.hit[*first_pixel].t) + ", boxes ref " + std::to_string(boxes.launch_ref[*first_pixel]) +
        " t " + std::to_string(boxes.hit[*first_pixel].t);
  const std::string line = "GPU gather: rasterizer against every pixel of the boxes: " + std::to_string(differ) + " of " +
                           std::to_string(boxes.size()) + " pixels differ in bits";
  std::printf("frame %u: %s\n", frame, line.c_str());
  if (!f.empty()) std::printf("  %s\n", f.c_str());
  check("frame " + std::to_string(frame) + ": GPU gather rasterizer", differ == 0, line, f);
}

// The GPU frame's own passes (vulkan/frame.h): the bounce rays it makes from its own gather
// against bounce_rays() of that gather (bits), its shadow rays (a scene with lights) against
// shadow_rays() of that gather (bits), and its trace of each against the reference's.
void DiffRun::diff_gpu_frame(uint32_t frame, float time) {
  if (!gpu_frame_)
    gpu_frame_ = std::make_unique<vulkan::VulkanFrame>(
        *gpu_, scene_,
        vulkan::FrameOptions{.width = o_.width, .height = o_.height, .shadows = shadows_for(o_.shadows, scene_),
                             .sort_bits = o_.sort_bits, .traces_together = o_.traces == "together"});
  vulkan::VulkanFrame& fr = *gpu_frame_;
  fr.render(frame);
  const uint32_t w = o_.width;
  const size_t pixels = size_t(o_.width) * o_.height;
  GatherBuffer gpu_gather = fr.download_gather();
  gpu_gather.time = time;
  const GatherBuffer cpu = reference_gather(scene_, grid_, o_.width, o_.height, time);
  size_t same_launch = 0;
  for (size_t p = 0; p < cpu.size(); ++p) same_launch += cpu.launch_ref[p] == gpu_gather.launch_ref[p];
  // The compute gather keeps the CPU's triangle on every pixel (docs/SPEC.md, "The gather as a
  // rasterizer"), but where the eye lies within a hair of a triangle's plane and the CPU's hit is
  // nearer than the frame's near plane (the scene's extent x 1e-6): those pixels are not counted
  size_t gather_mismatch = 0;
  std::optional<size_t> first_gather;
  if (fr.gather_mode() == vulkan::GatherMode::compute) {
    const Camera cam = scene_.frame_camera();
    const CameraFrame cf = camera_frame(cam);
    const float near_plane = vulkan::frame_near_plane(scene_);
    for (size_t p = 0; p < cpu.size(); ++p) {
      if (cpu.launch_ref[p] == gpu_gather.launch_ref[p]) continue;
      if (cpu.valid[p] && glm::dot(cpu.position[p] - cam.eye, cf.forward) < near_plane) continue;
      if (gather_mismatch++ == 0) first_gather = p;
    }
  }
  std::string f;
  if (first_gather) {
    const size_t p = *first_gather;
    f = "first: pixel (" + std::to_string(p % w) + ", " + std::to_string(p / w) + "), the gather's triangle: reference " +
        std::to_string(cpu.launch_ref[p]) + " t " + std::to_string(cpu.hit[p].t) + ", vulkan " +
        std::to_string(gpu_gather.launch_ref[p]) + " t " + std::to_string(gpu_gather.hit[p].t);
    first(FirstDifference{.what = "gpu-frame", .frame = frame, .pixel = glm::uvec2(uint32_t(p % w), uint32_t(p / w)),
                          .ray_kind = "primary", .text = f});
  }
  // One kind of the frame's rays (index % pixels = the pixel) and their hits against the reference's.
  struct Count {
    size_t used = 0, ray_mismatch = 0, hit_mismatch = 0, excused = 0;
  };
  auto compare = [&](const char* kind, const std::vector<Ray>& want_rays, const std::vector<Ray>& got_rays,
                     const std::vector<Hit>& got, bool any_hit) {
    Count c;
    std::optional<size_t> first_ray;
    for (size_t p = 0; p < want_rays.size(); ++p) {
      c.used += !is_unused(want_rays[p]);
      if (std::memcmp(&want_rays[p], &got_rays[p], sizeof(Ray)) != 0 && c.ray_mismatch++ == 0) first_ray = p;
    }
    std::vector<Hit> want(want_rays.size());
    if (any_hit)
      ref_->trace_any(want_rays, want);  // shadow rays: any hit, as the frame traces them
    else
      ref_->trace(want_rays, want);
    reference::HitDiff d = reference::compare_hits(want, got);
    c.hit_mismatch = d.rays - d.identical;
    // First-empty insertion on the image layout keeps a cell's slots in the order the references
    // arrived, which differs between runs and devices by design: any hit stops at the first
    // accepted in that order, so which triangle and how many tests may differ. Hit or miss may not
    if (any_hit && grid_.insertion == reference::Insertion::first_empty && (ref_->params().flags & sh::kGridCompact) == 0u) {
      d.differing.clear();
      for (size_t i = 0; i < want.size(); ++i)
        if (is_miss(want[i]) != is_miss(got[i])) d.differing.push_back(i);
      c.hit_mismatch = d.differing.size();
    }
    // Grids that differ by design (timing_): a ray through one of those cells may differ too
    if (!timing_.empty()) {
      std::vector<size_t> kept;
      for (size_t i : d.differing)
        if (through_timing_cell(want_rays[i])) ++c.excused;
        else kept.push_back(i);
      d.differing = kept;
    }
    if (f.empty() && (first_ray || !d.differing.empty())) {
      const size_t i = first_ray ? *first_ray : d.differing.front();
      const size_t p = i % pixels;
      f = std::string("first: pixel (") + std::to_string(p % w) + ", " + std::to_string(p / w) + "), " + kind + " " +
          (first_ray ? "ray: reference " + reference::hex_ray(want_rays[i]) + "\n  vulkan    " +
                           reference::hex_ray(got_rays[i])
                     : "hit: " + reference::hex_ray(want_rays[i]) + "\n  reference " + reference::hex_hit(want[i]) +
                           "\n  vulkan    " + reference::hex_hit(got[i]));
      first(FirstDifference{.what = "gpu-frame", .frame = frame, .pixel = glm::uvec2(uint32_t(p % w), uint32_t(p / w)),
                            .ray_kind = kind, .text = f});
    }
    return c;
  };
  Count bounce, shadow;
  if (fr.bounce())
    bounce = compare("bounce", bounce_rays(scene_, gpu_gather, frame), fr.download_rays(), fr.download_hits(), false);
  if (fr.shadows())
    shadow = compare("shadow", shadow_rays(scene_, gpu_gather), fr.download_shadow_rays(), fr.download_shadow_hits(),
                     true);
  const bool raster = fr.gather_mode() == vulkan::GatherMode::raster;
  char line[768];
  std::snprintf(line, sizeof line,
                "GPU frame: %s gather %zu of %zu pixels with the reference's launch triangle%s; %zu bounce rays: %zu "
                "differ in bits from bounce_rays() of the GPU's gather, %zu frame hits differ in bits from the "
                "reference's trace; %s",
                raster ? "raster" : "compute", same_launch, cpu.size(),
                raster ? " (the rest: the rasterizer's tie rules)"
                       : (gather_mismatch == cpu.size() - same_launch
                              ? ""
                              : (" (" + std::to_string(cpu.size() - same_launch - gather_mismatch) +
                                 " others: hits nearer than the near plane)")
                                    .c_str()),
                bounce.used, bounce.ray_mismatch,
                bounce.hit_mismatch,
                fr.shadows() ? (std::to_string(shadow.used) + " shadow rays (" + std::to_string(scene_.lights.size()) +
                                " light(s)): " + std::to_string(shadow.ray_mismatch) +
                                " differ in bits from shadow_rays(), " + std::to_string(shadow.hit_mismatch) +
                                (grid_.insertion == reference::Insertion::first_empty &&
                                         (ref_->params().flags & sh::kGridCompact) == 0u
                                     ? " shadow hits differ in hit or miss (first-empty: a cell's slots in arrival order)"
                                     : " shadow hits differ in bits"))
                                   .c_str()
                             : (scene_.lights.empty() ? "no shadow pass (the scene has no lights)"
                                                      : "no shadow pass (--shadows off)"));
  std::printf("frame %u: %s%s\n", frame, line,
              fr.traces_together() ? "; the bounce and shadow rays traced in one dispatch (--traces together)"
              : fr.bounce() && fr.shadows() && o_.sort_bits == 0u ? "; the bounce and shadow traces apart (--traces apart)"
                                                                  : "");
  if (!f.empty()) std::printf("  %s\n", f.c_str());
  if (fr.gather_mode() == vulkan::GatherMode::compute) diff_gather_boxes(frame, gpu_gather);
  // The sorted rays: the order the trace took them in, checked on its own (the hits above do not
  // depend on it)
  std::string order_problem;
  if (o_.sort_bits != 0u && fr.bounce()) {
    const std::vector<uint32_t> order = fr.download_ray_order();
    const std::vector<Ray> frame_rays = fr.download_rays();
    order_problem = vulkan::ray_order_problem(order, fr.download_ray_order_keys(), frame_rays, o_.sort_bits);
    const std::string text = order_problem.empty()
                                 ? "the order lists every pixel with a ray once (" + std::to_string(order.size()) +
                                       " of " + std::to_string(frame_rays.size()) +
                                       " pixels), its keys in order, ties in pixel order"
                                 : order_problem;
    std::printf("frame %u: sorted rays (%u key bits): %s\n", frame, o_.sort_bits, text.c_str());
    check("frame " + std::to_string(frame) + ": the sorted rays' order", order_problem.empty(), text,
          order_problem.empty() ? "" : "the sorted rays: " + order_problem);
  } else if (o_.sort_bits != 0u) {
    std::printf("frame %u: sorted rays: none to sort (%s has no glossy material: the frame makes no bounce rays)\n",
                frame, scene_.name.c_str());
  }
  const size_t hit_mismatch = bounce.hit_mismatch + shadow.hit_mismatch - bounce.excused - shadow.excused;
  if (bounce.excused + shadow.excused > 0)
    std::printf("frame %u: %zu frame hit(s) not held to bits: their rays pass %s\n", frame,
                bounce.excused + shadow.excused, timing_.c_str());
  total_timing_ += bounce.excused + shadow.excused;
  check("frame " + std::to_string(frame) + ": GPU frame",
        gather_mismatch + bounce.ray_mismatch + shadow.ray_mismatch + hit_mismatch == 0, line, f);
}

void DiffRun::write_reports(int code, double seconds) {
  const char* verdict = code == 0 ? "agree" : code == 3 ? "differ" : "validation";
  if (!o_.json_path.empty()) {
    json j = {{"scene", scene_.name},
              {"device", ctx_->info().name},
              {"build", o_.backend_options.vk_build},
              {"traversal", grid_.traversal == reference::Traversal::paper ? "paper" : "exact"},
              {"insertion", grid_.insertion == reference::Insertion::sorted ? "sorted" : "first-empty"},
              {"width", o_.width},
              {"height", o_.height},
              {"frames", o_.frames},
              {"verdict", verdict},
              {"exit_code", code},
              {"rays", total_rays_},
              {"identical", total_identical_},
              {"another_hit", total_discrete_},
              {"beyond_float_bounds", total_beyond_},
              // records not held to bits (grids that differ by design: first-empty insertion's full
              // cells), which the text counts on a line of its own (the JSON left them out: an
              // outside sweep)
              {"not_held_to_bits", total_timing_},
              {"validation", o_.validation},
              {"validation_messages", messages_},
              {"seconds", seconds}};
    json checks = json::array();
    for (const Check& c : checks_)
      checks.push_back({{"name", c.name}, {"ok", c.ok}, {"detail", c.detail}, {"failure", c.failure}});
    j["checks"] = checks;
    if (first_) {
      json f = {{"what", first_->what}, {"frame", first_->frame}, {"text", first_->text}};
      if (first_->cell) f["cell"] = {first_->cell->x, first_->cell->y, first_->cell->z};
      if (first_->pixel) f["pixel"] = {first_->pixel->x, first_->pixel->y};
      if (!first_->ray_kind.empty()) f["ray_kind"] = first_->ray_kind;
      if (!first_->explain.empty()) f["explain"] = first_->explain;
      j["first_difference"] = f;
    } else {
      j["first_difference"] = nullptr;
    }
    write_file_atomically(o_.json_path, "JSON report", j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n");
  }
  if (!o_.junit_path.empty()) {
    size_t failures = 0;
    for (const Check& c : checks_) failures += !c.ok;
    std::ostringstream x;
    const std::string suite = "gridrt diff " + scene_.name + " (" + o_.backend_options.vk_build + " build, " +
                              (grid_.traversal == reference::Traversal::paper ? "paper" : "exact") + ", " +
                              (grid_.insertion == reference::Insertion::sorted ? "sorted" : "first-empty") + ")";
    x << "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<testsuites>\n  <testsuite name=\"" << xml_escape(suite)
      << "\" tests=\"" << checks_.size() << "\" failures=\"" << failures << "\" errors=\"0\" time=\"" << seconds
      << "\">\n";
    for (const Check& c : checks_) {
      x << "    <testcase classname=\"gridrt.diff\" name=\"" << xml_escape(c.name) << "\">\n";
      if (!c.ok)
        x << "      <failure message=\"" << xml_escape(c.detail) << "\">" << xml_escape(c.failure) << "</failure>\n";
      x << "      <system-out>" << xml_escape(c.detail) << "</system-out>\n    </testcase>\n";
    }
    x << "  </testsuite>\n</testsuites>\n";
    write_file_atomically(o_.junit_path, "JUnit report", x.str());
  }
}

int DiffRun::run() {
  const auto t0 = std::chrono::steady_clock::now();
  if (!o_.json_path.empty()) check_output_path(o_.json_path);
  if (!o_.junit_path.empty()) check_output_path(o_.junit_path);
  if (!o_.json_path.empty() && !o_.junit_path.empty() && !is_stream_output(o_.json_path) &&
      names_same_file(o_.json_path, o_.junit_path))
    throw CLI::ValidationError("--junit", "--json and --junit both name " + o_.junit_path +
                                              ": give each report its own file");
  check_frame_size(o_.width, o_.height);
  // Frame k at --time + k / --fps: the last one within the scene time's limit (1e6 s)
  if (o_.frames > 1 && !(std::abs(double(o_.time) + double(o_.frames - 1) / double(o_.fps)) <= 1.0e6))
    throw CLI::ValidationError("--frames", std::to_string(o_.frames) + " frames at --fps " + std::to_string(o_.fps) +
                                               " from --time " + std::to_string(o_.time) +
                                               " pass 1e6 s, the scene time's limit");
  require_distinct_frame_times(o_.time, 0, o_.frames, o_.fps, "--fps");
  DiffOptions o = o_;
  resolve_image_limit(o.backend_options, true);
  scene_ = load_scene_or_default(o.scene);
  // A report over a file the scene read is refused now, not after the whole diff (an outside sweep)
  if (!o_.json_path.empty()) check_output_allowed(o_.json_path, "JSON report");
  if (!o_.junit_path.empty()) check_output_allowed(o_.junit_path, "JUnit report");
  grid_ = grid_options_for(o.backend_options, scene_);
  vulkan::ContextOptions co = vulkan::ContextOptions::from_env();
  co.validation = o.validation != "off";
  co.best_practices = o.validation == "best-practices";
  co.raster_build = o.backend_options.vk_build != "compute";
  ctx_ = std::make_unique<vulkan::Context>(co);
  const vulkan::VulkanGridOptions vk = vulkan_grid_options(o.backend_options);
  gpu_ = std::make_unique<vulkan::VulkanGridTracer>(*ctx_, grid_, vk);
  ref_ = std::make_unique<reference::ReferenceGridTracer>(grid_);
  std::printf("diff: %s, %ux%u, %u frame(s), traversal %s, insertion %s, spill %s, mailbox %s, Vulkan device %s (%s build), "
              "validation %s\n",
              scene_.name.c_str(), o.width, o.height, o.frames,
              grid_.traversal == reference::Traversal::paper ? "paper" : "exact",
              grid_.insertion == reference::Insertion::sorted ? "sorted" : "first-empty",
              reference::spill_enabled(grid_) ? "on" : "off", plan::mailbox_enabled(grid_) ? "on" : "off",
              ctx_->info().name.c_str(),
              o.backend_options.vk_build.c_str(), o.validation.c_str());
  for (uint32_t frame = 0; frame < o.frames; ++frame) {
    const float time = frame_time(o.time, frame, o.fps);
    if (frame == 0) {
      ref_->build(scene_, time);
      gpu_->build(scene_, time);
    } else {
      ref_->update(time);
      gpu_->update(time);
    }
    timing_.clear();
    timing_cells_.clear();
    diff_images(frame, time);
    diff_spill(frame);
    if (o.gpu_frame) diff_gpu_frame(frame, time);
    diff_hits(frame, time);
  }
  // The validation layer: every message printed, any one fails the run
  if (ctx_->validation()) {
    messages_ = ctx_->messages();
    for (const std::string& m : messages_) std::printf("validation: %s\n", m.c_str());
    check("validation layer", messages_.empty(),
          std::to_string(messages_.size()) + " message(s) from the validation layer" +
              (o.validation == "best-practices" ? " (with best practices)" : ""),
          messages_.empty() ? "" : messages_.front());
  }
  bool same = true;
  for (const Check& c : checks_)
    if (c.name != "validation layer") same = same && c.ok;
  std::printf("%s: %zu of %zu hit records identical in bits, %zu with another hit, %zu beyond the float bounds, over "
              "the frames compared; %zu validation message(s)\n",
              same ? "AGREE" : "DIFFER", total_identical_, total_rays_, total_discrete_, total_beyond_,
              messages_.size());
  if (total_timing_ > 0)
    std::printf("  and %zu hit records not held to bits (grids that differ by design: first-empty insertion with "
                "saturated cells, or an overflowing spill list)\n",
                total_timing_);
  if (first_) {
    std::printf("first difference: frame %u, %s%s%s\n", first_->frame, first_->what.c_str(),
                first_->cell ? (", scene cell " + cell_text(*first_->cell)).c_str() : "",
                first_->pixel ? (", pixel (" + std::to_string(first_->pixel->x) + ", " +
                                 std::to_string(first_->pixel->y) + "), " + first_->ray_kind + " ray")
                                    .c_str()
                              : "");
    if (!first_->explain.empty()) std::printf("  %s\n", first_->explain.c_str());
  }
  const int code = !messages_.empty() ? 4 : !same ? 3 : 0;
  write_reports(code, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
  return code;
}

// The grid and limit options given, as explain takes them (the verb's own options and the scene
// left out), each value as parsed (several joined by commas).
std::string given_grid_flags(const CLI::App* cmd) {
  // The app's limit options given after the verb count too, and a value of several words
  // (--resolution 8 8 8) is joined by commas: the printed command lost both (an outside sweep)
  static const char* const kOwn[] = {"--width", "--height", "--time", "-t", "--frames", "--fps", "--ulps",
                                     "--uv-tolerance", "--gpu-frame", "--shadows", "--validation", "--json", "--junit",
                                     "--inject-difference"};
  const std::vector<std::string>& args = command_line;
  size_t k = 0;
  while (k < args.size() && args[k] != "diff") ++k;
  std::string out;
  for (++k; k < args.size(); ++k) {
    const std::string& a = args[k];
    // The scene, and values that look like options: a negative number (--time -.5)
    if (a.size() < 2 || a[0] != '-' || std::isdigit(static_cast<unsigned char>(a[1])) || a[1] == '.') continue;
    std::string name = a.substr(0, a.find('='));
    // -t0.5: a short option with its value glued on (it was printed beside the --time given)
    const bool glued = a.size() > 2 && a[0] == '-' && a[1] != '-';
    if (glued) name = a.substr(0, 2);
    const CLI::Option* opt = cmd->get_option_no_throw(name);
    if (!opt && cmd->get_parent()) opt = cmd->get_parent()->get_option_no_throw(name);
    const bool own = std::find(std::begin(kOwn), std::end(kOwn), name) != std::end(kOwn);
    if (!own) out += " " + shell_quote(a);
    if (!opt || opt->get_expected_min() == 0 || a.find('=') != std::string::npos || glued) continue;
    // The words of its value: as many items as it takes (a word may hold several, comma separated)
    const int items = std::max(1, opt->get_items_expected_max());
    std::string value;
    int have = 0;
    while (have < items && k + 1 < args.size() &&
           !(args[k + 1].size() > 1 && args[k + 1][0] == '-' && !std::isdigit(static_cast<unsigned char>(args[k + 1][1])) &&
             args[k + 1][1] != '.')) {
      const std::string& w = args[++k];
      have += 1 + int(std::count(w.begin(), w.end(), ','));
      value += (value.empty() ? "" : ",") + w;
    }
    if (!own && !value.empty()) out += " " + shell_quote(value);
  }
  return out;
}

}  // namespace
#endif

void add_diff_command(CLI::App& app) {
#ifdef GRIDRT_HAVE_VULKAN
  auto o = std::make_shared<DiffOptions>();
  CLI::App* cmd = app.add_subcommand(
      "diff",
      "Run the CPU reference and the Vulkan port on a scene: grid images and every hit, over frames, with the "
      "validation layer on. Exit 0 agree, 1 bad input, 2 bad command line, 3 differ, 4 validation messages");
  add_scene_argument(cmd, o->scene);
  add_image_size(cmd, o->width, o->height, "of the gather buffer");
  cmd->add_option("--time,-t", o->time, "Scene time in seconds")->check(CLI::Range(-1.0e6f, 1.0e6f));
  add_backend_options(cmd, o->backend_options);
  cmd->add_option("--frames", o->frames, "Animated frames to compare (the first is a build, then updates)")
      ->check(CLI::Range(1u, 10000u));
  cmd->add_option("--fps", o->fps, "Frames per second")->check(CLI::Range(1.0e-3f, 1.0e6f));
  cmd->add_option("--ulps", o->ulps_t,
                  "Allow t of otherwise identical hits to differ by this many ulps (drivers whose division is "
                  "not correctly rounded; default 0: bit for bit)");
  cmd->add_option("--uv-tolerance", o->abs_uv, "Allow u and v of otherwise identical hits to differ by this much")
      ->check(non_negative_number());
  cmd->add_flag("--gpu-frame", o->gpu_frame,
                "Also run the GPU frame's own passes (gather, bounce, trace) and compare its bounce rays "
                "and hits, bit for bit, with the reference's from the same gather");
  add_shadows_option(cmd, o->shadows);  // the GPU frame's shadow pass (a scene of more than 8 lights: off)
  add_sort_rays_option(cmd, o->sort_bits,
                       "With --gpu-frame: its bounce rays sorted on the GPU by the top BITS bits of their keys before "
                       "their trace (0, the default: 8x8 pixel tiles); the order is checked, and the rays and hits "
                       "must be the reference's all the same");
  add_traces_option(cmd, o->traces);
  add_choice(cmd, "--validation", o->validation, {"on", "best-practices", "off"},
                  "The Khronos validation layer (with synchronization validation): on (default; any message "
                  "fails the run with exit 4), best-practices (also the layer's best-practices checks), off");
  add_choice(cmd, "--inject-difference", o->inject, {"texel", "hit"},
                  "For testing the reports: change one texel or one hit record of the port's before comparing")
      ->group("");  // hidden
  add_json_option(cmd, o->json_path, "the result");
  cmd->add_option("--junit", o->junit_path, "Also write the result as a JUnit XML report to this file")->type_name("FILE");
  cmd->callback([o, cmd] {
    check_traversal_options(cmd, o->backend_options);
    // Options that did nothing here, without a word (an outside sweep)
    if (cmd->get_option("--fps")->count() > 0 && o->frames <= 1)
      throw OptionsError("--fps spaces the frames of --frames: give --frames 2 or more");
    if (cmd->get_option("--sort-rays")->count() > 0 && !o->gpu_frame)
      throw OptionsError("--sort-rays orders the GPU frame's bounce trace: it needs --gpu-frame");
    if (cmd->get_option("--traces")->count() > 0 && !o->gpu_frame)
      throw OptionsError("--traces chooses how the GPU frame dispatches its bounce and shadow traces: it needs --gpu-frame");
    if (cmd->get_option("--traces")->count() > 0 && o->sort_bits != 0u)
      throw OptionsError("--traces chooses whether the tiles' bounce trace shares its dispatch with the shadow trace; "
                         "--sort-rays traces the bounce rays through a list, always apart: it does nothing (leave one out)");
    if (cmd->get_option("--shadows")->count() > 0 && !o->gpu_frame)
      throw OptionsError("--shadows switches the GPU frame's shadow pass: it needs --gpu-frame");
    if (cmd->get_option("--fallback-cpu")->count() > 0)
      throw OptionsError("--fallback-cpu does not apply to diff: it compares the CPU reference with the Vulkan port, "
                         "and needs a Vulkan device");
    o->explain_flags = given_grid_flags(cmd);
    int code = 0;
    try {
      code = DiffRun(*o).run();
    } catch (const Error& e) {
      // The Vulkan port's way out names a backend diff does not take: diff needs the device (an
      // outside sweep); without one, verify checks the CPU reference against Embree
      std::string what = e.what();
      const std::string way = "use --backend cpu";
      // only where the device is missing: a device that lacks a feature, or a far eye, is another story
      if (what.find(way) == std::string::npos || what.find("no Vulkan device") == std::string::npos) throw;
      for (size_t at = what.find(way); at != std::string::npos; at = what.find(way, at + 1))
        what.replace(at, way.size(), "diff needs the Vulkan port (without it, gridrt verify checks the CPU reference "
                                     "against Embree)");
      throw Error(what);
    }
    if (code != 0) throw ExitStatus{code};
  });
#else
  (void)app;
#endif
}

}  // namespace gridrt::app
