#include "gridrt/common/scene_io.h"

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>

#include <unistd.h>
#include <zlib.h>

#include <glm/gtc/matrix_transform.hpp>
#include <nlohmann/json.hpp>

#include "gridrt/common/builtin/builtin.h"
#include "gridrt/common/loaders/loaders.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/util.h"

#ifndef GRIDRT_DEFAULT_SCENES
#define GRIDRT_DEFAULT_SCENES "../shared/data/scenes"
#endif

namespace gridrt {
namespace fs = std::filesystem;
using json = nlohmann::json;

namespace {

std::string lower_extension(std::string_view path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

std::string read_text(const std::string& path, const char* what) { return read_input_file(path, what); }

// ---------------------------------------------------------------------------------------------
// JSON scene files

// Reads one JSON scene file; every error names the file and the JSON path of the value.
// The path of the first key given twice in one object of the JSON `text` ("instances[].motion"),
// empty if none: a SAX pass, linear in the text (the text has parsed already).
std::string first_duplicate_key(const std::string& text) {
  using json = nlohmann::json;
  struct Tracker : nlohmann::json_sax<json> {
    struct Level {
      bool object = false;
      std::set<std::string> keys;
      std::string key;
    };
    std::vector<Level> levels;
    std::string duplicate;
    bool null() override { return true; }
    bool boolean(bool) override { return true; }
    bool number_integer(number_integer_t) override { return true; }
    bool number_unsigned(number_unsigned_t) override { return true; }
    bool number_float(number_float_t, const string_t&) override { return true; }
    bool string(string_t&) override { return true; }
    bool binary(binary_t&) override { return true; }
    bool start_object(std::size_t) override {
      levels.push_back({true, {}, {}});
      return true;
    }
    bool start_array(std::size_t) override {
      levels.push_back({false, {}, {}});
      return true;
    }
    bool end_object() override { return end(); }
    bool end_array() override { return end(); }
    bool end() {
      if (!levels.empty()) levels.pop_back();
      return true;
    }
    bool key(string_t& k) override {
      if (levels.empty()) return true;
      Level& l = levels.back();
      l.key = k;
      if (l.keys.insert(k).second) return true;
      for (size_t i = 0; i < levels.size(); ++i) duplicate += levels[i].object ? (i > 0 ? "." : "") + levels[i].key : "[]";
      return false;  // the first is enough
    }
    bool parse_error(std::size_t, const std::string&, const nlohmann::detail::exception&) override { return false; }
  } tracker;
  json::sax_parse(text, &tracker);
  return tracker.duplicate;
}

class SceneFileReader {
 public:
  explicit SceneFileReader(const std::string& path) : path_(path), dir_(fs::path(path).parent_path()) {}

  Scene read() {
    const std::string text = read_text(path_, "scene file");
    json root;
    check_json_depth(text, path_, input_limits().max_json_depth);
    // Line and column (1-based) of byte `at`
    const auto where = [&](size_t at) {
      size_t line = 1, column = 1;
      for (size_t i = 0; i < at; ++i) {
        if (text[i] == '\n') { ++line; column = 1; } else { ++column; }
      }
      return path_ + ":" + std::to_string(line) + ":" + std::to_string(column);
    };
    // JSON text holds no NUL byte (the parser would stop there and take what follows for nothing)
    if (const size_t nul = text.find('\0'); nul != std::string::npos)
      throw Error(where(nul) + ": JSON syntax error: a NUL byte (a JSON text has none)");
    try {
      root = json::parse(text);
    } catch (const json::out_of_range& e) {
      // e.g. an integer of 400 digits ("number overflow")
      throw Error(path_ + ": JSON number out of range: " + e.what());
    } catch (const json::parse_error& e) {
      // nlohmann gives the byte position (1-based, just past the offending character).
      const size_t at = std::min(e.byte > 0 ? e.byte - 1 : 0, text.size());
      throw Error(where(at) + ": JSON syntax error: " + printable_message(e.what()));
    }
    // A key given twice in one object: the parser keeps the last without a word (a second
    // "motion" pasted into an instance), so a second pass over the text names the first
    // duplicate's path. A SAX pass of its own: the DOM parser's callback walked the parent array
    // at every object's end, quadratic in an array's objects (200,000 empty objects took 17.5 s,
    // 3 million over an hour: an outside sweep).
    const std::string duplicate = first_duplicate_key(text);
    if (!duplicate.empty())
      throw Error(path_ + ": " + duplicate + ": the key is given twice in its object (the last would win without a word)");
    expect_object(root, "the top level");
    check_keys(root, "", {"name", "description", "meshes", "materials", "instances", "camera", "lights", "grid", "background"});

    scene_.name = root.contains("name") ? get_string(root["name"], "name") : fs::path(path_).stem().string();
    if (!root.contains("meshes")) fail("", "no \"meshes\"");
    if (!root.contains("instances")) fail("", "no \"instances\"");
    // The meshes some instance names (an unused one was loaded and kept too: 150 unused teapots of
    // a 6.5 KB file took 4 GB before any limit, an outside sweep)
    if (root["instances"].is_array())
      for (const json& in : root["instances"])
        if (in.is_object() && in.contains("mesh") && in["mesh"].is_string()) used_.insert(in["mesh"].get<std::string>());
    read_meshes(root["meshes"]);
    if (root.contains("materials")) read_materials(root["materials"]);
    read_instances(root["instances"]);
    if (root.contains("camera")) read_camera(root["camera"]);
    if (root.contains("lights")) read_lights(root["lights"]);
    if (root.contains("grid")) read_grid(root["grid"]);
    if (root.contains("background")) scene_.background = get_vec3(root["background"], "background");
    try {
      scene_.finalize();
    } catch (const Error& e) {
      throw Error(path_ + ": " + e.what());
    }
    return std::move(scene_);
  }

 private:
  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    throw Error(path_ + ": " + (where.empty() ? "" : where + ": ") + what);
  }

  void expect_object(const json& j, const std::string& where) const {
    if (!j.is_object()) fail(where, std::string("expected an object, found ") + j.type_name());
  }

  void check_keys(const json& j, const std::string& where, std::initializer_list<const char*> allowed) const {
    for (auto it = j.begin(); it != j.end(); ++it) {
      if (std::none_of(allowed.begin(), allowed.end(), [&](const char* a) { return it.key() == a; })) {
        std::string list;
        for (const char* a : allowed) list += std::string(list.empty() ? "" : ", ") + a;
        fail(where, "unknown key \"" + it.key() + "\" (expected one of: " + list + ")");
      }
    }
  }

  float get_number(const json& j, const std::string& where) const {
    if (!j.is_number()) fail(where, std::string("expected a number, found ") + j.type_name());
    const double d = j.get<double>();
    if (!std::isfinite(d)) fail(where, "not a finite number");
    // Kept as a float: 1e39 became inf, refused later as "non-finite" without its path
    if (!std::isfinite(float(d))) fail(where, j.dump() + " is beyond a float's range (about 3.4e38)");
    return float(d);
  }
  uint32_t get_uint(const json& j, const std::string& where) const {
    if (!j.is_number_unsigned() && !(j.is_number_integer() && j.get<int64_t>() >= 0))
      fail(where, std::string("expected a non-negative integer, found ") + (j.is_number() ? j.dump() : j.type_name()));
    const uint64_t v = j.get<uint64_t>();
    if (v > UINT32_MAX) fail(where, "integer too large");
    return uint32_t(v);
  }
  bool get_bool(const json& j, const std::string& where) const {
    if (!j.is_boolean()) fail(where, std::string("expected true or false, found ") + j.type_name());
    return j.get<bool>();
  }
  std::string get_string(const json& j, const std::string& where) const {
    if (!j.is_string()) fail(where, std::string("expected a string, found ") + j.type_name());
    return j.get<std::string>();
  }
  glm::vec3 get_vec3(const json& j, const std::string& where) const {
    if (!j.is_array() || j.size() != 3) fail(where, "expected an array of 3 numbers");
    return {get_number(j[0], where + "[0]"), get_number(j[1], where + "[1]"), get_number(j[2], where + "[2]")};
  }

  // "${GRIDRT_SCENES}/x" -> real_scenes_dir()/x; relative paths are relative to the scene file.
  std::string resolve(const std::string& p, const std::string& where) const {
    // A NUL ends the name the system opens but not the one whose extension picks the loader
    if (p.find('\0') != std::string::npos) fail(where, "a path may not contain a NUL character (\\u0000)");
    static const std::string kVar = "${GRIDRT_SCENES}";
    std::string out = p;
    bool real = false;
    if (out.rfind(kVar, 0) == 0) {
      out = real_scenes_dir() + out.substr(kVar.size());
      real = true;
    } else if (out.find("${") != std::string::npos) {
      fail(where, "unknown variable in \"" + p + "\" (only ${GRIDRT_SCENES} is expanded)");
    }
    fs::path fp(out);
    if (fp.is_relative()) fp = dir_ / fp;
    if (is_folder(fp.string())) fail(where, "'" + fp.string() + "' is a directory, not a file");
    if (const std::string why = why_missing(fp.string()); why == "no such file")
      fail(where, "file '" + fp.string() + "' not found" +
                      (real ? std::string(" (the real scenes folder is $GRIDRT_SCENES, else ") + GRIDRT_DEFAULT_SCENES + ")" : ""));
    else if (!why.empty())
      fail(where, "file '" + fp.string() + "': " + why);
    return fp.string();
  }

  void read_meshes(const json& j) {
    expect_object(j, "meshes");
    for (auto it = j.begin(); it != j.end(); ++it) {
      const std::string where = "meshes." + it.key();
      const json& m = it.value();
      expect_object(m, where);
      if (!used_.count(it.key())) {  // checked, not loaded
        check_keys(m, where, {"file", "builtin", "level", "diffuse"});
        if (!m.contains("file") && !m.contains("builtin")) fail(where, "needs \"file\" or \"builtin\"");
        unused_.push_back(it.key());
        continue;
      }
      std::vector<Instance> parts;
      if (m.contains("file")) {
        check_keys(m, where, {"file"});
        const std::string file = resolve(get_string(m["file"], where + ".file"), where + ".file");
        const std::string ext = lower_extension(file);
        // A model named under several keys is loaded once, its meshes shared (N keys loaded it N
        // times: N times the memory and the time, an outside sweep)
        std::error_code ec;
        std::string same = std::filesystem::weakly_canonical(file, ec).string();
        if (ec) same = file;
        if (const auto loaded = files_.find(same); loaded != files_.end()) {
          meshes_[it.key()] = loaded->second;
          continue;
        }
        if (ext == ".obj") parts = load_obj(file, scene_, textures_);
        else if (ext == ".gltf" || ext == ".glb") parts = load_gltf(file, scene_, textures_);
        else fail(where + ".file", "unknown model extension '" + ext + "' (expected .obj, .gltf or .glb)");
        files_[same] = parts;
      } else if (m.contains("builtin")) {
        check_keys(m, where, {"builtin", "level", "diffuse"});
        const std::string name = get_string(m["builtin"], where + ".builtin");
        if (name != "teapot") fail(where + ".builtin", "unknown built-in mesh \"" + name + "\" (expected \"teapot\")");
        const uint32_t level = m.contains("level") ? get_uint(m["level"], where + ".level") : 6u;
        if (level < 1 || level > 64) fail(where + ".level", "must lie in [1, 64]");
        Material mat{.name = it.key()};
        if (m.contains("diffuse")) mat.diffuse = get_vec3(m["diffuse"], where + ".diffuse");
        Mesh mesh = builtin_teapot(level, where);
        mesh.name = it.key();
        mesh.materials.assign(mesh.triangles.size(), uint32_t(scene_.materials.size()));
        scene_.materials.push_back(mat);
        parts.push_back(Instance{.name = it.key(), .mesh = uint32_t(scene_.meshes.size())});
        scene_.meshes.push_back(std::move(mesh));
      } else {
        fail(where, "needs \"file\" or \"builtin\"");
      }
      meshes_[it.key()] = std::move(parts);
      // Each mesh loaded counts at least once over the instances: a file over the limits is
      // refused as it is read, not after every mesh is held
      uint64_t triangles = 0, vertices = 0;
      for (const Mesh& mesh : scene_.meshes) {
        triangles += mesh.triangles.size();
        vertices += mesh.positions.size();
      }
      if (triangles > input_limits().max_triangles)
        fail(where, "the meshes loaded so far hold " + std::to_string(triangles) + " triangles, more than the limit of " +
                        std::to_string(input_limits().max_triangles) + " (--max-triangles)");
      if (vertices > input_limits().max_vertices)
        fail(where, "the meshes loaded so far hold " + std::to_string(vertices) + " vertices, more than the limit of " +
                        std::to_string(input_limits().max_vertices));
    }
    if (!unused_.empty()) {
      std::string list;
      for (size_t i = 0; i < unused_.size() && i < 5; ++i) list += (i ? ", " : "") + unused_[i];
      std::fprintf(stderr, "warning: %s: %zu mesh entr%s no instance uses (%s%s): not loaded\n", path_.c_str(),
                   unused_.size(), unused_.size() == 1 ? "y" : "ies", list.c_str(), unused_.size() > 5 ? ", ..." : "");
    }
  }

  Mesh builtin_teapot(uint32_t level, const std::string& where) const {
    try {
      return make_teapot_mesh(level);
    } catch (const Error& e) {
      fail(where, e.what());
    }
  }

  void read_materials(const json& j) {
    expect_object(j, "materials");
    check_keys(j, "materials", {"glossiness", "overrides"});
    if (j.contains("glossiness")) {
      const float g = get_number(j["glossiness"], "materials.glossiness");
      for (Material& m : scene_.materials) m.glossiness = g;
    }
    if (j.contains("overrides")) {
      expect_object(j["overrides"], "materials.overrides");
      for (auto it = j["overrides"].begin(); it != j["overrides"].end(); ++it) {
        const std::string where = "materials.overrides." + it.key();
        expect_object(it.value(), where);
        check_keys(it.value(), where, {"glossiness", "diffuse", "opacity"});
        bool found = false;
        for (Material& m : scene_.materials) {
          if (m.name != it.key()) continue;
          found = true;
          if (it->contains("glossiness")) m.glossiness = get_number((*it)["glossiness"], where + ".glossiness");
          if (it->contains("diffuse")) m.diffuse = get_vec3((*it)["diffuse"], where + ".diffuse");
          if (it->contains("opacity")) m.opacity = get_number((*it)["opacity"], where + ".opacity");
        }
        // A material of a mesh entry no instance uses (not loaded) is not in the scene: said, not
        // refused (such a file loaded before unused entries were skipped)
        if (!found && !unused_.empty()) {
          std::fprintf(stderr, "warning: %s: %s: no loaded material is named \"%s\" (mesh entries no instance uses are "
                       "not loaded): ignored\n", path_.c_str(), where.c_str(), it.key().c_str());
          continue;
        }
        if (!found) fail(where, "no material is named \"" + it.key() + "\"");
      }
    }
  }

  glm::mat4 read_transform(const json& j, const std::string& where) const {
    glm::mat4 m(1.0f);
    if (j.contains("translate")) m = glm::translate(m, get_vec3(j["translate"], where + ".translate"));
    if (j.contains("rotate")) {
      const json& r = j["rotate"];
      const json list = r.is_array() ? r : json::array({r});
      // Applied in order, as SCENE_FORMAT.md says: the first rotation acts on the object first,
      // so R = R(n-1) * ... * R(0) (post-multiplying each one applied the last first)
      glm::mat4 rotation(1.0f);
      for (size_t i = 0; i < list.size(); ++i) {
        const std::string w = where + ".rotate" + (r.is_array() ? "[" + std::to_string(i) + "]" : "");
        expect_object(list[i], w);
        check_keys(list[i], w, {"axis", "degrees"});
        if (!list[i].contains("axis") || !list[i].contains("degrees")) fail(w, "needs \"axis\" and \"degrees\"");
        // Scaled first, as a motion's axis is (an axis of length 1e30 overflowed the normalization)
        const glm::vec3 axis = direction_in_range(get_vec3(list[i]["axis"], w + ".axis"));
        if (glm::length(axis) == 0.0f) fail(w + ".axis", "zero axis");
        rotation = glm::rotate(glm::mat4(1.0f), glm::radians(get_number(list[i]["degrees"], w + ".degrees")),
                               glm::normalize(axis)) *
                   rotation;
      }
      m = m * rotation;
    }
    if (j.contains("scale")) {
      const json& s = j["scale"];
      m = glm::scale(m, s.is_number() ? glm::vec3(get_number(s, where + ".scale")) : get_vec3(s, where + ".scale"));
    }
    return m;
  }

  Motion read_motion(const json& j, const std::string& where, const glm::vec3& default_pivot) const {
    expect_object(j, where);
    check_keys(j, where, {"rotate", "path"});
    Motion mo;
    if (j.contains("rotate")) {
      const std::string w = where + ".rotate";
      const json& r = j["rotate"];
      expect_object(r, w);
      check_keys(r, w, {"axis", "pivot", "speed"});
      mo.axis = r.contains("axis") ? get_vec3(r["axis"], w + ".axis") : glm::vec3(0, 1, 0);
      mo.pivot = r.contains("pivot") ? get_vec3(r["pivot"], w + ".pivot") : default_pivot;
      if (!r.contains("speed")) fail(w, "needs \"speed\" (radians per second)");
      mo.angular_speed = get_number(r["speed"], w + ".speed");
      // Scaled before it is judged, as the base rotation's axis is (a length of 1e-25 underflowed
      // to 0 in float and was called a zero axis: an outside sweep); Scene::finalize scales it too
      if (glm::length(direction_in_range(mo.axis)) == 0.0f) fail(w + ".axis", "zero axis");
    }
    if (j.contains("path")) {
      const std::string w = where + ".path";
      const json& p = j["path"];
      expect_object(p, w);
      check_keys(p, w, {"points", "period"});
      if (!p.contains("points") || !p["points"].is_array() || p["points"].empty())
        fail(w + ".points", "expected a non-empty array of [x, y, z] offsets");
      for (size_t i = 0; i < p["points"].size(); ++i)
        mo.path_points.push_back(get_vec3(p["points"][i], w + ".points[" + std::to_string(i) + "]"));
      mo.path_period = p.contains("period") ? get_number(p["period"], w + ".period") : 1.0f;
      if (!(mo.path_period > 0.0f)) fail(w + ".period", "must be positive (seconds)");
    }
    return mo;
  }

  void read_instances(const json& j) {
    if (!j.is_array()) fail("instances", std::string("expected an array, found ") + j.type_name());
    for (size_t i = 0; i < j.size(); ++i) {
      const std::string where = "instances[" + std::to_string(i) + "]";
      const json& in = j[i];
      expect_object(in, where);
      check_keys(in, where, {"name", "mesh", "translate", "rotate", "scale", "dynamic", "motion"});
      if (!in.contains("mesh")) fail(where, "needs \"mesh\"");
      const std::string mesh = get_string(in["mesh"], where + ".mesh");
      auto found = meshes_.find(mesh);
      if (found == meshes_.end()) fail(where + ".mesh", "no mesh is named \"" + mesh + "\"");
      const std::string name = in.contains("name") ? get_string(in["name"], where + ".name") : mesh;
      const glm::mat4 m = read_transform(in, where);
      const glm::vec3 translate = glm::vec3(m[3]);
      Motion motion;
      if (in.contains("motion")) motion = read_motion(in["motion"], where + ".motion", translate);
      const bool dynamic = in.contains("dynamic") ? get_bool(in["dynamic"], where + ".dynamic") : motion.moves();
      if (motion.moves() && !dynamic) fail(where, "has a motion but \"dynamic\": false (static instances never move)");
      for (const Instance& part : found->second) {
        Instance inst = part;
        inst.name = found->second.size() == 1 ? name : name + "/" + part.name;
        inst.transform = m * part.transform;
        inst.dynamic = dynamic;
        inst.motion = motion;
        scene_.instances.push_back(std::move(inst));
      }
    }
  }

  void read_camera(const json& j) {
    expect_object(j, "camera");
    check_keys(j, "camera", {"eye", "target", "up", "vfov"});
    Camera c;
    if (!j.contains("eye") || !j.contains("target")) fail("camera", "needs \"eye\" and \"target\"");
    c.eye = get_vec3(j["eye"], "camera.eye");
    c.target = get_vec3(j["target"], "camera.target");
    if (j.contains("up")) c.up = get_vec3(j["up"], "camera.up");
    if (j.contains("vfov")) c.vfov_degrees = get_number(j["vfov"], "camera.vfov");
    scene_.camera = c;
  }

  void read_lights(const json& j) {
    if (!j.is_array()) fail("lights", std::string("expected an array, found ") + j.type_name());
    for (size_t i = 0; i < j.size(); ++i) {
      const std::string where = "lights[" + std::to_string(i) + "]";
      expect_object(j[i], where);
      check_keys(j[i], where, {"position", "direction", "color", "intensity"});
      Light l;
      if (j[i].contains("position") == j[i].contains("direction"))
        fail(where, "needs exactly one of \"position\" (point light) and \"direction\" (towards a directional light)");
      if (j[i].contains("position")) l.position = get_vec3(j[i]["position"], where + ".position");
      else { l.position = get_vec3(j[i]["direction"], where + ".direction"); l.directional = true; }
      if (j[i].contains("color")) l.color = get_vec3(j[i]["color"], where + ".color");
      if (j[i].contains("intensity")) l.intensity = get_number(j[i]["intensity"], where + ".intensity");
      scene_.lights.push_back(l);
    }
  }

  void read_grid(const json& j) {
    expect_object(j, "grid");
    check_keys(j, "grid", {"resolution", "capacity", "cell_size"});
    if (j.contains("resolution")) {
      const json& r = j["resolution"];
      if (!r.is_array() || r.size() != 3) fail("grid.resolution", "expected an array of 3 integers");
      scene_.grid.resolution = glm::uvec3(get_uint(r[0], "grid.resolution[0]"), get_uint(r[1], "grid.resolution[1]"),
                                          get_uint(r[2], "grid.resolution[2]"));
    }
    if (j.contains("capacity")) scene_.grid.capacity = get_uint(j["capacity"], "grid.capacity");
    if (j.contains("cell_size")) scene_.grid.cell_size = get_number(j["cell_size"], "grid.cell_size");
    // Both size the grid: one of them was silently dropped (an outside sweep's find)
    if (scene_.grid.resolution && scene_.grid.cell_size)
      fail("grid", "gives both \"resolution\" and \"cell_size\", which both size the grid: give one of them");
  }

  std::string path_;
  fs::path dir_;
  Scene scene_;
  TextureCache textures_;
  std::map<std::string, std::vector<Instance>> meshes_;  // by name: the instances a file gave
  std::map<std::string, std::vector<Instance>> files_;   // by the file's canonical path: the same
  std::set<std::string> used_;                           // the mesh names the instances give
  std::vector<std::string> unused_;                      // the mesh entries no instance uses (not loaded)
};

// ---------------------------------------------------------------------------------------------
// Binary cache

static_assert(std::endian::native == std::endian::little, "the .gridscene writer assumes a little-endian host");
constexpr char kMagic[8] = {'G', 'R', 'I', 'D', 'S', 'C', 'N', '\0'};
constexpr char kEndMagic[8] = {'E', 'N', 'D', 'S', 'C', 'N', '\0', '\0'};

// The cache's records are written and read by one list of fields (transfer_scene below): the
// Writer's and the Reader's calls of the same name write a field and read it back.
class Writer {
 public:
  static constexpr bool kReading = false;
  template <class T>
  void pod(const T& v, const char* = nullptr) {
    static_assert(std::is_trivially_copyable_v<T>);
    const char* p = reinterpret_cast<const char*>(&v);
    out.append(p, sizeof(T));
  }
  template <class T>
  void vec(const std::vector<T>& v, const char* = nullptr) {
    pod(uint64_t(v.size()));
    if (!v.empty()) out.append(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
  }
  void str(const std::string& s, const char* = nullptr) {
    pod(uint64_t(s.size()));
    out.append(s);
  }
  void flag(bool b, const char* = nullptr) { pod(uint8_t(b)); }
  template <class T>
  void items(const std::vector<T>& v, const char*, size_t) { pod(uint64_t(v.size())); }
  // A flag, then the value (a zero where there is none)
  template <class T>
  void optional(const std::optional<T>& v, const char*, const char*) {
    flag(v.has_value());
    pod(v.value_or(T(0)));
  }
  std::string out;
};

class Reader {
 public:
  Reader(const std::string& data, const std::string& path) : d_(data), path_(path) {}
  template <class T>
  T pod(const char* what) {
    static_assert(std::is_trivially_copyable_v<T>);
    need(sizeof(T), what);
    T v;
    std::memcpy(&v, d_.data() + pos_, sizeof(T));
    pos_ += sizeof(T);
    return v;
  }
  template <class T>
  std::vector<T> vec(const char* what) {
    const uint64_t n = pod<uint64_t>(what);
    if (n > (d_.size() - pos_) / sizeof(T)) fail(std::string(what) + ": " + std::to_string(n) + " elements run past the end of the file");
    std::vector<T> v(n);
    if (n) std::memcpy(v.data(), d_.data() + pos_, n * sizeof(T));
    pos_ += n * sizeof(T);
    return v;
  }
  std::string str(const char* what) {
    const uint64_t n = pod<uint64_t>(what);
    need(n, what);
    std::string s = d_.substr(pos_, n);
    pos_ += n;
    return s;
  }
  uint32_t count(const char* what, size_t min_bytes_each) {
    const uint64_t n = pod<uint64_t>(what);
    if (n > (d_.size() - pos_) / min_bytes_each) fail(std::string(what) + ": count " + std::to_string(n) + " exceeds the file");
    return uint32_t(n);
  }
  bool flag(const char* what) {
    const uint8_t b = pod<uint8_t>(what);
    if (b > 1) fail(std::string(what) + ": flag byte " + std::to_string(b) + " is neither 0 nor 1");
    return b != 0;
  }
  // The Writer's calls, reading into the field
  static constexpr bool kReading = true;
  template <class T>
  void pod(T& v, const char* what) { v = pod<T>(what); }
  template <class T>
  void vec(std::vector<T>& v, const char* what) { v = vec<T>(what); }
  void str(std::string& s, const char* what) { s = str(what); }
  void flag(bool& b, const char* what) { b = flag(what); }
  template <class T>
  void items(std::vector<T>& v, const char* what, size_t min_bytes_each) { v.resize(count(what, min_bytes_each)); }
  template <class T>
  void optional(std::optional<T>& v, const char* flag_what, const char* value_what) {
    const bool has = flag(flag_what);
    const T value = pod<T>(value_what);
    if (has) v = value;
  }
  void need(uint64_t n, const char* what) const {
    if (n > d_.size() - pos_) fail(std::string("truncated at ") + what + " (byte " + std::to_string(pos_) + " of " + std::to_string(d_.size()) + ")");
  }
  [[noreturn]] void fail(const std::string& what) const { throw Error("corrupt scene cache '" + path_ + "': " + what); }
  size_t pos() const { return pos_; }
  size_t size() const { return d_.size(); }
  const char* at() const { return d_.data() + pos_; }
  void skip(size_t n) { pos_ += n; }

 private:
  const std::string& d_;
  const std::string& path_;
  size_t pos_ = 0;
};

// Every field of the cache after the version, in file order. `A` is the Writer (with a const
// Scene) or the Reader; each record's count comes before its items.
template <class A, class S>
void transfer_scene(A& a, S& s) {
  a.str(s.name, "the scene name");
  a.pod(s.background, "the background");
  a.items(s.meshes, "the mesh count", 48);
  for (auto& m : s.meshes) {
    a.str(m.name, "a mesh name");
    a.vec(m.positions, "positions");
    a.vec(m.normals, "normals");
    a.vec(m.uvs, "uvs");
    a.vec(m.triangles, "triangles");
    a.vec(m.materials, "material ids");
  }
  a.items(s.materials, "the material count", 32);
  for (auto& m : s.materials) {
    a.str(m.name, "a material name");
    a.pod(m.diffuse, "a diffuse colour");
    a.pod(m.diffuse_texture, "a diffuse texture");
    a.pod(m.alpha_texture, "an alpha texture");
    a.pod(m.glossiness, "a glossiness");
    a.pod(m.opacity, "an opacity");
  }
  a.items(s.textures, "the texture count", 25);
  for (auto& t : s.textures) {
    a.str(t.path, "a texture path");
    a.pod(t.width, "a texture width");
    a.pod(t.height, "a texture height");
    a.flag(t.has_alpha, "a texture alpha flag");
    if constexpr (A::kReading) {  // the size checked before the texels are allocated
      if (t.width == 0 || t.height == 0 || uint64_t(t.width) * t.height > input_limits().max_texture_pixels)
        a.fail("texture '" + t.path + "': size " + std::to_string(t.width) + " x " + std::to_string(t.height) +
               " is zero or above the limit of " + std::to_string(input_limits().max_texture_pixels) +
               " pixels (--max-texture-pixels)");
    }
    a.vec(t.rgba, "texels");
    if constexpr (A::kReading) {
      if (t.rgba.size() != uint64_t(t.width) * t.height * 4)
        a.fail("texture '" + t.path + "': " + std::to_string(t.rgba.size()) + " bytes for " + std::to_string(t.width) +
               " x " + std::to_string(t.height) + " RGBA8");
    }
  }
  a.items(s.instances, "the instance count", 100);
  for (auto& i : s.instances) {
    a.str(i.name, "an instance name");
    a.pod(i.mesh, "an instance mesh");
    a.pod(i.transform, "an instance transform");
    a.flag(i.dynamic, "an instance dynamic flag");
    a.pod(i.motion.axis, "a motion axis");
    a.pod(i.motion.pivot, "a motion pivot");
    a.pod(i.motion.angular_speed, "an angular speed");
    a.vec(i.motion.path_points, "path points");
    a.pod(i.motion.path_period, "a path period");
  }
  bool has_camera = s.camera.has_value();
  a.flag(has_camera, "the camera flag");
  if (has_camera) {
    if constexpr (A::kReading) s.camera.emplace();
    auto& c = *s.camera;
    a.pod(c.eye, "the camera eye");
    a.pod(c.target, "the camera target");
    a.pod(c.up, "the camera up");
    a.pod(c.vfov_degrees, "the camera field of view");
  }
  a.items(s.lights, "the light count", 29);
  for (auto& l : s.lights) {
    a.pod(l.position, "a light position");
    a.pod(l.color, "a light colour");
    a.pod(l.intensity, "a light intensity");
    a.flag(l.directional, "a light directional flag");
  }
  a.optional(s.grid.resolution, "the grid resolution flag", "the grid resolution");
  a.optional(s.grid.capacity, "the grid capacity flag", "the grid capacity");
  a.optional(s.grid.cell_size, "the grid cell size flag", "the grid cell size");
}

}  // namespace

std::string json_first_duplicate_key(const std::string& text) { return first_duplicate_key(text); }

std::string real_scenes_dir() {
  // A relative value is the working folder's, as any path an environment variable names (it was
  // read against the scene file's folder)
  if (const char* env = std::getenv("GRIDRT_SCENES"); env && *env) {
    std::error_code ec;
    const fs::path p = fs::absolute(env, ec);
    return ec ? std::string(env) : p.string();
  }
  return GRIDRT_DEFAULT_SCENES;
}

Scene load_scene_file(const std::string& path) { return SceneFileReader(path).read(); }

Scene load_model_scene(const std::string& path) {
  if (const std::string why = why_missing(path); !why.empty()) throw Error("cannot open model '" + path + "': " + why);
  Scene scene;
  scene.name = fs::path(path).filename().string();
  TextureCache textures;
  const std::string ext = lower_extension(path);
  std::vector<Instance> parts;
  if (ext == ".obj") parts = load_obj(path, scene, textures);
  else if (ext == ".gltf" || ext == ".glb") parts = load_gltf(path, scene, textures);
  else throw Error("cannot load model '" + path + "': unknown extension '" + ext + "' (expected .obj, .gltf or .glb)");
  for (Instance& inst : parts) scene.instances.push_back(std::move(inst));
  try {
    scene.finalize();
  } catch (const Error& e) {
    throw Error("model '" + path + "': " + e.what());
  }
  // A camera that frames it, and a light above and in front, bright enough at the centre.
  const Camera cam = scene.frame_camera();
  scene.camera = cam;
  const Bounds b = scene.bounds(0.0f);
  const glm::vec3 center = 0.5f * (b.lo + b.hi);
  // (no absolute floor: 1e-6 put the light of a model 1e-9 across straight overhead, an outside sweep)
  const float radius = std::max(0.5f * glm::length(b.extent()), std::numeric_limits<float>::min());
  Light light;
  light.position = center + 0.5f * (cam.eye - center) + glm::vec3(0.0f, 2.0f * radius, 0.0f);
  const float d = glm::length(light.position - center);
  light.intensity = d * d;  // 1/d^2 falloff: unit irradiance at the centre
  scene.lights.push_back(light);
  return scene;
}

namespace {

// Material opacity is kept (the scene, its cache) but not rendered: every surface is opaque, and
// alpha masks are the transparency the grid traces. A material below 1 is said once per load,
// where it did nothing without a word (an outside sweep's find).
void warn_unrendered_opacity(const Scene& s, const std::string& what) {
  std::string names;
  size_t count = 0;
  for (const Material& m : s.materials)
    if (m.opacity < 1.0f && count++ < 3) names += (names.empty() ? "'" : ", '") + m.name + "'";
  if (count == 0) return;
  std::fprintf(stderr,
               "warning: %s: %zu material(s) with an opacity below 1 (%s%s): opacity is read but not rendered, "
               "every surface is opaque (alpha masks, map_d or glTF MASK, cut surfaces out)\n",
               what.c_str(), count, names.c_str(), count > 3 ? ", ..." : "");
}

Scene load_scene_any(std::string_view spec) {
  if (spec.rfind("builtin:", 0) == 0) {
    return make_builtin(spec.substr(8));
  }
  const std::string path(spec);
  const std::string ext = lower_extension(path);
  if (std::error_code ec; fs::is_directory(path, ec))
    throw Error("cannot load scene '" + path + "': it is a directory, not a scene file");
  if (ext == ".json") return load_scene_file(path);
  if (ext == ".gridscene") return load_scene_binary(path);
  if (ext == ".obj" || ext == ".gltf" || ext == ".glb") return load_model_scene(path);
  throw Error("cannot load scene '" + path + "': unknown extension '" + ext +
              "' (expected builtin:NAME, .json, .obj, .gltf, .glb or .gridscene)");
}

}  // namespace

Scene load_scene(std::string_view spec) {
  Scene s = load_scene_any(spec);
  // The name every message and report prints: its control bytes (a scene file's "name", a cache's,
  // a file name with a line break or an escape sequence) as \xNN, so that none reaches a terminal
  s.name = control_escaped(s.name);
  warn_unrendered_opacity(s, std::string(spec));
  return s;
}

// CRC-32 (zlib's) of `n` bytes at `p`.
static uint32_t crc32_of(const char* p, size_t n) {
  uLong crc = crc32(0L, Z_NULL, 0);
  while (n > 0) {
    const uInt chunk = uInt(std::min<size_t>(n, size_t(1) << 30));
    crc = crc32(crc, reinterpret_cast<const Bytef*>(p), chunk);
    p += chunk;
    n -= chunk;
  }
  return uint32_t(crc);
}

void save_scene_binary(const Scene& s, const std::string& path) {
  Writer w;
  w.out.append(kMagic, 8);
  w.pod(kSceneBinaryVersion);
  transfer_scene(w, s);
  w.out.append(kEndMagic, 8);
  // The checksum of everything before it: a damaged payload (a vertex, a texel) read back as
  // another scene without a word (an outside sweep flipped each byte of a cache: over half loaded)
  w.pod(crc32_of(w.out.data(), w.out.size()));

  // Temp file beside the target, checked, synced, then renamed: never a half-written cache.
  write_file_atomically(path, "scene cache", w.out);
}

Scene load_scene_binary(const std::string& path) {
  std::string data = read_text(path, "scene cache");
  {
    Reader head(data, path);
    head.need(8, "the magic number");
    if (std::memcmp(head.at(), kMagic, 8) != 0) head.fail("not a .gridscene file (wrong magic number)");
    head.skip(8);
    const uint32_t version = head.pod<uint32_t>("the version");
    if (version != 1 && version != kSceneBinaryVersion)
      head.fail("version " + std::to_string(version) + ", this build reads versions 1 and " +
                std::to_string(kSceneBinaryVersion) + " (convert the scene again)");
    // Version 2: the CRC-32 of every byte before its last four, checked before anything is read
    if (version == 2) {
      if (data.size() < 8 + 4 + 8 + 4) head.fail("truncated: no room for the end marker and the checksum");
      uint32_t stored;
      std::memcpy(&stored, data.data() + data.size() - 4, 4);
      data.resize(data.size() - 4);
      if (crc32_of(data.data(), data.size()) != stored)
        head.fail("checksum mismatch: the file is damaged (convert the scene again)");
    }
  }
  Reader r(data, path);
  r.skip(12);  // the magic number and the version, read above
  Scene s;
  transfer_scene(r, s);
  r.need(8, "the end marker");
  if (std::memcmp(r.at(), kEndMagic, 8) != 0) r.fail("end marker missing");
  r.skip(8);
  if (r.pos() != r.size()) r.fail(std::to_string(r.size() - r.pos()) + " bytes after the end marker");
  // Validate every index and number, as for any other scene (the scene was finalized when it was
  // saved, so this splits and reorders nothing).
  try {
    s.finalize();
  } catch (const Error& e) {
    r.fail(e.what());
  }
  return s;
}

}  // namespace gridrt
