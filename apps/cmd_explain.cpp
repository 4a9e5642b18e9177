// gridrt explain: every step of one ray through the grid, by the CPU reference, and with
// --backend vulkan the shader's own record beside it, aligned event by event.
//   which ray   --pixel X,Y with --kind primary|bounce|shadow (the ray the frame makes for the
//               pixel; --gpu-frame: the GPU frame's own), or --ray / --ray-file (any ray)
//   how         full (every float in decimal and hex) or --brief on stdout; --json FILE
//   pictures    --export ray.obj, --svg ray.svg, --html page.html (the step-by-step viewer)
#include <cctype>
#include <cmath>
#include <cstring>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <sstream>

#include "apps/backends.h"
#include "apps/commands.h"
#include "gridrt/common/camera.h"
#include "gridrt/common/gather.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/shade.h"
#include "gridrt/common/shared/shadow.h"
#include "gridrt/reference/explain_export.h"
#include "gridrt/plan/explain_format.h"
#include "gridrt/reference/grid.h"
#ifdef GRIDRT_HAVE_VULKAN
#  include "gridrt/vulkan/frame.h"
#  include "gridrt/vulkan/grid.h"
#endif

namespace gridrt::app {

namespace {

namespace sh = gridrt::shared;
using reference::Traversal;

const char* traversal_name(Traversal t) { return t == Traversal::exact ? "exact" : "paper"; }

// out.svg -> out_2.svg for the third of several rays.
std::string numbered(const std::string& path, size_t i, size_t n) {
  if (n <= 1) return path;
  const std::filesystem::path p(path);
  return (p.parent_path() / (p.stem().string() + "_" + std::to_string(i) + p.extension().string())).string();
}

struct ExplainOptions {
  std::string scene;
  std::string backend = "cpu";
  uint32_t width = 960, height = 540;
  float time = 0.0f;
  uint32_t frame = 0;
  bool frame_given = false;  // --frame on the command line
  BackendOptions backend_options;
  std::vector<uint32_t> pixel;
  std::string kind = "auto";
  bool primary = false;
  std::vector<std::string> rays;
  std::string ray_file;
  bool gpu_frame = false;
  std::optional<uint32_t> light;
  bool brief = false;
  std::string json;  // --json FILE
  std::string obj, svg, html;
  bool traversal_given = false;
};

// One ray to explain and what to say of it.
struct Item {
  std::string label;
  std::vector<std::string> header;
  Ray ray{};
  Traversal traversal = Traversal::paper;
  uint32_t mode = shared::kTraceClosestHit;  // shadow rays: kTraceAnyHit, as the frame traces them
  std::optional<Hit> frame_hit;  // --gpu-frame: the frame's own hit of this ray
  // Traced on the gather's grid (plan::gather_options: the exact traversal with the watertight test),
  // as the frame traces a pixel's primary ray, not on the grid of the options given
  bool gather_grid = false;
};

const char* policy_name(reference::GridOptions::CapacityPolicy p) {
  using P = reference::GridOptions::CapacityPolicy;
  return p == P::trace_cost ? "trace-cost" : p == P::no_saturation ? "no-saturation" : "percentile";
}

// A grid in words: resolution, cell size, capacity, how they were chosen.
std::string grid_words(const reference::GridOptions& o, const Scene& scene, const sh::GridParams& g) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "%ux%ux%u cells of %.6g, capacity %u", g.cells.x, g.cells.y, g.cells.z,
                double(g.cell_size), g.capacity);
  std::string s = buf;
  std::string set;
  if (o.resolution || o.cell_size || scene.grid.resolution || scene.grid.cell_size) set += "resolution";
  if (o.capacity || scene.grid.capacity) set += std::string(set.empty() ? "" : " and ") + "capacity";
  s += set.empty() ? std::string(" (chosen by the ") + policy_name(o.capacity_policy) + " policy)"
                   : " (" + set + " set by the scene or the command line)";
  s += (g.flags & sh::kGridSpill) ? ", spill list on" : "";
  s += (g.flags & sh::kGridGapFill) ? ", gap-fill on" : "";
  return s;
}

// The grids, tracers and frames an explain needs, made on first use.
class Explainer {
 public:
  Explainer(const ExplainOptions& o, const Scene& scene)
      : o_(o), scene_(scene), grid_(grid_options_for(o.backend_options, scene)) {}

  const reference::GridOptions& options() const { return grid_; }
  reference::GridOptions options(Traversal t) const {
    reference::GridOptions g = grid_;
    g.traversal = t;
    return g;
  }
  reference::ReferenceGridTracer& reference(Traversal t) {
    auto& p = reference_[t];
    if (!p) {
      p = std::make_unique<reference::ReferenceGridTracer>(options(t));
      p->build(scene_, o_.time);
    }
    return *p;
  }
  std::string grid(Traversal t) { return grid_words(options(t), scene_, reference(t).params()); }
  // The gather's grid: the frame's primary rays are traced there (plan::gather_options)
  reference::ReferenceGridTracer& gather_reference() {
    if (!gather_) {
      gather_ = std::make_unique<reference::ReferenceGridTracer>(plan::gather_options(grid_));
      build_gather_grid(*gather_, scene_, o_.time);
    }
    return *gather_;
  }

#ifdef GRIDRT_HAVE_VULKAN
  vulkan::VulkanGridTracer& gpu(Traversal t) {
    if (!context_) context_ = std::make_unique<vulkan::Context>();
    auto& p = gpu_[t];
    if (!p) {
      const vulkan::VulkanGridOptions vk = vulkan_grid_options(o_.backend_options);
      p = std::make_unique<vulkan::VulkanGridTracer>(*context_, options(t), vk);
      p->build(scene_, o_.time);
    }
    return *p;
  }
  vulkan::VulkanGridTracer& gather_gpu() {
    if (!context_) context_ = std::make_unique<vulkan::Context>();
    if (!gather_gpu_) {
      const vulkan::VulkanGridOptions vk = vulkan_grid_options(o_.backend_options);
      gather_gpu_ = std::make_unique<vulkan::VulkanGridTracer>(*context_, plan::gather_options(grid_), vk);
      build_gather_grid(*gather_gpu_, scene_, o_.time);
    }
    return *gather_gpu_;
  }
  // The GPU frame's passes at --width x --height (gather, bounce, trace) on the grid of the
  // frame's traversal; its read-backs.
  struct GpuFrame {
    GatherBuffer gather;
    std::vector<Ray> rays;
    std::vector<Hit> hits;
    bool bounce = false;
    std::string gather_mode;
  };
  const GpuFrame& gpu_frame() {
    if (!frame_) {
      vulkan::VulkanGridTracer& g = gpu(grid_.traversal);
      vulkan::VulkanFrame f(g, scene_, vulkan::FrameOptions{.width = o_.width, .height = o_.height});
      f.render(o_.frame);
      frame_ = std::make_unique<GpuFrame>();
      frame_->gather = f.download_gather();
      frame_->gather.time = o_.time;
      frame_->bounce = f.bounce();
      if (f.bounce()) {
        frame_->rays = f.download_rays();
        frame_->hits = f.download_hits();
      }
      frame_->gather_mode = f.gather_mode() == vulkan::GatherMode::raster ? "raster" : "compute";
    }
    return *frame_;
  }
  std::string device() { return context_ ? context_->info().name : ""; }
  // The validation layer's messages (GRIDRT_VALIDATION=1), if any
  std::vector<std::string> validation_messages() const {
    return context_ ? context_->messages() : std::vector<std::string>{};
  }
#endif

  // The reference's gather buffer, its one pixel traced as the frame's CPU gather traces it
  GatherBuffer reference_gather_pixel(uint32_t x, uint32_t y) {
    return reference_gather(scene_, grid_, o_.width, o_.height, o_.time, size_t(y) * o_.width + x);
  }

 private:
  const ExplainOptions& o_;
  const Scene& scene_;
  reference::GridOptions grid_;
  std::map<Traversal, std::unique_ptr<reference::ReferenceGridTracer>> reference_;
  std::unique_ptr<reference::ReferenceGridTracer> gather_;
#ifdef GRIDRT_HAVE_VULKAN
  std::unique_ptr<vulkan::Context> context_;
  std::map<Traversal, std::unique_ptr<vulkan::VulkanGridTracer>> gpu_;
  std::unique_ptr<vulkan::VulkanGridTracer> gather_gpu_;
  std::unique_ptr<GpuFrame> frame_;
#endif
};

std::string ray_words(const Ray& r) {
  char buf[256];
  std::snprintf(buf, sizeof buf, "org (%.7g, %.7g, %.7g) dir (%.7g, %.7g, %.7g) t in (%.7g, %.7g)", double(r.org.x),
                double(r.org.y), double(r.org.z), double(r.dir.x), double(r.dir.y), double(r.dir.z), double(r.tmin),
                double(r.tmax));
  return buf;
}

// The rays of a pixel: the frame's rays of the kind asked for.
std::vector<Item> pixel_items(const ExplainOptions& o, const Scene& scene, Explainer& ex) {
  const uint32_t x = o.pixel[0], y = o.pixel[1];
  if (x >= o.width || y >= o.height)
    throw OptionsError("pixel " + std::to_string(x) + "," + std::to_string(y) + " lies outside the " +
                       std::to_string(o.width) + "x" + std::to_string(o.height) + " image");
  const size_t p = size_t(y) * o.width + x;
  const Traversal frame_t = ex.options().traversal;
  char where[128];
  std::snprintf(where, sizeof where, "pixel %u,%u of %ux%u at t = %.9g", x, y, o.width, o.height, double(o.time));
  // Which traversal and grid the frame uses
  std::vector<std::string> frame_words;
  frame_words.push_back("the frame (gridrt render, CPU): primary rays (the gather buffer) by the exact traversal on " +
                        ex.grid(Traversal::exact) + "; the glossy bounce and --shadows' shadow rays by the " +
                        traversal_name(frame_t) + " traversal on " + ex.grid(frame_t));
  // The pixel's gather buffer: the reference's, or the GPU frame's own
  GatherBuffer gather;
  std::vector<Ray> bounces;
  std::optional<Hit> frame_hit;
  std::string gpu_gather;
  if (o.gpu_frame) {
#ifdef GRIDRT_HAVE_VULKAN
    const auto& f = ex.gpu_frame();
    frame_words.push_back("the GPU frame (gridrt render --backend vulkan): gather by its " + f.gather_mode +
                          " pass (no grid traversal), bounce rays by its bounce pass, traced by the " +
                          traversal_name(frame_t) + " traversal; explained below: the GPU frame's own rays");
    gather = f.gather;
    gpu_gather = f.gather_mode;
    bounces = f.bounce ? f.rays : bounce_rays(scene, gather, o.frame);
    if (f.bounce && !is_unused(f.rays[p])) frame_hit = f.hits[p];
#endif
  } else {
    gather = ex.reference_gather_pixel(x, y);
    bounces = bounce_rays(scene, gather, o.frame);
  }
  std::string kind = o.primary ? "primary" : o.kind;
  if (kind == "auto") kind = is_unused(bounces[p]) ? "primary" : "bounce";
  // The pixel has no glossy bounce: its ray is the primary one, which --frame does not change (it
  // was accepted without a word: an outside sweep), as --kind primary refuses it
  if (kind == "primary" && o.kind == "auto" && !o.primary && o.frame_given)
    throw OptionsError("--frame seeds the glossy bounce's random numbers; pixel " + std::to_string(x) + "," +
                       std::to_string(y) + " has no glossy bounce (its ray is the primary one): it does nothing (leave it out)");
  std::vector<Item> items;
  if (kind == "primary") {
    Item it;
    it.ray = camera_ray(scene.frame_camera(), o.width, o.height, x, y);
    it.traversal = o.traversal_given ? frame_t : Traversal::exact;
    // On the gather's grid, with its test (the watertight one: plan::gather_options), as the frame
    // traces the pixel: the explain's own options may give another test, and on coplanar faces
    // another triangle than the pixel shows (an outside sweep's find)
    it.gather_grid = !o.traversal_given;
    it.label = std::string(where) + ": the primary ray";
    it.header = {it.label + (o.kind == "auto" && !o.primary ? " (the pixel has no glossy bounce)" : "")};
    it.header.insert(it.header.end(), frame_words.begin(), frame_words.end());
    const std::string gather_test = "the watertight test";  // whatever the trace's (plan::gather_options)
    it.header.push_back(std::string("explained by the ") + traversal_name(it.traversal) + " traversal" +
                        (it.gather_grid ? " on the gather's grid (" + gather_test + "), as the frame's gather traces it"
                                        : " (asked for with --traversal, on the options given; the frame's gather "
                                          "uses the exact traversal with " + gather_test + ")") +
                        (o.gpu_frame ? " (the GPU frame gathers by its " + gpu_gather +
                                           " pass: the same camera rays, not traced through the grid)"
                                     : std::string()));
    items.push_back(it);
  } else if (kind == "bounce") {
    if (is_unused(bounces[p]))
      throw Error(std::string(where) + " has no glossy bounce ray (" +
                  (!gather.valid[p] ? "its primary ray meets no surface" : "its surface is not glossy") + ")");
    Item it;
    it.ray = bounces[p];
    it.traversal = frame_t;
    it.frame_hit = frame_hit;
    it.label = std::string(where) + ": the glossy bounce ray" + (o.gpu_frame ? " of the GPU frame" : "");
    it.header = {it.label + (o.gpu_frame ? " (made by the GPU frame's bounce pass from its own gather)"
                                         : " (bounce_rays() off the reference's gather buffer, frame " +
                                               std::to_string(o.frame) + ")")};
    it.header.insert(it.header.end(), frame_words.begin(), frame_words.end());
    it.header.push_back(std::string("explained by the ") + traversal_name(it.traversal) +
                        " traversal, as the frame traces its bounce");
    items.push_back(it);
  } else {  // shadow
    if (!gather.valid[p]) throw Error(std::string(where) + ": the primary ray meets no surface, so no shadow rays");
    if (scene.lights.empty())
      throw Error("the scene has no lights: shading uses a headlight, which casts no shadow rays");
    // The frame traces no shadow ray on a scene of more lights than it takes: none to explain
    // (a ninth light's ray was explained though render refuses it; an outside sweep's find)
    check_shadow_lights(scene);
    if (o.light && *o.light >= scene.lights.size())
      throw Error("light " + std::to_string(*o.light) + " does not exist (the scene has " +
                  std::to_string(scene.lights.size()) + ")");
    for (uint32_t l = 0; l < scene.lights.size(); ++l) {
      if (o.light && *o.light != l) continue;
      const Ray r = shared::shadow_ray(gather.position[p], gather.normal[p], gather.launch_ref[p],
                                       scene.lights[l].position, scene.lights[l].directional);
      if (is_unused(r)) {
        std::fprintf(stderr, "%s: light %u lies behind the surface: no shadow ray\n", where, l);
        continue;
      }
      Item it;
      it.ray = r;
      it.traversal = frame_t;
      it.mode = shared::kTraceAnyHit;
      it.label = std::string(where) + ": the shadow ray toward light " + std::to_string(l);
      it.header = {it.label + " (" + (scene.lights[l].directional ? "directional" : "a point light") +
                   ", from the primary hit, as render --shadows traces it)"};
      it.header.insert(it.header.end(), frame_words.begin(), frame_words.end());
      it.header.push_back(std::string("explained by the ") + traversal_name(it.traversal) +
                          " traversal for any hit, as render --shadows traces its shadow rays; a hit before the "
                          "light (t < " + (scene.lights[l].directional ? "inf" : "1") + ") is a shadow");
      items.push_back(it);
    }
    if (items.empty()) throw Error(std::string(where) + ": no light lights the surface, so no shadow rays");
  }
  return items;
}

// --ray and --ray-file: each ray explained by the grid's traversal of the options.
std::vector<Item> ray_items(const ExplainOptions& o, const Scene& scene, Explainer& ex) {
  std::vector<Item> items;
  std::vector<Ray> rays;
  // A --ray value is the command line's: a malformed one is exit 2 (it was 1, as a bad file is:
  // an outside sweep); a --ray-file's stay bad input
  for (const std::string& r : o.rays) {
    try {
      rays.push_back(plan::parse_ray(r));
    } catch (const OptionsError&) {
      throw;
    } catch (const Error& e) {
      throw OptionsError(std::string("--ray: ") + e.what());
    }
  }
  if (!o.ray_file.empty())
    for (const Ray& r : plan::read_ray_file(o.ray_file)) rays.push_back(r);
  // A launch reference names a triangle of the scene (instance << 16 | triangle)
  for (size_t i = 0; i < rays.size(); ++i) {
    const uint32_t ref = rays[i].launch_ref;
    if (ref == shared::kNoRef) continue;
    const uint32_t inst = ref >> 16, tri = ref & 0xFFFFu;
    if (inst >= scene.instances.size() || tri >= scene.meshes[scene.instances[inst].mesh].triangle_count())
      throw Error("ray " + std::to_string(i) + ": launch_ref " + std::to_string(inst) + ":" + std::to_string(tri) +
                  " names no triangle of the scene (" + std::to_string(scene.instances.size()) +
                  " instances; none for no surface)");
  }
  const Traversal t = ex.options().traversal;
  for (size_t i = 0; i < rays.size(); ++i) {
    Item it;
    it.ray = rays[i];
    it.traversal = t;
    it.label = "ray " + std::to_string(i) + ": " + ray_words(rays[i]);
    it.header = {it.label,
                 std::string("explained by the ") + traversal_name(t) + " traversal (" +
                     (t == Traversal::exact ? "the frame's gather traversal"
                                            : "the frame's bounce traversal; --traversal exact for its gather's") +
                     ") on " + ex.grid(t)};
    items.push_back(it);
  }
  return items;
}

// One explained ray as JSON: the reference's record, and the shader's with their alignment.
nlohmann::json item_json(const Item& it, const reference::ExplainRecord& want,
                         const std::optional<reference::ExplainRecord>& got, const std::string& device,
                         const plan::ExplainFormat& fmt) {
  nlohmann::json j{{"label", it.label},
                   {"header", it.header},
                   {"traversal", traversal_name(it.traversal)},
                   {"hit", it.mode == shared::kTraceAnyHit ? "any" : "closest"},  // docs/SPEC.md "Any hit"
                   {"reference", plan::explain_json(want, fmt)}};
  if (got) {
    j["device"] = device;
    j["shader"] = plan::explain_json(*got, fmt);
    j["alignment"] = plan::alignment_json(want, *got, plan::align_events(want.events, got->events));
  }
  if (it.frame_hit)
    j["frame_hit"] = {{"instance", it.frame_hit->instance}, {"triangle", it.frame_hit->triangle},
                      {"t", reference::hex(it.frame_hit->t)},
                      {"same_as_reference", std::memcmp(&*it.frame_hit, &want.hit, sizeof(Hit)) == 0}};
  return j;
}

// One explained ray as text: its header, the reference's record, the shader's divergence from it.
void print_item(const Item& it, size_t i, size_t count, const reference::ExplainRecord& want,
                const std::optional<reference::ExplainRecord>& got, const std::string& device,
                const plan::ExplainFormat& fmt) {
  if (count > 1) std::printf("%s== ray %zu (%zu of %zu) ==\n", i ? "\n" : "", i, i + 1, count);  // numbered from 0, as its label and files
  for (const std::string& h : it.header) std::printf("%s\n", h.c_str());
  std::printf("\n== CPU reference ==\n%s", plan::explain_text(want, fmt).c_str());
  if (got) {
    std::printf("\n== Vulkan (%s) ==\n%s", device.c_str(),
                plan::divergence_text(want, *got, fmt, "reference", "shader").c_str());
  }
  if (it.frame_hit) {
    const bool same = std::memcmp(&*it.frame_hit, &want.hit, sizeof(Hit)) == 0;
    std::printf("the GPU frame's own hit of this ray %s the reference's%s\n", same ? "equals" : "DIFFERS from",
                same ? " bit for bit" : "");
  }
}

// --export and --svg: ray i's pictures (numbered where there are several rays).
void write_pictures(const ExplainOptions& o, size_t i, size_t count, const reference::ExplainRecord& want,
                    const reference::GridData& data, const plan::ExplainFormat& fmt, std::vector<std::string>& written) {
  if (!o.obj.empty()) {
    const std::string path = numbered(o.obj, i, count);
    const std::filesystem::path mtl = std::filesystem::path(path).replace_extension(".mtl");
    // Both checked before either is written: a refused OBJ left its .mtl replaced (an outside sweep)
    check_output_allowed(path, "OBJ");
    if (!o.svg.empty()) check_output_allowed(numbered(o.svg, i, count), "SVG");
    // An OBJ streamed to a FIFO or a character device (/dev/stdout) has no folder of its own: no
    // .mtl is written beside it (an outside sweep: /dev/null.mtl was made in /dev), and it names none
    std::error_code ec;
    const std::filesystem::file_status st = std::filesystem::status(path, ec);
    if (!ec && (std::filesystem::is_character_file(st) || std::filesystem::is_fifo(st))) {
      write_file_atomically(path, "OBJ", reference::explain_obj(want, data, ""));
      written.push_back(path + " (a stream: without its materials, no .mtl beside it)");
    } else {
      write_file_atomically(mtl.string(), "OBJ materials", reference::explain_mtl());
      write_file_atomically(path, "OBJ", reference::explain_obj(want, data, mtl.filename().string()));
      written.push_back(path + " (and " + mtl.string() + ")");
    }
  }
  if (!o.svg.empty()) {
    const std::string path = numbered(o.svg, i, count);
    write_file_atomically(path, "SVG", reference::explain_svg(want, data, fmt));
    written.push_back(path);
  }
}

// The most events --json and --html keep over all rays (each is a JSON object of a few KiB, or a
// row of the viewer), so that many rays, or rays through crowded cells, fail named instead of
// exhausting memory.
constexpr size_t kMaxKeptEvents = 200000;

void run_explain(const ExplainOptions& options) {
  // Only where a pixel's ray is explained: --ray and --ray-file make no image (a low --max-pixels
  // refused them for the default size, which they refuse to be given: an outside sweep)
  if (!options.pixel.empty()) check_frame_size(options.width, options.height);
  ExplainOptions o = options;
  const bool vulkan = o.backend == "vulkan";
#ifndef GRIDRT_HAVE_VULKAN
  if (vulkan) throw Error("explain --backend vulkan: this build has no Vulkan (it has: " + backend_list() + ")");
#endif
  for (const std::string* path : {&o.obj, &o.svg, &o.html, &o.json})
    if (!path->empty()) check_output_path(*path);
  resolve_image_limit(o.backend_options, vulkan);
  const Scene scene = load_scene_or_default(o.scene);
  Explainer ex(o, scene);
  const plan::ExplainNames names = plan::ExplainNames::of(scene);
  const plan::ExplainFormat fmt{o.brief, &names};

  // The rays
  const std::vector<Item> items = !o.pixel.empty() ? pixel_items(o, scene, ex) : ray_items(o, scene, ex);
  // Every ray's pictures and the reports named and checked before the first is written: a refused
  // later one left the earlier replaced (an outside sweep), and no two may name one file
  {
    std::vector<std::string> paths;
    for (size_t i = 0; i < items.size(); ++i) {
      if (!o.obj.empty()) {
        paths.push_back(numbered(o.obj, i, items.size()));
        paths.push_back(std::filesystem::path(paths.back()).replace_extension(".mtl").string());
        // The OBJ names its .mtl on a mtllib line, which ends at white space and where '#' starts
        // a comment: such a name wrote an OBJ that opened without its colours (an outside sweep)
        const std::string mtl = std::filesystem::path(paths.back()).filename().string();
        for (const char ch : mtl)
          if (std::isspace(static_cast<unsigned char>(ch)) || std::iscntrl(static_cast<unsigned char>(ch)) || ch == '#')
            throw OptionsError("explain --export: the OBJ's name may not contain spaces, '#' or control characters "
                               "(its mtllib line names the materials by it): '" + mtl + "'");
      }
      if (!o.svg.empty()) paths.push_back(numbered(o.svg, i, items.size()));
    }
    if (!o.html.empty()) paths.push_back(o.html);
    if (!o.json.empty()) paths.push_back(o.json);
    for (size_t a = 0; a < paths.size(); ++a) {
      check_output_allowed(paths[a], "explain output");
      for (size_t b = a + 1; b < paths.size(); ++b)
        if (!is_stream_output(paths[a]) && names_same_file(paths[a], paths[b]))
          throw OptionsError("explain: two outputs name one file, '" + paths[a] + "' (" + paths[b] + ")");
    }
  }

  // Each ray through the reference, and the shader
  nlohmann::json json_rays = nlohmann::json::array();
  std::vector<std::string> written;  // said on stderr after stdout's text, which they would split
  nlohmann::json views = nlohmann::json::array();
  size_t kept = 0;  // events kept for --json and --html (a few KiB each there)
  for (size_t i = 0; i < items.size(); ++i) {
    const Item& it = items[i];
    reference::ReferenceGridTracer& ref = it.gather_grid ? ex.gather_reference() : ex.reference(it.traversal);
    const reference::ExplainRecord want = ref.explain_ray(it.ray, it.mode);
    std::optional<reference::ExplainRecord> got;
    std::string device;
#ifdef GRIDRT_HAVE_VULKAN
    if (vulkan) {
      got = (it.gather_grid ? ex.gather_gpu() : ex.gpu(it.traversal)).explain_ray(it.ray, it.mode);
      device = ex.device();
    }
#endif
    if (!o.json.empty() || !o.html.empty()) {
      kept += want.events.size() + (got ? got->events.size() : 0);
      if (kept > kMaxKeptEvents)
        throw Error("explain: the " + std::to_string(i + 1) + " ray(s) so far leave " + std::to_string(kept) +
                    " events, more than --json and --html keep (" + std::to_string(kMaxKeptEvents) +
                    "; each takes a few KiB there): explain fewer rays at a time, or leave those outputs out");
    }
    if (!o.json.empty()) json_rays.push_back(item_json(it, want, got, device, fmt));
    print_item(it, i, items.size(), want, got, device, fmt);
    write_pictures(o, i, items.size(), want, ref.data(), fmt, written);
    if (!o.html.empty())
      views.push_back(reference::explain_view(it.label, it.header, want, got ? &*got : nullptr, ref.data(), fmt));
  }
  if (!o.json.empty()) {
    write_file_atomically(o.json, "JSON",
                          nlohmann::json{{"scene", scene.name}, {"rays", json_rays}}.dump(
                              1, ' ', false, nlohmann::json::error_handler_t::replace) +
                              "\n");
    written.push_back(o.json);
  }
  if (!o.html.empty()) {
    write_file_atomically(o.html, "HTML viewer", reference::explain_html("gridrt explain: " + scene.name, views));
    written.push_back(o.html);
  }
  std::fflush(stdout);
  for (const std::string& w : written) std::fprintf(stderr, "wrote %s\n", w.c_str());
#ifdef GRIDRT_HAVE_VULKAN
  const std::vector<std::string> messages = ex.validation_messages();
  for (const std::string& m : messages) std::fprintf(stderr, "validation %s\n", m.c_str());
  if (!messages.empty())
    throw Error("the Vulkan validation layer reported " + std::to_string(messages.size()) + " message(s)");
#endif
}

}  // namespace

void add_explain_command(CLI::App& app) {
  auto o = std::make_shared<ExplainOptions>();
  CLI::App* cmd = app.add_subcommand(
      "explain",
      "Every step of one ray through the grid (a pixel's primary, bounce or shadow ray, or any ray), the shader's "
      "own record beside it with --backend vulkan; as text or --brief, and --json, OBJ, SVG or an HTML viewer");
  add_scene_argument(cmd, o->scene);
  add_image_size(cmd, o->width, o->height, "of the frame whose pixel is explained");
  cmd->add_option("--time,-t", o->time, "Scene time in seconds")->check(CLI::Range(-1.0e6f, 1.0e6f));
  cmd->add_option("--frame", o->frame, "The frame number that seeds the glossy bounce's per-pixel random numbers");
  auto* pixel = cmd->add_option("--pixel,-p", o->pixel, "The pixel X,Y whose ray is explained")->delimiter(',')->expected(2);
  add_choice(cmd, "--kind", o->kind, {"auto", "primary", "bounce", "shadow"},
             "Which of the pixel's rays: primary, bounce (its glossy bounce), shadow (toward each light from its "
             "primary hit), auto (the bounce where the pixel has one, else the primary)");
  cmd->add_flag("--primary", o->primary, "The same as --kind primary");
  cmd->add_option("--light", o->light, "--kind shadow: only the shadow ray toward this light (its index)");
  auto* ray = cmd->add_option("--ray", o->rays,
                              "A ray ox,oy,oz,dx,dy,dz[,tmin,tmax[,launch_ref]]: floats in decimal or C99 hex "
                              "(0x1.8p+1), launch_ref a number, 0x hex, INSTANCE:TRIANGLE or none; repeatable")
                  ->expected(1)
                  ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll);
  auto* file = cmd->add_option("--ray-file", o->ray_file, "A file of rays, one a line in --ray's syntax, # comments");
  pixel->excludes(ray)->excludes(file);
  cmd->add_flag("--gpu-frame", o->gpu_frame,
                "--pixel: take the ray from the GPU frame's own passes (its gather, its bounce pass) and compare "
                "the frame's own hit (--backend vulkan)");
  add_choice(cmd, "--backend,-b", o->backend, {"cpu", "vulkan"},
             "cpu, or vulkan to show the shader's own record beside the reference's");
  cmd->add_flag("--brief", o->brief, "One line an event, no hex, runs of empty cells folded");
  add_json_option(cmd, o->json, "the event records (with names)");
  cmd->add_option("--export", o->obj,
                  "Write the ray, its visited cells (boxes), the tested triangles and the hit as a Wavefront OBJ "
                  "(with a .mtl beside it)");
  cmd->add_option("--svg", o->svg, "Write a 2D projection of the ray, its cells and triangles as SVG");
  cmd->add_option("--html", o->html,
                  "Write the step-by-step viewer: one self-contained HTML page (the picture, a slider over the events, "
                  "the reference's and the shader's records side by side, the triangle tests)");
  add_backend_options(cmd, o->backend_options);
  cmd->callback([o, cmd] {
    if (o->pixel.empty() && o->rays.empty() && o->ray_file.empty())
      throw CLI::ValidationError("explain", "give --pixel X,Y, --ray or --ray-file");
    if (o->pixel.empty() && (o->kind != "auto" || o->primary || o->gpu_frame || o->light))
      throw CLI::ValidationError("explain", "--kind, --primary, --light and --gpu-frame go with --pixel");
    if (o->primary && o->kind != "auto" && o->kind != "primary")
      throw CLI::ValidationError("--primary", "is --kind primary: it contradicts --kind " + o->kind + " (give one)");
    if (o->light && o->kind != "shadow")
      throw CLI::ValidationError("explain", "--light picks the shadow ray of one light: it goes with --kind shadow");
    // Options that did nothing here, without a word (an outside sweep)
    if (cmd->get_option("--fallback-cpu")->count() > 0)
      throw CLI::ValidationError("--fallback-cpu", "does not apply to explain (--backend vulkan shows the shader's own "
                                                   "record beside the reference's, and needs a Vulkan device)");
    check_vulkan_options_apply(cmd, o->backend == "vulkan");
    // --ray and --ray-file trace the options' grid alone (a pixel's ray also has the gather's, the
    // exact traversal's): there the exact traversal's knobs with the paper traversal do nothing
    check_traversal_options(cmd, o->backend_options, /*trace_grid_only=*/o->pixel.empty());
    // A primary ray is explained on the gather's grid, the exact traversal's, unless --traversal
    // names one: the paper traversal's knobs did nothing there, without a word (an outside sweep)
    if ((o->primary || o->kind == "primary") && cmd->count("--traversal") == 0)
      for (const char* name : {"--gap-fill", "--revisit", "--elongation", "--gap-fill-distance"})
        if (cmd->get_option_no_throw(name) != nullptr && cmd->count(name) > 0)
          throw CLI::ValidationError(name, "is a knob of the paper traversal; --kind primary explains the ray on the "
                                           "gather's grid, the exact traversal's: it does nothing (leave it out, or "
                                           "give --traversal paper)");
    // The frame number seeds only the glossy bounce's random numbers
    o->frame_given = cmd->count("--frame") > 0;
    if (cmd->count("--frame") > 0 && (o->primary || o->kind == "primary" || o->kind == "shadow"))
      throw CLI::ValidationError("--frame", "seeds the glossy bounce's random numbers: it does not change a " +
                                                std::string(o->kind == "shadow" ? "shadow" : "primary") +
                                                " ray (leave it out)");
    if (!o->rays.empty() || !o->ray_file.empty())
      for (const char* name : {"--width", "--height", "--frame"})
        if (cmd->get_option(name)->count() > 0)
          throw CLI::ValidationError(name, "goes with --pixel (a given ray is traced as it is)");
    const auto lower_extension = [](const std::string& path) {
      std::string e = std::filesystem::path(path).extension().string();
      for (char& c : e) c = char(std::tolower(static_cast<unsigned char>(c)));
      return e;
    };
    if (!o->obj.empty() && lower_extension(o->obj) == ".mtl")
      throw CLI::ValidationError("explain", "--export " + o->obj + ": the OBJ's materials go beside it as NAME.mtl; "
                                            "name the OBJ NAME.obj");
    // Each output its own file (the OBJ's .mtl beside it counts as one): one would replace another
    std::vector<std::pair<std::string, std::string>> outputs;
    for (const auto& [name, path] : {std::pair{"--export", o->obj}, std::pair{"--svg", o->svg},
                                     std::pair{"--html", o->html}, std::pair{"--json", o->json}})
      if (!path.empty()) outputs.emplace_back(name, path);
    if (!o->obj.empty())
      outputs.emplace_back("--export's materials", std::filesystem::path(o->obj).replace_extension(".mtl").string());
    for (size_t a = 0; a < outputs.size(); ++a)
      for (size_t b = a + 1; b < outputs.size(); ++b)
        if (!is_stream_output(outputs[a].second) && names_same_file(outputs[a].second, outputs[b].second))
          throw CLI::ValidationError("explain", outputs[a].first + " and " + outputs[b].first + " both name " +
                                                    outputs[b].second + ": give each output its own file");
    // Nor an input: the scene or the ray file would be replaced by the picture of its own rays
    for (const auto& [name, path] : outputs)
      for (const auto& [input, in_path] : {std::pair{"the scene", o->scene}, std::pair{"--ray-file", o->ray_file}})
        if (!in_path.empty() && names_same_file(path, in_path))
          throw CLI::ValidationError("explain", std::string(name) + " names " + input + "'s file " + in_path +
                                                    ": an output may not replace an input");
    if (o->gpu_frame && o->backend != "vulkan")
      throw CLI::ValidationError("explain", "--gpu-frame needs --backend vulkan (the GPU frame runs on the device)");
    o->traversal_given = cmd->count("--traversal") > 0;
    run_explain(*o);
  });
}

}  // namespace gridrt::app
