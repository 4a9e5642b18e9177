// Loaders (OBJ, glTF), image I/O, scene files and the binary cache, on the project's fixtures
// and on the real scenes of ../shared/data/scenes.
#include <catch2/catch.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <map>
#include <mutex>
#include <optional>

#include <unistd.h>

#include <nlohmann/json.hpp>

#include "gridrt/common/image_io.h"
#include "gridrt/common/loaders/loaders.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/common/shared/alpha.h"
#include "gridrt/plan/plan.h"

using namespace gridrt;
namespace fs = std::filesystem;

namespace {

std::string fixture(const std::string& name) { return std::string(GRIDRT_DATA_DIR) + "/fixtures/" + name; }

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("gridrt-loaders-" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}

// The real scenes folder: $GRIDRT_SCENES, else the one beside the checkout. Empty when absent;
// absent is a skip, except under CI (env CI set), where it is a failure.
std::string real_scenes() {
  const char* env = std::getenv("GRIDRT_SCENES");
  const std::string dir = env && *env ? env : GRIDRT_SHARED_SCENES;
  if (fs::is_directory(dir)) return dir;
  if (std::getenv("CI")) FAIL("the real scenes folder '" << dir << "' is missing, and CI must test with it");
  WARN("skipped: the real scenes folder '" << dir << "' is missing (set GRIDRT_SCENES)");
  return "";
}

// Each real scene is loaded once per test run (they take a second or more each in Debug).
const Scene& cached(const std::string& spec) {
  static std::map<std::string, Scene> cache;
  static std::mutex mutex;
  std::lock_guard lock(mutex);
  auto it = cache.find(spec);
  if (it == cache.end()) {
    const auto t0 = std::chrono::steady_clock::now();
    it = cache.emplace(spec, load_scene(spec)).first;
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::cerr << "loaded " << spec << " in " << s << " s\n";
  }
  return it->second;
}

size_t count_named(const Scene& s, const std::string& prefix) {
  size_t n = 0;
  for (const Material& m : s.materials) n += m.name.rfind(prefix, 0) == 0;
  return n;
}

// A fresh scratch folder for a texture test, or none (with a warning) where this build has no
// OpenImageIO to read textures.
std::optional<fs::path> texture_scratch(const std::string& name) {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO");
    return std::nullopt;
  }
  const fs::path dir = fs::temp_directory_path() / ("gridrt_" + name + "_" + std::to_string(getpid()));
  fs::create_directories(dir);
  return dir;
}

}  // namespace

// ---- Fixtures ------------------------------------------------------------------------------

TEST_CASE("OBJ: polygons triangulated, vertices welded by index triple, materials and textures", "[unit][loaders]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  Scene s;
  TextureCache cache;
  const auto inst = load_obj(fixture("quad.obj"), s, cache);
  REQUIRE(inst.size() == 1);
  REQUIRE(s.meshes.size() == 1);
  const Mesh& m = s.meshes[0];
  // A quad (2 triangles), a pentagon (3) and a triangle (1).
  CHECK(m.triangle_count() == 6);
  // Distinct (v, vt, vn) triples: 1/1/1 2/2/1 3/3/1 4/4/1 5/2/1 6/3/1 7/3/1 1//1 2//1 4//1.
  CHECK(m.positions.size() == 10);
  REQUIRE(m.normals.size() == 10);
  REQUIRE(m.uvs.size() == 10);
  CHECK(m.uvs[m.triangles[0][1]] == glm::vec2(1, 0));
  // Materials: leaf, plain, graymask, in MTL order; faces keep theirs.
  REQUIRE(s.materials.size() == 3);
  CHECK(s.materials[0].name == "leaf");
  CHECK(s.materials[0].diffuse == glm::vec3(0.2f, 0.6f, 0.1f));
  CHECK(m.materials == std::vector<uint32_t>{0, 0, 0, 0, 0, 1});
  CHECK(s.materials[1].opacity == 0.5f);
  CHECK(s.materials[1].diffuse_texture == -1);
  CHECK(s.materials[0].glossiness == 0.0f);
  // map_Kd and map_d of one RGBA file share one texture; graymask, which no face uses, keeps its
  // place and decodes nothing (its grey map_d below, on a face that uses it)
  REQUIRE(s.textures.size() == 1);
  CHECK(s.materials[0].diffuse_texture == s.materials[0].alpha_texture);
  const Texture& leaf = s.textures[size_t(s.materials[0].alpha_texture)];
  CHECK(leaf.width == 2);
  CHECK(leaf.height == 2);
  CHECK(leaf.has_alpha);
  CHECK(leaf.texel(0, 0) == glm::u8vec4(255, 0, 0, 255));  // row 0 = first row of the file
  CHECK(leaf.texel(1, 0) == glm::u8vec4(0, 255, 0, 0));
  CHECK(leaf.texel(0, 1) == glm::u8vec4(0, 0, 255, 200));
  CHECK(s.materials[2].name == "graymask");
  CHECK(s.materials[2].alpha_texture == -1);
  // A gray map_d takes its first channel: the fixture's material on a face of its own
  const fs::path d = temp_dir();
  fs::copy_file(fixture("quad.mtl"), d / "quad.mtl");
  fs::copy_file(fixture("gray4x2.png"), d / "gray4x2.png");
  fs::copy_file(fixture("rgba2x2.png"), d / "rgba2x2.png");
  Scene g;
  TextureCache gcache;
  std::ofstream(d / "gray.obj") << "mtllib quad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                   "usemtl graymask\nf 1/1 2/2 3/3\n";
  load_obj((d / "gray.obj").string(), g, gcache);
  REQUIRE(g.materials.size() == 3);
  REQUIRE(g.materials[2].alpha_texture >= 0);
  const Texture& gray = g.textures[size_t(g.materials[2].alpha_texture)];
  CHECK(gray.width == 4);
  CHECK(gray.texel(1, 0).a == 255);
  CHECK(gray.texel(0, 0).a == 0);
  CHECK(gray.texel(3, 1).a == 128);
  CHECK(g.materials[2].diffuse_texture == -1);
  fs::remove_all(d);
}

TEST_CASE("glTF and GLB: node hierarchy, flipped v, MASK material", "[unit][loaders]") {
  for (const char* file : {"quad.gltf", "quad.glb"}) {
    INFO(file);
    Scene s;
    TextureCache cache;
    const auto inst = load_gltf(fixture(file), s, cache);
    REQUIRE(s.meshes.size() == 1);
    REQUIRE(inst.size() == 2);  // two nodes share the mesh
    const Mesh& m = s.meshes[0];
    CHECK(m.triangle_count() == 2);
    CHECK(m.positions.size() == 4);
    CHECK(m.normals.size() == 4);
    // World matrices: parent translation (10, 0, 0) times child scale 2 / translation (0, 5, 0).
    CHECK(inst[0].name == "quad");
    CHECK(glm::vec3(inst[0].transform * glm::vec4(1, 1, 0, 1)) == glm::vec3(12, 2, 0));
    CHECK(glm::vec3(inst[1].transform * glm::vec4(1, 1, 0, 1)) == glm::vec3(11, 6, 0));
    // v flipped (1 - v); where that is a whole number (glTF's v = 1 and v = 0 here), the next
    // float below it, so that the rule reads the first row there, as glTF's repeating texture does
    CHECK(m.uvs[0] == glm::vec2(0, std::nextafter(0.0f, -1.0f)));
    CHECK(m.uvs[2] == glm::vec2(1, std::nextafter(1.0f, 0.0f)));
    REQUIRE(s.materials.size() == 1);
    const Material& mat = s.materials[0];
    CHECK(mat.name == "leaf");
    CHECK(mat.diffuse == glm::vec3(0.5f, 0.25f, 1.0f));
    CHECK(mat.alpha_keyed());
    CHECK(mat.alpha_texture == mat.diffuse_texture);
    REQUIRE(s.textures.size() == 1);
    CHECK(s.textures[0].width == 2);
    CHECK(s.textures[0].texel(1, 0) == glm::u8vec4(0, 255, 0, 0));
    CHECK(s.textures[0].has_alpha);
  }
}

namespace {

std::string base64(const std::string& bin) {
  static const char* b64 = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string enc;
  for (size_t i = 0; i < bin.size(); i += 3) {
    uint32_t v = uint32_t(uint8_t(bin[i])) << 16;
    if (i + 1 < bin.size()) v |= uint32_t(uint8_t(bin[i + 1])) << 8;
    if (i + 2 < bin.size()) v |= uint32_t(uint8_t(bin[i + 2]));
    enc += b64[(v >> 18) & 63];
    enc += b64[(v >> 12) & 63];
    enc += i + 1 < bin.size() ? b64[(v >> 6) & 63] : '=';
    enc += i + 2 < bin.size() ? b64[v & 63] : '=';
  }
  return enc;
}

// A glTF file of `materials.size()` triangles, triangle k with material k, every vertex's
// TEXCOORD_0 `uv`, each material's base colour texture the image `image_uri`; `image_json`
// replaces the image's object where given.
std::string gltf_textured(glm::vec2 uv, const std::vector<std::string>& materials, const std::string& image_uri,
                          const std::string& image_json = "") {
  std::string bin;
  std::string primitives, mats;
  const size_t n = materials.size();
  for (size_t k = 0; k < n; ++k) {
    const float x = float(2 * k);
    const float pos[9] = {x, 0, 0, x + 1, 0, 0, x, 1, 0};
    bin.append(reinterpret_cast<const char*>(pos), sizeof pos);
  }
  const size_t uv_offset = bin.size();
  for (size_t v = 0; v < 3 * n; ++v) bin.append(reinterpret_cast<const char*>(&uv), sizeof uv);
  std::string views = "{\"buffer\":0,\"byteOffset\":0,\"byteLength\":" + std::to_string(uv_offset) +
                      "},{\"buffer\":0,\"byteOffset\":" + std::to_string(uv_offset) +
                      ",\"byteLength\":" + std::to_string(bin.size() - uv_offset) + "}";
  std::string accessors;
  for (size_t k = 0; k < n; ++k) {
    accessors += std::string(k ? "," : "") + "{\"bufferView\":0,\"byteOffset\":" + std::to_string(36 * k) +
                 ",\"componentType\":5126,\"count\":3,\"type\":\"VEC3\"},{\"bufferView\":1,\"byteOffset\":" +
                 std::to_string(24 * k) + ",\"componentType\":5126,\"count\":3,\"type\":\"VEC2\"}";
    primitives += std::string(k ? "," : "") + "{\"attributes\":{\"POSITION\":" + std::to_string(2 * k) +
                  ",\"TEXCOORD_0\":" + std::to_string(2 * k + 1) + "},\"material\":" + std::to_string(k) + "}";
    mats += std::string(k ? "," : "") + materials[k];
  }
  const std::string image = image_json.empty() ? "{\"uri\":\"" + image_uri + "\"}" : image_json;
  return "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
         "\"meshes\":[{\"primitives\":[" + primitives + "]}],\"accessors\":[" + accessors + "],\"bufferViews\":[" +
         views + "],\"buffers\":[{\"byteLength\":" + std::to_string(bin.size()) +
         ",\"uri\":\"data:application/octet-stream;base64," + base64(bin) + "\"}],\"materials\":[" + mats +
         "],\"textures\":[{\"source\":0}],\"images\":[" + image + "]}";
}

// A glTF file of one mesh over the unit square's corners (0,0) (1,0) (0,1) (1,1) at z = 0: one
// primitive per (mode, indices) pair, unsigned-short indices, the buffer inline as base64.
std::string gltf_with_primitives(const std::vector<std::pair<int, std::vector<uint16_t>>>& prims) {
  std::string bin;
  const float pos[12] = {0, 0, 0, 1, 0, 0, 0, 1, 0, 1, 1, 0};
  bin.append(reinterpret_cast<const char*>(pos), sizeof pos);
  std::string views = "{\"buffer\":0,\"byteOffset\":0,\"byteLength\":48}";
  std::string accessors = "{\"bufferView\":0,\"componentType\":5126,\"count\":4,\"type\":\"VEC3\"}";
  std::string primitives;
  for (size_t k = 0; k < prims.size(); ++k) {
    const size_t offset = bin.size();
    bin.append(reinterpret_cast<const char*>(prims[k].second.data()), prims[k].second.size() * 2);
    while (bin.size() % 4) bin.push_back('\0');
    views += ",{\"buffer\":0,\"byteOffset\":" + std::to_string(offset) +
             ",\"byteLength\":" + std::to_string(prims[k].second.size() * 2) + "}";
    accessors += ",{\"bufferView\":" + std::to_string(k + 1) + ",\"componentType\":5123,\"count\":" +
                 std::to_string(prims[k].second.size()) + ",\"type\":\"SCALAR\"}";
    primitives += std::string(k ? "," : "") + "{\"attributes\":{\"POSITION\":0},\"indices\":" + std::to_string(k + 1) +
                  ",\"mode\":" + std::to_string(prims[k].first) + "}";
  }
  const std::string enc = base64(bin);
  return "{\"asset\":{\"version\":\"2.0\"},\"scene\":0,\"scenes\":[{\"nodes\":[0]}],\"nodes\":[{\"mesh\":0}],"
         "\"meshes\":[{\"primitives\":[" + primitives + "]}],\"accessors\":[" + accessors + "],\"bufferViews\":[" +
         views + "],\"buffers\":[{\"byteLength\":" + std::to_string(bin.size()) +
         ",\"uri\":\"data:application/octet-stream;base64," + enc + "\"}]}";
}

std::string write_text(const fs::path& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
  return path.string();
}

}  // namespace

TEST_CASE("glTF triangle strips and fans: every triangle, one winding - points and lines left out", "[unit][loaders]") {
  const fs::path d = temp_dir();
  // The square as a strip (0 1 2 3) and as a fan (0 1 3 2), each two triangles facing +z; a line
  // primitive beside them adds nothing
  const std::string path =
      write_text(d / "topology.gltf", gltf_with_primitives({{5, {0, 1, 2, 3}}, {6, {0, 1, 3, 2}}, {1, {0, 3}}}));
  Scene s;
  TextureCache cache;
  load_gltf(path, s, cache);
  REQUIRE(s.meshes.size() == 1);
  const Mesh& m = s.meshes[0];
  REQUIRE(m.triangle_count() == 4);
  double area = 0.0;
  for (const glm::uvec3& t : m.triangles) {
    const glm::vec3 n = glm::cross(m.positions[t.y] - m.positions[t.x], m.positions[t.z] - m.positions[t.x]);
    CHECK(n.z > 0.0f);  // the first triangle's winding kept by every later one
    area += 0.5 * double(glm::length(n));
  }
  CHECK(area == Approx(2.0));  // each form covers the square once
  // A mode outside glTF's seven, and a strip too short for a triangle: errors naming the primitive
  Scene bad;
  CHECK_THROWS_WITH(load_gltf(write_text(d / "mode7.gltf", gltf_with_primitives({{7, {0, 1, 2}}})), bad, cache),
                    Catch::Contains("primitive 0: mode 7 is not a glTF primitive mode"));
  CHECK_THROWS_WITH(load_gltf(write_text(d / "short.gltf", gltf_with_primitives({{5, {0, 1}}})), bad, cache),
                    Catch::Contains("a triangle strip of 2 vertices (at least 3)"));
  // Primitives sharing one index accessor: the triangles they make are held to --max-triangles from
  // the accessors' counts, before any is read (2,000 primitives of a 3,000-index accessor asked
  // for gigabytes of a 2 MB file before the limit refused the scene: an outside sweep)
  {
    nlohmann::json j = nlohmann::json::parse(gltf_with_primitives({{4, std::vector<uint16_t>(3000, 0)}}));
    const nlohmann::json prim = j["meshes"][0]["primitives"][0];
    for (int k = 1; k < 2000; ++k) j["meshes"][0]["primitives"].push_back(prim);
    const uint64_t before = input_limits().max_triangles;
    input_limits().max_triangles = 10000;
    Scene many;
    CHECK_THROWS_WITH(load_gltf(write_text(d / "shared.gltf", j.dump()), many, cache),
                      Catch::Contains("primitives[10]") && Catch::Contains("--max-triangles"));
    input_limits().max_triangles = before;
    CHECK(many.meshes.empty());
  }
  // A key given twice in one object: refused by its path (TinyGLTF kept the last, a node moved)
  {
    nlohmann::json j = nlohmann::json::parse(gltf_with_primitives({{4, {0, 1, 2}}}));
    std::string text = j.dump();
    const std::string node = "{\"mesh\":0}";
    REQUIRE(text.find(node) != std::string::npos);
    text.replace(text.find(node), node.size(), "{\"mesh\":0,\"translation\":[0,0,0],\"translation\":[5,0,0]}");
    Scene twice;
    CHECK_THROWS_WITH(load_gltf(write_text(d / "twice.gltf", text), twice, cache),
                      Catch::Contains("translation") && Catch::Contains("given twice"));
  }
}

TEST_CASE("Image output: PPM and PFM by hand, PNG and EXR through OpenImageIO, read back", "[unit][image]") {
  const fs::path dir = temp_dir();
  const std::vector<glm::vec3> px = {{0, 0, 0}, {1, 0.5f, 0.25f}, {0.2f, 2.0f, -1.0f}, {0.0031308f, 0.5f, 1.0f}};
  CHECK(linear_to_srgb8(0.5f) == 188);
  CHECK(linear_to_srgb8(std::numeric_limits<float>::quiet_NaN()) == 0);
  const std::string ppm = (dir / "a.ppm").string();
  write_image(ppm, 2, 2, px);
  {
    std::ifstream f(ppm, std::ios::binary);
    std::string all((std::istreambuf_iterator<char>(f)), {});
    REQUIRE(all.rfind("P6\n2 2\n255\n", 0) == 0);
    REQUIRE(all.size() == 11 + 12);
    CHECK(uint8_t(all[11 + 3]) == 255);
    CHECK(uint8_t(all[11 + 4]) == 188);
  }
  const std::string pfm = (dir / "a.pfm").string();
  write_image(pfm, 2, 2, px);
  CHECK(fs::file_size(pfm) == std::string("PF\n2 2\n-1.0\n").size() + 4 * 12);
  if (have_image_library()) {
    const std::string png = (dir / "a.png").string();
    write_image(png, 2, 2, px);
    const Texture t = load_texture(png);
    CHECK(t.width == 2);
    CHECK(t.height == 2);
    CHECK(t.texel(1, 0) == glm::u8vec4(255, 188, 137, 255));
    CHECK(t.texel(0, 1) == glm::u8vec4(124, 255, 0, 255));
    write_image((dir / "a.exr").string(), 2, 2, px);
    CHECK(fs::file_size(dir / "a.exr") > 0);
  }
  // Only the final files, no temporaries.
  size_t files = 0;
  for (const auto& e : fs::directory_iterator(dir)) files += e.path().filename().string()[0] != '.';
  size_t all = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir)) ++all;
  CHECK(files == all);
  fs::remove_all(dir);
}

TEST_CASE("Scene file: meshes, instances, motion, materials, camera, lights, grid", "[unit][scenefile]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const Scene s = load_scene(fixture("scene_small.json"));
  CHECK(s.name == "small");
  // floor + spinner (the OBJ) + walker (2 glTF nodes): 4 instances, dynamic ones last.
  REQUIRE(s.instances.size() == 4);
  CHECK(s.static_instance_count() == 1);
  CHECK(s.instances[0].name == "floor");
  CHECK(s.instances[1].name == "spinner");
  CHECK(s.instances[2].name == "walker/quad");
  CHECK(s.has_dynamic());
  // Rotating in place: the default pivot is the instance's translation.
  CHECK(s.instances[1].motion.pivot == glm::vec3(1, 0, 2));
  CHECK(s.instances[1].motion.angular_speed == 1.5f);
  CHECK(s.instances[2].motion.path_points.size() == 3);
  CHECK(s.instances[2].motion.path_period == 3.0f);
  // Floor: rotated -90 degrees about x, scaled 10: (1, 1, 0) -> (10, 0, -10).
  const glm::vec3 p = glm::vec3(s.instances[0].transform * glm::vec4(1, 1, 0, 1));
  CHECK(p.x == Approx(10));
  CHECK(p.y == Approx(0).margin(1e-5));
  CHECK(p.z == Approx(-10));
  // Materials: default glossiness, then the override by name.
  for (const Material& m : s.materials) CHECK(m.glossiness == (m.name == "plain" ? 0.7f : 0.1f));
  CHECK(s.has_glossy());
  CHECK(s.has_alpha_masks());
  REQUIRE(s.camera);
  CHECK(s.camera->vfov_degrees == 50.0f);
  REQUIRE(s.lights.size() == 2);
  CHECK(s.lights[0].intensity == 40.0f);
  CHECK(s.lights[1].directional);
  CHECK(s.grid.resolution == glm::uvec3(16, 8, 16));
  CHECK(s.grid.capacity == 12u);
  CHECK_FALSE(s.grid.cell_size);
  CHECK(s.background == glm::vec3(0.1f, 0.1f, 0.2f));
}

TEST_CASE("A bare model loads as a framed scene with a light", "[unit][scenefile]") {
  const Scene s = load_scene(fixture("quad.glb"));
  CHECK(s.instances.size() == 2);
  CHECK(s.static_instance_count() == 2);
  REQUIRE(s.camera);
  REQUIRE(s.lights.size() == 1);
  const Bounds b = s.bounds();
  CHECK(s.lights[0].position.y > b.hi.y);
}

namespace {
void check_same(const Scene& a, const Scene& b) {
  CHECK(a.name == b.name);
  CHECK(a.background == b.background);
  REQUIRE(a.meshes.size() == b.meshes.size());
  for (size_t i = 0; i < a.meshes.size(); ++i) {
    CHECK(a.meshes[i].name == b.meshes[i].name);
    CHECK(a.meshes[i].positions == b.meshes[i].positions);
    CHECK(a.meshes[i].normals == b.meshes[i].normals);
    CHECK(a.meshes[i].uvs == b.meshes[i].uvs);
    CHECK(a.meshes[i].triangles == b.meshes[i].triangles);
    CHECK(a.meshes[i].materials == b.meshes[i].materials);
  }
  REQUIRE(a.materials.size() == b.materials.size());
  for (size_t i = 0; i < a.materials.size(); ++i) {
    const Material &x = a.materials[i], &y = b.materials[i];
    CHECK((x.name == y.name && x.diffuse == y.diffuse && x.diffuse_texture == y.diffuse_texture &&
           x.alpha_texture == y.alpha_texture && x.glossiness == y.glossiness && x.opacity == y.opacity));
  }
  REQUIRE(a.textures.size() == b.textures.size());
  for (size_t i = 0; i < a.textures.size(); ++i) {
    const Texture &x = a.textures[i], &y = b.textures[i];
    CHECK((x.path == y.path && x.width == y.width && x.height == y.height && x.has_alpha == y.has_alpha && x.rgba == y.rgba));
  }
  REQUIRE(a.instances.size() == b.instances.size());
  for (size_t i = 0; i < a.instances.size(); ++i) {
    const Instance &x = a.instances[i], &y = b.instances[i];
    CHECK((x.name == y.name && x.mesh == y.mesh && x.transform == y.transform && x.dynamic == y.dynamic &&
           x.motion.axis == y.motion.axis && x.motion.pivot == y.motion.pivot &&
           x.motion.angular_speed == y.motion.angular_speed && x.motion.path_points == y.motion.path_points &&
           x.motion.path_period == y.motion.path_period));
  }
  REQUIRE(a.camera.has_value() == b.camera.has_value());
  if (a.camera)
    CHECK((a.camera->eye == b.camera->eye && a.camera->target == b.camera->target && a.camera->up == b.camera->up &&
           a.camera->vfov_degrees == b.camera->vfov_degrees));
  REQUIRE(a.lights.size() == b.lights.size());
  for (size_t i = 0; i < a.lights.size(); ++i)
    CHECK((a.lights[i].position == b.lights[i].position && a.lights[i].color == b.lights[i].color &&
           a.lights[i].intensity == b.lights[i].intensity && a.lights[i].directional == b.lights[i].directional));
  CHECK(a.grid.resolution == b.grid.resolution);
  CHECK(a.grid.capacity == b.grid.capacity);
  CHECK(a.grid.cell_size == b.grid.cell_size);
}
}  // namespace

TEST_CASE("Binary scene cache round trip gives an identical scene", "[unit][scenefile]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const fs::path dir = temp_dir();
  Scene a = load_scene(fixture("scene_small.json"));
  a.grid.resolution.reset();  // the cell size in its place (a scene gives one of them)
  a.grid.cell_size = 0.25f;
  const std::string path = (dir / "small.gridscene").string();
  save_scene_binary(a, path);
  const Scene b = load_scene(path);
  check_same(a, b);
  // Saving again gives the same bytes.
  save_scene_binary(b, (dir / "again.gridscene").string());
  CHECK(fs::file_size(path) == fs::file_size(dir / "again.gridscene"));
  fs::remove_all(dir);
}

// ---- Real scenes -------------------------------------------------------------------------------

TEST_CASE("Real scenes load with the README's triangle counts", "[scenes]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const std::string dir = real_scenes();
  if (dir.empty()) return;
  // Every face of these files is already a triangle (checked with awk), and no triangle is
  // dropped: degenerate (zero-area) ones are kept (sibenik has ~1.1k), as the README counts them.
  struct Expect { const char* file; uint64_t triangles; size_t materials; size_t meshes; };
  for (const Expect& e : {Expect{"sibenik/sibenik.obj", 80479, 18, 2}, Expect{"sponza/sponza.obj", 66454, 20, 2},
                          Expect{"ons-reborn/ons-reborn.obj", 125101, 72, 2}, Expect{"bunny/bunny.obj", 69451, 1, 2},
                          Expect{"teapot/teapot-992.obj", 992, 1, 1}}) {
    INFO(e.file);
    const Scene& s = cached(dir + "/" + e.file);
    CHECK(s.triangle_count() == e.triangles);
    // Over 65,536 triangles: split into pieces of at most 65,536.
    CHECK(s.meshes.size() == e.meshes);
    for (const Mesh& m : s.meshes) CHECK(m.triangle_count() <= kMaxTrianglesPerMesh);
    CHECK(s.instances.size() == e.meshes);
    CHECK(s.materials.size() == e.materials);  // the MTL's (bunny, teapot: one default)
    CHECK(s.camera);
    CHECK(s.lights.size() == 1);
  }
}

TEST_CASE("Real scenes: textures load with sane sizes - ons-reborn's foliage is alpha-masked", "[scenes]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const std::string dir = real_scenes();
  if (dir.empty()) return;
  for (const char* file : {"sibenik/sibenik.obj", "sponza/sponza.obj", "ons-reborn/ons-reborn.obj"}) {
    INFO(file);
    const Scene& s = cached(dir + "/" + file);
    CHECK_FALSE(s.textures.empty());
    for (const Texture& t : s.textures) {
      INFO(t.path);
      CHECK(t.width >= 1);
      CHECK(t.width <= 4096);
      CHECK(t.height >= 1);
      CHECK(t.height <= 4096);
      CHECK(t.rgba.size() == size_t(t.width) * t.height * 4);
    }
  }
  const Scene& ons = cached(dir + "/ons-reborn/ons-reborn.obj");
  // The three materials with map_d: grass02, leaves4, textures/morph/leaves3.
  std::vector<std::string> masked;
  for (const Material& m : ons.materials)
    if (m.alpha_keyed()) masked.push_back(m.name);
  CHECK(masked == std::vector<std::string>{"grass02", "leaves4", "textures/morph/leaves3"});
  for (const Material& m : ons.materials)
    if (m.alpha_keyed()) {
      const Texture& t = ons.textures[size_t(m.alpha_texture)];
      CHECK(t.has_alpha);  // the foliage really has holes
      CHECK(m.alpha_texture == m.diffuse_texture);  // same TGA, decoded once
    }
  CHECK(ons.has_alpha_masks());
  CHECK_FALSE(cached(dir + "/sponza/sponza.obj").has_alpha_masks());
  // Sibenik's glass: d 0.5.
  CHECK(cached(dir + "/sibenik/sibenik.obj").materials.size() == 18);
  CHECK(count_named(cached(dir + "/sibenik/sibenik.obj"), "staklo") >= 4);
}

TEST_CASE("The paper's scene files load - their dynamic instances move between t = 0 and t = 1", "[scenes]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  if (real_scenes().empty()) return;
  const std::string dir = std::string(GRIDRT_DATA_DIR) + "/scenes/";
  struct Expect { const char* file; uint64_t static_triangles; size_t dynamic; bool alpha; };
  for (const Expect& e : {Expect{"sibenik-teapots.json", 80479, 3, false}, Expect{"sponza-teapots.json", 66454, 3, false},
                          Expect{"ons-reborn-teapot.json", 125101, 1, true}, Expect{"teapot.json", 0, 1, false},
                          Expect{"bunny.json", 69451, 0, false}}) {
    INFO(e.file);
    const Scene& s = cached(dir + e.file);
    CHECK(s.instances.size() - s.static_instance_count() == e.dynamic);
    CHECK(s.triangle_count() == e.static_triangles + 992 * e.dynamic);
    CHECK(s.has_alpha_masks() == e.alpha);
    CHECK(s.camera);
    CHECK(s.lights.size() == 1);
    for (const Instance& inst : s.instances) {
      if (!inst.dynamic) continue;
      INFO(inst.name);
      CHECK(inst.motion.moves());
      const glm::vec3 p(1.0f, 2.0f, 3.0f);  // an off-axis point of the teapot
      const glm::vec3 a(inst.transform_at(0.0f) * glm::vec4(p, 1.0f)), b(inst.transform_at(1.0f) * glm::vec4(p, 1.0f));
      CHECK(glm::length(b - a) > 1e-3f * glm::length(s.bounds().extent()));
    }
    // The paper's frames have a glossy floor (the glossy bounce matters; the foliage level's terrain).
    if (e.dynamic > 0) CHECK(s.has_glossy());
  }
  // Teapots stand on the floor: their lowest point at t = 0 lies within 1 cm of the floor.
  const Scene& sib = cached(dir + "sibenik-teapots.json");
  for (const Instance& inst : sib.instances)
    if (inst.dynamic) {
      float low = 1e30f;
      for (const glm::vec3& q : sib.meshes[inst.mesh].positions) low = std::min(low, (inst.transform_at(0.0f) * glm::vec4(q, 1.0f)).y);
      CHECK(low == Approx(0.001f).margin(0.01f));
    }
}

TEST_CASE("A real scene survives the binary cache unchanged", "[scenes]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  if (real_scenes().empty()) return;
  const Scene& a = cached(std::string(GRIDRT_DATA_DIR) + "/scenes/ons-reborn-teapot.json");
  const fs::path dir = temp_dir();
  const std::string path = (dir / "ons.gridscene").string();
  const auto t0 = std::chrono::steady_clock::now();
  save_scene_binary(a, path);
  const auto t1 = std::chrono::steady_clock::now();
  const Scene b = load_scene(path);
  const auto t2 = std::chrono::steady_clock::now();
  std::cerr << "ons-reborn-teapot.gridscene: " << fs::file_size(path) / 1e6 << " MB, saved in "
            << std::chrono::duration<double>(t1 - t0).count() << " s, loaded in " << std::chrono::duration<double>(t2 - t1).count() << " s\n";
  check_same(a, b);
  fs::remove_all(dir);
}

TEST_CASE("Scene files and the dispatcher reach the built-in scenes", "[unit][scenefile]") {
  const Scene s = load_scene(fixture("builtin_teapot.json"));
  REQUIRE(s.meshes.size() == 1);
  CHECK(s.meshes[0].triangle_count() > 0);
  REQUIRE(s.materials.size() == 1);
  CHECK(s.materials[0].name == "pot");
  CHECK(s.materials[0].glossiness == 0.5f);
  CHECK(s.materials[0].diffuse == glm::vec3(0.8f, 0.2f, 0.2f));
  CHECK(s.has_dynamic());
  const Scene b = load_scene("builtin:teapot");
  CHECK(b.triangle_count() > 0);
  REQUIRE_THROWS_WITH(load_scene("builtin:nosuch"), Catch::Contains("nosuch"));
}

TEST_CASE("glTF MASK without a texture: the factor's alpha alone keeps or cuts the material", "[unit][loaders]") {
  // An outside sweep's find: a MASK material with baseColorFactor alpha 0.2 (cutoff 0.5) and no
  // texture rendered opaque; by glTF 2.0 its alpha is the factor's, so every fragment is cut
  const fs::path d = temp_dir();
  for (const float a : {0.2f, 0.5f, 0.8f}) {
    std::string text = gltf_with_primitives({{4, {0, 1, 2}}});
    const std::string mode = "\"mode\":4}";
    text.replace(text.find(mode), mode.size(), "\"mode\":4,\"material\":0}");
    text.insert(text.size() - 1, ",\"materials\":[{\"alphaMode\":\"MASK\",\"alphaCutoff\":0.5,"
                                 "\"pbrMetallicRoughness\":{\"baseColorFactor\":[1,1,1," + std::to_string(a) + "]}}]");
    Scene s;
    TextureCache cache;
    load_gltf(write_text(d / "mask_factor.gltf", text), s, cache);
    INFO("factor alpha " << a);
    REQUIRE(s.materials.size() == 1);
    const Material& m = s.materials[0];
    CHECK(m.diffuse_texture == -1);
    CHECK(m.alpha_keyed() == (a < 0.5f));  // glTF: cut where alpha < cutoff
    if (m.alpha_keyed()) {
      const Texture& t = s.textures[size_t(m.alpha_texture)];
      CHECK((t.width == 1 && t.height == 1 && t.texel(0, 0).a == 0));
    }
  }
}

// Outside sweeps' finds: glTF put v = 0 at the image's first row, and the loader flipped v to
// 1 - v, which for a v of 0 (or below about 3e-8, rounding to 1) read the last row instead: a
// strip of constant v = 0 was cut where its texel is opaque. (Storing the rows last first instead
// put every tie v = k / h a row off: a review's find.) Now a flipped v that is a whole number
// takes the next float below it. Two MASK cutoffs six digits apart shared one baked mask (its key
// printed 6 digits).
TEST_CASE("glTF textures: v reads glTF's nearest row, ties and v = 0 included, masks keyed by exact cutoffs",
          "[unit][loaders]") {
  const fs::path d = temp_dir();
  // 1 x 2 texels: the file's first row opaque, its second transparent; the alpha 128 of a third
  // file tells two cutoffs apart (128 / 255 = 0.50196078)
  const std::vector<uint8_t> rows = {255, 255, 255, 255, 255, 255, 255, 0};
  write_image_rgba8((d / "rows.png").string(), 1, 2, rows);
  const std::string mask = R"({"alphaMode":"MASK","pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
  for (const float v : {0.0f, 1e-8f, 2e-8f, 0.25f, 0.4999999f, 0.5f, 0.75f, 1.0f, 3.0f, -0.5f, -1.0f}) {
    INFO("v = " << v);
    Scene s;
    TextureCache cache;
    load_gltf(write_text(d / "row.gltf", gltf_textured(glm::vec2(0.5f, v), {mask}, "rows.png")), s, cache);
    REQUIRE(s.materials.size() == 1);
    const Texture& t = s.textures[size_t(s.materials[0].alpha_texture)];
    const glm::uvec2 xy = shared::alpha_texel_coords(s.meshes[0].uvs[0], t.width, t.height);
    // glTF's nearest texel: row floor(frac(v) * 2) of the file, the first opaque, the second not
    const double f = double(v) - std::floor(double(v));
    const bool first_row = std::floor(f * 2.0) == 0.0;
    CHECK(t.texel(xy.x, xy.y).a == (first_row ? 255 : 0));
  }
  const std::vector<uint8_t> half = {255, 255, 255, 128};
  write_image_rgba8((d / "half.png").string(), 1, 1, half);
  Scene s;
  TextureCache cache;
  const std::string a = R"({"alphaMode":"MASK","alphaCutoff":0.5019606,"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
  const std::string b = R"({"alphaMode":"MASK","alphaCutoff":0.5019612,"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
  load_gltf(write_text(d / "cutoffs.gltf", gltf_textured(glm::vec2(0.5f), {a, b}, "half.png")), s, cache);
  REQUIRE(s.materials.size() == 2);
  CHECK(s.materials[0].alpha_texture != s.materials[1].alpha_texture);
  CHECK(s.textures[size_t(s.materials[0].alpha_texture)].texel(0, 0).a == 255);  // 0.50196 >= 0.5019606: kept
  CHECK(s.textures[size_t(s.materials[1].alpha_texture)].texel(0, 0).a == 0);    // below 0.5019612: cut
}

// An outside sweep's find: an image in a buffer view whose offset lay past its buffer was handed
// to the decoder as the buffer's bytes from that offset, unchecked (2^31 past it: a crash).
TEST_CASE("glTF: an image's buffer view past its buffer, an unknown alphaMode, a negative cutoff are refused",
          "[unit][loaders][badinput]") {
  const fs::path d = temp_dir();
  const std::string mask = R"({"alphaMode":"MASK","pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
  for (const std::string offset : {"2147483648", "4611686018427387904", "40"}) {
    std::string text = gltf_textured(glm::vec2(0.5f), {mask}, "", R"({"bufferView":2,"mimeType":"image/png"})");
    // A third view over the buffer's end (its 60 bytes), the image's
    const std::string views_end = "}],\"buffers\"";
    text.replace(text.find(views_end), views_end.size(),
                 "},{\"buffer\":0,\"byteOffset\":" + offset + ",\"byteLength\":72}],\"buffers\"");
    Scene s;
    TextureCache cache;
    INFO("offset " << offset);
    CHECK_THROWS_WITH(load_gltf(write_text(d / "view.gltf", text), s, cache), Catch::Contains("lies past buffer 0"));
  }
  for (const auto& [material, why] : std::vector<std::pair<std::string, std::string>>{
           {R"({"alphaMode":"MASKED"})", "is none of OPAQUE, MASK, BLEND"},
           {R"({"alphaMode":"MASK","alphaCutoff":-1})", "is below 0"}}) {
    Scene s;
    TextureCache cache;
    const std::vector<uint8_t> texel = {255, 255, 255, 255};
    write_image_rgba8((d / "one.png").string(), 1, 1, texel);
    CHECK_THROWS_WITH(load_gltf(write_text(d / "mode.gltf", gltf_textured(glm::vec2(0.5f), {material}, "one.png")), s, cache),
                      Catch::Contains(why));
  }
  // Another major version than 2 (the spec asks a loader to refuse it; "3.0" was read as 2.0)
  {
    std::string text = gltf_with_primitives({{4, {0, 1, 2}}});
    text.replace(text.find("\"2.0\""), 5, "\"3.0\"");
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_gltf(write_text(d / "v3.gltf", text), s, cache), Catch::Contains("asset.version is '3.0'"));
  }
  // asset.minVersion above 2.0, and the extensions' lists given as one name: read as absent before
  for (const auto& [insert, why] : std::vector<std::pair<std::string, std::string>>{
           {R"("minVersion":"3.0",)", "asset.minVersion: is \"3.0\""},
           {R"("minVersion":"2.1",)", "asset.minVersion: is \"2.1\""}}) {
    std::string text = gltf_with_primitives({{4, {0, 1, 2}}});
    text.replace(text.find("\"version\""), 0, insert);
    Scene s;
    TextureCache cache;
    INFO(text.substr(0, 120));
    CHECK_THROWS_WITH(load_gltf(write_text(d / "minv.gltf", text), s, cache), Catch::Contains(why));
  }
  {
    std::string text = gltf_with_primitives({{4, {0, 1, 2}}});
    text.replace(text.find("\"version\""), 0, R"("minVersion":"2.0",)");
    Scene s;
    TextureCache cache;
    CHECK_NOTHROW(load_gltf(write_text(d / "minv20.gltf", text), s, cache));
  }
  for (const std::string list : {R"("EXT_meshopt_compression")", R"(["KHR_mesh_quantization", 3])"}) {
    std::string text = gltf_with_primitives({{4, {0, 1, 2}}});
    text.insert(text.find('{') + 1, "\"extensionsRequired\":" + list + ",");
    Scene s;
    TextureCache cache;
    INFO(text.substr(0, 120));
    CHECK_THROWS_WITH(load_gltf(write_text(d / "ext.gltf", text), s, cache),
                      Catch::Contains("extensionsRequired: expected an array of extension names"));
  }
}

// An outside sweep's find: 16 materials keying with one 4096^2 mask made 16 copies of it in the
// grid's texel table (2.3 GB). Each mask is now packed once.
TEST_CASE("OBJ: materials that share a mask share its texels in the grid's tables", "[unit][loaders]") {
  const fs::path d = temp_dir();
  const std::vector<uint8_t> rgba(4 * 8 * 4, 200);
  write_image_rgba8((d / "leaf.png").string(), 8, 4, rgba);
  std::string mtl, obj = "mtllib shared.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n";
  for (int k = 0; k < 5; ++k) {
    mtl += "newmtl m" + std::to_string(k) + "\nKd 1 1 1\nmap_d leaf.png\n";
    obj += "usemtl m" + std::to_string(k) + "\nf 1/1 2/2 3/3\n";
  }
  write_text(d / "shared.mtl", mtl);
  Scene s;
  TextureCache cache;
  load_obj(write_text(d / "shared.obj", obj), s, cache);
  size_t keyed = 0;
  for (const Material& m : s.materials) keyed += m.alpha_keyed();
  REQUIRE(keyed == 5);
  const plan::GridTables t = plan::pack_tables(s);
  CHECK(t.texels.size() == 8 * 4);
  for (const shared::GridMaterial& gm : t.materials)
    if (gm.alpha_width) CHECK(gm.alpha_offset == 0);
}

// Outside sweeps' finds: tinyobjloader reads -o, -s and -t as three numbers whatever follows, so
// "map_Kd -s 2 2 t.png" lost its file name and the texture was dropped without a word; a vt
// past a float's range was refused without its line.
TEST_CASE("OBJ: map options with fewer numbers keep their texture, a float overflow names its line",
          "[unit][loaders][badinput]") {
  const fs::path d = temp_dir();
  const std::vector<uint8_t> rgba(4 * 2 * 2, 90);
  write_image_rgba8((d / "t.png").string(), 2, 2, rgba);
  const std::string obj = "mtllib o.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nusemtl m\nf 1/1 2/2 3/3\n";
  for (const std::string line : {"map_Kd -s 2 2 t.png", "map_Kd -o 0.5 t.png", "map_Kd -t 1 2 t.png",
                                 "map_Kd -mm 0 t.png", "map_Kd -s 2 2 2 t.png", "map_Kd -clamp on -s 3 t.png"}) {
    INFO(line);
    write_text(d / "o.mtl", "newmtl m\nKd 1 1 1\n" + line + "\n");
    Scene s;
    TextureCache cache;
    load_obj(write_text(d / "o.obj", obj), s, cache);
    REQUIRE(s.materials.size() == 1);
    CHECK(s.materials[0].diffuse_texture >= 0);
  }
  // Options with no file name after them (the texture was dropped without a word)
  for (const std::string line : {"map_Kd -clamp on", "map_Kd -o 1", "map_d -blendu off", "map_Kd -s 1 2 3 -bm 2"}) {
    INFO(line);
    write_text(d / "o.mtl", "newmtl m\nKd 1 1 1\n" + line + "\n");
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_obj(write_text(d / "o.obj", obj), s, cache),
                      Catch::Contains("o.mtl:3") && Catch::Contains("no file name after its options"));
  }
  {
    write_text(d / "o.mtl", "newmtl m\nKd 1 1 1\nmap_Kd -s t.png\n");
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_obj(write_text(d / "o.obj", obj), s, cache),
                      Catch::Contains("o.mtl:3") && Catch::Contains("'-s' without a number"));
  }
  {
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_obj(write_text(d / "big.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 1e39 0\nf 1/1 2/1 3/1\n"), s, cache),
                      Catch::Contains("big.obj:4") && Catch::Contains("beyond a float's range"));
  }
  // A corner with an empty index where the format has none ("1/", "/1", "1/2/") or a fourth index
  // is named as such (it was told as "zero value for face index"); v//vn stays a corner
  for (const std::string corner : {"1/", "1/1/", "/1", "1/1/1/1", "1///1"}) {
    INFO(corner);
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_obj(write_text(d / "c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf " + corner +
                                                           " 2 3\n"), s, cache),
                      Catch::Contains("c.obj:6") && Catch::Contains("corner '" + corner + "'"));
  }
  for (const std::string face : {"1//1 2//1 3//1", "1/1 2/1 3/1", "1/1/1 2/1/1 3/1/1", "1 2 3"}) {
    INFO(face);
    Scene s;
    TextureCache cache;
    CHECK(load_obj(write_text(d / "c.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf " + face + "\n"), s, cache)
              .size() == 1);
  }
}

// An outside sweep's find: newmtl took its whole rest of line as the name, usemtl its first word
// (tinyobjloader), so "usemtl my mat" took material "my" without a word, and "wire 008" could not
// be used at all. Both read the whole rest now; a comment after a usemtl's name still finds it.
TEST_CASE("OBJ: material names with blanks and '#' are one name in newmtl and usemtl alike", "[unit][loaders][badinput]") {
  const fs::path d = temp_dir();
  write_text(d / "n.mtl", "newmtl my\nKd 0 1 0\nnewmtl my mat\nKd 1 0 0\nnewmtl Material #25\nKd 0 0 1\n"
                          "newmtl wire\t008\nKd 0.5 0.5 0.5\nnewmtl leaf\nKd 0.25 0.25 0.25\n");
  const std::string verts = "mtllib n.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const auto diffuse_of = [&](const std::string& use) {
    Scene s;
    TextureCache cache;
    load_obj(write_text(d / "n.obj", verts + "usemtl " + use + "\nf 1 2 3\n"), s, cache);
    REQUIRE(s.meshes.size() == 1);
    const Material& m = s.materials[s.meshes[0].materials[0]];
    return std::pair{m.name, m.diffuse};
  };
  CHECK(diffuse_of("my mat") == std::pair{std::string("my mat"), glm::vec3(1, 0, 0)});
  CHECK(diffuse_of("my") == std::pair{std::string("my"), glm::vec3(0, 1, 0)});
  CHECK(diffuse_of("Material #25") == std::pair{std::string("Material #25"), glm::vec3(0, 0, 1)});
  CHECK(diffuse_of("wire\t008  ").first == "wire\t008");
  CHECK(diffuse_of("leaf # the leaves").first == "leaf");
  // A name no library defines is refused with its whole text
  Scene s;
  TextureCache cache;
  CHECK_THROWS_WITH(load_obj(write_text(d / "n.obj", verts + "usemtl my other\nf 1 2 3\n"), s, cache),
                    Catch::Contains("n.obj:5") && Catch::Contains("usemtl 'my other'"));
}

// An outside sweep's find: "rotate": [r0, r1] applied r1 to the object first, where SCENE_FORMAT.md
// says the rotations apply in order.
TEST_CASE("Scene file: a rotate array applies its rotations in order, the first to the object first",
          "[unit][scenefile]") {
  const fs::path d = temp_dir();
  write_text(d / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  write_text(d / "rot.json", R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t","rotate":[)"
                             R"({"axis":[0,1,0],"degrees":90},{"axis":[1,0,0],"degrees":90}]}]})");
  const Scene s = load_scene((d / "rot.json").string());
  REQUIRE(s.instances.size() == 1);
  // (1, 0, 0): about y by 90 degrees to (0, 0, -1), then about x by 90 degrees to (0, 1, 0)
  const glm::vec3 p = glm::vec3(s.instances[0].transform * glm::vec4(1, 0, 0, 1));
  CHECK(p.x == Approx(0).margin(1e-6));
  CHECK(p.y == Approx(1).margin(1e-6));
  CHECK(p.z == Approx(0).margin(1e-6));
  // (0, 1, 0): about y unchanged, then about x to (0, 0, 1)
  const glm::vec3 q = glm::vec3(s.instances[0].transform * glm::vec4(0, 1, 0, 1));
  CHECK(q.z == Approx(1).margin(1e-6));
}

// Outside sweeps' finds: an MTL "Kd 0.5" was read as (0.5, 0, 0), grey drawn red (the format's g
// and b default to r); glTF node matrices that are not affine passed without a word.
TEST_CASE("OBJ: a one-number colour is grey - glTF: a node's matrix is affine", "[unit][loaders][badinput]") {
  const fs::path d = temp_dir();
  {  // a comment after a line's numbers, faces included (the face parser failed on its '#')
    Scene s;
    TextureCache cache;
    load_obj(write_text(d / "comments.obj", "v 0 0 0 # origin\nv 1 0 0\nv 0 1 0\nv 1 1 0#\nf 1 2 3 # a note\nf 2 4 3#x\n"), s,
             cache);
    REQUIRE(s.meshes.size() == 1);
    CHECK(s.meshes[0].triangles.size() == 2);
    CHECK(s.meshes[0].positions.size() == 4);
  }
  {
    write_text(d / "kd.mtl", "newmtl grey\nKd 0.5\nnewmtl red\nKd 0.5 0 0\n");
    Scene s;
    TextureCache cache;
    load_obj(write_text(d / "kd.obj", "mtllib kd.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl grey\nf 1 2 3\nusemtl red\nf 1 3 2\n"),
             s, cache);
    REQUIRE(s.materials.size() == 2);
    for (const Material& m : s.materials) {
      INFO(m.name);
      CHECK(m.diffuse == (m.name == "grey" ? glm::vec3(0.5f) : glm::vec3(0.5f, 0, 0)));
    }
  }
  const std::string base = gltf_textured(glm::vec2(0.5f), {"{}"}, "", R"({"uri":"none.png"})");
  const std::string node = R"("nodes":[{"mesh":0}])";
  REQUIRE(base.find(node) != std::string::npos);
  for (const auto& [replacement, why] : std::vector<std::pair<std::string, std::string>>{
           {R"("nodes":[{"mesh":0,"matrix":[1,0,0,0, 0,1,0,0, 0,0,1,0.5, 0,0,0,1]}])", "not 0 0 0 1"}}) {
    std::string text = base;
    text.replace(text.find(node), node.size(), replacement);
    text.replace(text.find(",\"textures\""), std::string(",\"textures\":[{\"source\":0}],\"images\":[{\"uri\":\"none.png\"}]").size(), "");
    Scene s;
    TextureCache cache;
    INFO(replacement);
    CHECK_THROWS_WITH(load_gltf(write_text(d / "matrix.gltf", text), s, cache), Catch::Contains(why));
  }
}

// Outside sweeps' finds, each a silently wrong scene before: a rotation axis of length 1e30 was refused as a
// non-finite transform (a motion's was accepted); a NUL in a mesh path opened one file and took
// another's loader; a grid with both sizes, or a static instance with a motion, from a source
// other than the scene file's reader, dropped one without a word.
TEST_CASE("Scenes: huge rotation axes, NUL in paths, both grid sizes, a static instance with a motion",
          "[unit][loaders][badinput]") {
  const fs::path d = temp_dir();
  write_text(d / "tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  {
    const std::string scene = write_text(
        d / "axis.json", R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t","rotate":{"axis":[1e30,1e30,0],"degrees":90}}]})");
    const Scene s = load_scene(scene);
    const glm::vec4 p = s.instances[0].transform * glm::vec4(0, 0, 1, 1);  // about (1, 1, 0) / sqrt 2: z to k x z
    CHECK(std::abs(p.x - 0.7071f) < 1e-4f);
    CHECK(std::abs(p.y + 0.7071f) < 1e-4f);
  }
  {
    const std::string nul = std::string(R"({"meshes":{"t":{"file":"tri.obj)") + "\\u0000" + R"(.gltf"}},"instances":[{"mesh":"t"}]})";
    CHECK_THROWS_WITH(load_scene(write_text(d / "nul.json", nul)), Catch::Contains("NUL"));
  }
  {
    Scene s = load_scene(write_text(d / "plain.json", R"({"meshes":{"t":{"file":"tri.obj"}},"instances":[{"mesh":"t"}]})"));
    Scene both = s;
    both.grid.resolution = glm::uvec3(4);
    both.grid.cell_size = 0.5f;
    CHECK_THROWS_WITH(both.finalize(), Catch::Contains("both a resolution and a cell size"));
    Scene moving = s;
    moving.instances[0].dynamic = false;
    moving.instances[0].motion.angular_speed = 1.0f;
    CHECK_THROWS_WITH(moving.finalize(), Catch::Contains("a motion on a static instance"));
  }
}

TEST_CASE("Scene file: an override naming only an unused mesh's material is ignored, not refused", "[unit][scenefile]") {
  // Unused mesh entries are not loaded; such a file loaded before they were skipped (the review)
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("gridrt_unused_override_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::ofstream(dir / "s.json") << R"({"meshes": {"used": {"builtin": "teapot", "level": 2}, "spare": {"builtin": "teapot", "level": 2}},
    "materials": {"overrides": {"spare": {"glossiness": 0.5}}}, "instances": [{"mesh": "used"}]})";
  Scene s;
  REQUIRE_NOTHROW(s = load_scene((dir / "s.json").string()));
  CHECK(s.instances.size() == 1);
  // Without unused entries a name no material has is still an error
  std::ofstream(dir / "t.json") << R"({"meshes": {"used": {"builtin": "teapot", "level": 2}},
    "materials": {"overrides": {"nothing": {"glossiness": 0.5}}}, "instances": [{"mesh": "used"}]})";
  CHECK_THROWS_WITH(load_scene((dir / "t.json").string()), Catch::Contains("no material is named"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("Scene file: one model named under several mesh keys is loaded once, its meshes shared", "[unit][scenefile]") {
  // N keys naming one file loaded it N times: N times its memory and time (an outside sweep)
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("gridrt_shared_model_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string quad = fixture("quad.obj");
  std::ofstream(dir / "twice.json") << R"({"meshes": {"a": {"file": ")" << quad << R"("}, "b": {"file": ")" << quad
                                    << R"("}, "c": {"builtin": "teapot", "level": 2}},
    "instances": [{"mesh": "a"}, {"mesh": "b", "translate": [3, 0, 0]}, {"mesh": "c", "translate": [0, 3, 0]}]})";
  std::ofstream(dir / "once.json") << R"({"meshes": {"a": {"file": ")" << quad << R"("}},
    "instances": [{"mesh": "a"}]})";
  const Scene twice = load_scene((dir / "twice.json").string());
  const Scene once = load_scene((dir / "once.json").string());
  REQUIRE(twice.instances.size() == 3);
  CHECK(twice.meshes.size() == once.meshes.size() + 1);  // the teapot its own
  CHECK(twice.instances[0].mesh == twice.instances[1].mesh);
  CHECK(twice.instances[0].name == "a");
  CHECK(twice.instances[1].name == "b");
  CHECK(twice.triangle_count() == 2 * once.triangle_count() + twice.meshes[twice.instances[2].mesh].triangles.size());
  std::filesystem::remove_all(dir);
}

TEST_CASE("glTF: values TinyGLTF drops are refused by path, images no material uses are not decoded",
          "[unit][loaders][badinput]") {
  // A property of the wrong type or length, or an index below -1, was read as absent: the parent's
  // translation, a child's scale or a whole mesh silently gone (an outside sweep)
  const std::string text = read_input_file(fixture("quad.gltf"), "glTF");
  const nlohmann::json base = nlohmann::json::parse(text);
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("gridrt_gltf_values_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const auto load = [&](const nlohmann::json& j) {
    const std::filesystem::path p = dir / "m.gltf";
    std::ofstream(p) << j.dump();
    return load_scene(p.string());
  };
  struct Case {
    const char* what;
    std::function<void(nlohmann::json&)> edit;
    const char* where;
  };
  const std::vector<Case> cases = {
      {"a string in a translation", [](nlohmann::json& j) { j["nodes"][0]["translation"] = {"a", 0, 0}; },
       "nodes[0].translation"},
      {"a scale of two numbers", [](nlohmann::json& j) { j["nodes"][1]["scale"] = {2, 2}; }, "nodes[1].scale"},
      {"a rotation of five numbers", [](nlohmann::json& j) { j["nodes"][1]["rotation"] = {0, 0, 0, 1, 0}; },
       "nodes[1].rotation"},
      {"a mesh index of -2", [](nlohmann::json& j) { j["nodes"][1]["mesh"] = -2; }, "nodes[1].mesh"},
      {"a material index of -2", [](nlohmann::json& j) { j["meshes"][0]["primitives"][0]["material"] = -2; },
       "meshes[0].primitives[0].material"},
      {"a string alphaCutoff", [](nlohmann::json& j) { j["materials"][0]["alphaCutoff"] = "0.5"; },
       "materials[0].alphaCutoff"},
      // A later sweep: offsets, strides and flags of another type were read as absent or 0, and the
      // indices came from the positions' bytes with exit 0
      {"a string byteOffset", [](nlohmann::json& j) { j["bufferViews"][3]["byteOffset"] = "36"; },
       "bufferViews[3].byteOffset"},
      {"a negative byteStride", [](nlohmann::json& j) { j["bufferViews"][0]["byteStride"] = -12; },
       "bufferViews[0].byteStride"},
      {"a fractional accessor byteOffset", [](nlohmann::json& j) { j["accessors"][0]["byteOffset"] = 0.5; },
       "accessors[0].byteOffset"},
      {"a numeric normalized", [](nlohmann::json& j) { j["accessors"][2]["normalized"] = 1; }, "accessors[2].normalized"},
      {"a count of 0", [](nlohmann::json& j) { j["accessors"][1]["count"] = 0; }, "accessors[1].count"},
      {"a NUL in an image URI", [](nlohmann::json& j) { j["images"][0]["uri"] = std::string("a.png\0.jpg", 10); },
       "images[0].uri"},
      {"a %00 in an image URI", [](nlohmann::json& j) { j["images"][0]["uri"] = "a.png%00.jpg"; }, "images[0].uri"},
      // A later sweep: an index of 2^32 or more was read modulo 2^32 (scene 4294967297 chose scene
      // 1, POSITION 4294967298 accessor 2), a string or a fraction as absent
      {"a scene index past 2^32", [](nlohmann::json& j) { j["scene"] = 4294967296ull; }, "scene"},
      {"a string scene", [](nlohmann::json& j) { j["scene"] = "0"; }, "scene"},
      {"a scene's node past 2^32", [](nlohmann::json& j) { j["scenes"][0]["nodes"] = {4294967296ull}; },
       "scenes[0].nodes"},
      {"a fractional scene node", [](nlohmann::json& j) { j["scenes"][0]["nodes"] = {0.5}; }, "scenes[0].nodes"},
      {"a POSITION past 2^32",
       [](nlohmann::json& j) { j["meshes"][0]["primitives"][0]["attributes"]["POSITION"] = 4294967296ull; },
       "attributes.POSITION"},
      {"a sampler past 2^32", [](nlohmann::json& j) { j["textures"][0]["sampler"] = 4294967296ull; },
       "textures[0].sampler"},
      {"a texCoord past 2^32",
       [](nlohmann::json& j) { j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["texCoord"] = 4294967296ull; },
       "baseColorTexture.texCoord"},
      {"an image's buffer view past 2^32", [](nlohmann::json& j) { j["images"][0]["bufferView"] = 4294967296ull; },
       "images[0].bufferView"}};
  for (const Case& c : cases) {
    nlohmann::json j = base;
    c.edit(j);
    INFO(c.what);
    CHECK_THROWS_WITH(load(j), Catch::Contains(c.where));
  }
  // Images no material names are not decoded (twelve unused 8192 x 8192 entries took 3.5 GB): an
  // unused entry that is no image at all loads
  nlohmann::json j = base;
  j["images"].push_back({{"uri", "data:image/png;base64,AAAA"}});
  CHECK_NOTHROW(load(j));
  j["textures"].push_back({{"source", 1}});
  j["materials"][0]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 1;  // now used: refused
  CHECK_THROWS_WITH(load(j), Catch::Contains("image 1"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("Textures: a truncated JPEG is refused, one with bytes after its end marker or progressive loads",
          "[unit][loaders][badinput]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO");
    return;
  }
  // libjpeg calls missing scan lines a warning and OpenImageIO drew them grey without an error (an
  // outside sweep); cameras append data after the end marker, which must still load (the review)
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("gridrt_jpeg_end_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  std::vector<glm::vec3> rgb(64 * 64);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = glm::vec3(float(i % 64) / 63.0f, float(i / 64) / 63.0f, 0.5f);
  const std::string whole = (dir / "whole.jpg").string();
  write_image(whole, 64, 64, rgb);
  const std::string bytes = read_input_file(whole, "texture");
  std::ofstream((dir / "cut.jpg").string(), std::ios::binary) << bytes.substr(0, bytes.size() * 3 / 4);
  std::ofstream((dir / "tail.jpg").string(), std::ios::binary) << bytes << std::string(500, '\x5a');
  CHECK_NOTHROW(load_texture(whole, AlphaSource::kImage, nullptr));
  CHECK_NOTHROW(load_texture((dir / "tail.jpg").string(), AlphaSource::kImage, nullptr));
  // Stray bytes between two segments: libjpeg skips them with a warning and decodes the file whole
  // (a review's find: the end-marker walk, and a late-error check, refused it)
  REQUIRE(bytes.size() > 6);
  REQUIRE(static_cast<unsigned char>(bytes[2]) == 0xFF);
  const size_t segment_end = 4 + (size_t(static_cast<unsigned char>(bytes[4])) << 8 | static_cast<unsigned char>(bytes[5]));
  std::ofstream((dir / "stray.jpg").string(), std::ios::binary)
      << bytes.substr(0, segment_end) << std::string("\x12\x34", 2) << bytes.substr(segment_end);
  CHECK_NOTHROW(load_texture((dir / "stray.jpg").string(), AlphaSource::kImage, nullptr));
  CHECK_THROWS_WITH(load_texture((dir / "cut.jpg").string(), AlphaSource::kImage, nullptr),
                    Catch::Contains("truncated"));
  // Cut in its scan data and given an end marker after the cut: libjpeg calls the missing lines
  // "premature end of data segment" and OpenImageIO drew them grey (an outside sweep)
  std::ofstream((dir / "cut_marked.jpg").string(), std::ios::binary) << bytes.substr(0, bytes.size() * 3 / 4) << "\xff\xd9";
  CHECK_THROWS_WITH(load_texture((dir / "cut_marked.jpg").string(), AlphaSource::kImage, nullptr),
                    Catch::Contains("cut_marked.jpg") && Catch::Contains("truncated or corrupt"));
  std::filesystem::remove_all(dir);
}

// An outside sweep's find: a glTF's images went through TinyGLTF's decoder (stb_image), which read
// a JPEG cut short as filler texels, a header claiming 8000 x 8000 as 64 megapixels of filler, and a
// PNG failing its checksum, all with exit 0, where the OBJ's textures refused the same files.
TEST_CASE("glTF images: a truncated JPEG, an overstated JPEG header and a PNG failing its checksum are refused",
          "[unit][loaders][badinput]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO");
    return;
  }
  const fs::path d = temp_dir();
  std::vector<glm::vec3> rgb(64 * 64);
  for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = glm::vec3(float(i % 64) / 63.0f, float(i / 64) / 63.0f, 0.5f);
  write_image((d / "whole.jpg").string(), 64, 64, rgb);
  write_image((d / "whole.png").string(), 64, 64, rgb);
  const std::string jpeg = read_input_file((d / "whole.jpg").string(), "texture");
  const std::string png = read_input_file((d / "whole.png").string(), "texture");
  std::ofstream((d / "cut_marked.jpg").string(), std::ios::binary) << jpeg.substr(0, jpeg.size() * 3 / 4) << "\xff\xd9";
  // The frame header's height and width (SOF0: FF C0, length, precision, height, width) as 8000
  std::string big = jpeg;
  const size_t sof = big.find("\xff\xc0");
  REQUIRE(sof != std::string::npos);
  big[sof + 5] = big[sof + 7] = char(8000 >> 8);
  big[sof + 6] = big[sof + 8] = char(8000 & 0xFF);
  std::ofstream((d / "big.jpg").string(), std::ios::binary) << big;
  // A byte of the first IDAT chunk's data changed: its CRC fails
  std::string crc = png;
  const size_t idat = crc.find("IDAT");
  REQUIRE(idat != std::string::npos);
  crc[idat + 8] = char(crc[idat + 8] ^ 0x5A);
  std::ofstream((d / "crc.png").string(), std::ios::binary) << crc;
  const std::string mask = R"({"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
  for (const char* name : {"cut_marked.jpg", "big.jpg", "crc.png"}) {
    INFO(name);
    Scene s;
    TextureCache cache;
    CHECK_THROWS_WITH(load_gltf(write_text(d / "bad.gltf", gltf_textured(glm::vec2(0.5f), {mask}, name)), s, cache),
                      Catch::Contains("image 0") && Catch::Contains(name));
  }
  // The intact files load with the texels the OBJ's textures get
  for (const char* name : {"whole.jpg", "whole.png"}) {
    INFO(name);
    Scene s;
    TextureCache cache;
    load_gltf(write_text(d / "good.gltf", gltf_textured(glm::vec2(0.5f), {mask}, name)), s, cache);
    REQUIRE(s.materials.size() == 1);
    REQUIRE(s.materials[0].diffuse_texture >= 0);
    const Texture& t = s.textures[size_t(s.materials[0].diffuse_texture)];
    const Texture ref = load_texture((d / name).string(), AlphaSource::kImage, nullptr);
    REQUIRE(t.width == ref.width);
    REQUIRE(t.height == ref.height);
    CHECK(t.rgba == ref.rgba);
  }
}

namespace {
// A baseline TIFF by hand (little-endian, uncompressed RGB or RGBA in one strip), with an
// Orientation tag and, for 4 channels, ExtraSamples: 1 associated alpha, 2 unassociated.
void write_tiff(const std::string& path, uint32_t w, uint32_t h, const std::vector<uint8_t>& px, uint32_t channels,
                uint16_t orientation, uint16_t extra) {
  std::string out;
  const auto u16 = [&](uint32_t v) { out += char(v & 0xFF); out += char((v >> 8) & 0xFF); };
  const auto u32 = [&](uint32_t v) { u16(v & 0xFFFF); u16(v >> 16); };
  out = "II";
  u16(42);
  u32(8);  // the directory right after the header
  struct Tag { uint16_t id, type; uint32_t count, value; };
  const uint32_t entries = channels == 4 ? 11u : 10u;
  const uint32_t dir_size = 2 + 12 * entries + 4;
  const uint32_t bits_at = 8 + dir_size, data_at = bits_at + 2 * channels;
  std::vector<Tag> tags = {{256, 4, 1, w}, {257, 4, 1, h}, {258, 3, channels, bits_at}, {259, 3, 1, 1}, {262, 3, 1, 2},
                           {273, 4, 1, data_at}, {274, 3, 1, orientation}, {277, 3, 1, channels}, {278, 4, 1, h},
                           {279, 4, 1, uint32_t(px.size())}};
  if (channels == 4) tags.push_back({338, 3, 1, extra});
  u16(uint32_t(tags.size()));
  for (const Tag& t : tags) {
    u16(t.id);
    u16(t.type);
    u32(t.count);
    if (t.type == 3 && t.count == 1) u16(t.value), u16(0);
    else u32(t.value);
  }
  u32(0);
  for (uint32_t c = 0; c < channels; ++c) u16(8);
  out.append(reinterpret_cast<const char*>(px.data()), px.size());
  std::ofstream(path, std::ios::binary) << out;
}
}  // namespace

TEST_CASE("Textures: EXIF/TIFF orientation applied, a premultiplied TIFF's colour divided, a PNM's maxval checked",
          "[unit][loaders][badinput]") {
  const auto scratch = texture_scratch("texture_orient");
  if (!scratch) return;
  const std::filesystem::path& dir = *scratch;
  // A 3 x 2 image of distinct texels: texel (x, y) has red 10 x + 1, green 10 y + 1
  const uint32_t w = 3, h = 2;
  std::vector<uint8_t> px;
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x) px.insert(px.end(), {uint8_t(10 * x + 1), uint8_t(10 * y + 1), 7});
  // Where the stored texel (sx, sy) is displayed, per orientation (the EXIF/TIFF definitions: the
  // stored first row is the displayed top, right, bottom or left; the first column the left, top,
  // right or bottom), for a displayed image of dw x dh
  const auto displayed_at = [&](uint16_t o, uint32_t sx, uint32_t sy) -> glm::uvec2 {
    switch (o) {
      case 1: return {sx, sy};
      case 2: return {w - 1 - sx, sy};
      case 3: return {w - 1 - sx, h - 1 - sy};
      case 4: return {sx, h - 1 - sy};
      case 5: return {sy, sx};            // first row left, first column top
      case 6: return {h - 1 - sy, sx};    // first row right, first column top
      case 7: return {h - 1 - sy, w - 1 - sx};  // first row right, first column bottom
      default: return {sy, w - 1 - sx};   // 8: first row left, first column bottom
    }
  };
  for (uint16_t o = 1; o <= 8; ++o) {
    INFO("orientation " << o);
    const std::string path = (dir / ("o" + std::to_string(o) + ".tif")).string();
    write_tiff(path, w, h, px, 3, o, 0);
    const Texture t = load_texture(path, AlphaSource::kImage, nullptr);
    const uint32_t dw = o >= 5 ? h : w, dh = o >= 5 ? w : h;
    REQUIRE(t.width == dw);
    REQUIRE(t.height == dh);
    for (uint32_t sy = 0; sy < h; ++sy)
      for (uint32_t sx = 0; sx < w; ++sx) {
        const glm::uvec2 d = displayed_at(o, sx, sy);
        INFO("stored texel (" << sx << ", " << sy << ") displayed at (" << d.x << ", " << d.y << ")");
        const size_t k = (size_t(d.y) * dw + d.x) * 4;
        CHECK(int(t.rgba[k]) == int(10 * sx + 1));
        CHECK(int(t.rgba[k + 1]) == int(10 * sy + 1));
      }
  }
  // Associated alpha (ExtraSamples 1): colour premultiplied in the file, divided back; unassociated
  // (2) and unspecified (0: a fourth channel not named alpha) read as stored
  const std::vector<uint8_t> texels = {100, 50, 0, 128, 200, 100, 50, 255, 0, 0, 0, 0};
  for (const uint16_t extra : {uint16_t(0), uint16_t(1), uint16_t(2)}) {
    INFO("ExtraSamples " << extra);
    const std::string path = (dir / ("alpha" + std::to_string(extra) + ".tif")).string();
    write_tiff(path, 3, 1, texels, 4, 1, extra);
    const Texture t = load_texture(path, AlphaSource::kImage, nullptr);
    REQUIRE(t.width == 3);
    const std::vector<uint8_t> want = extra == 1 ? std::vector<uint8_t>{199, 100, 0, 128, 200, 100, 50, 255, 0, 0, 0, 0}
                                                 : texels;
    CHECK(t.rgba == want);
  }
  // PNM: a largest value of 0 or above 65535, and a sample above it or not a number, refused by
  // name (OpenImageIO read "-5" as 251 and clamped 300); a file within them loads
  for (const auto& [name, text, ok, why] :
       {std::tuple{"max0.ppm", "P6\n1 1\n0\n@@@@@@", false, "1..65535"},
        std::tuple{"max70000.ppm", "P6\n1 1\n70000\n@@@@@@", false, "1..65535"},
        std::tuple{"maxneg.pgm", "P5 1 1 -5\n@@", false, "1..65535"},
        std::tuple{"comment.ppm", "P6\n# made by hand\n1 1 # size\n255\n@@@", true, ""},
        std::tuple{"max65535.pgm", "P5\n1 1\n65535\n@@", true, ""},
        std::tuple{"plain.ppm", "P3\n2 1\n255\n# a comment\n255 0 0  0 17 255\n", true, ""},
        std::tuple{"plain_neg.pgm", "P2\n2 1\n255\n-5 20\n", false, "'-5', not a number in 0..255"},
        std::tuple{"plain_over.ppm", "P3\n2 1\n255\n300 0 0  0 1 0\n", false, "'300', not a number in 0..255"},
        std::tuple{"plain_bits.pbm", "P1\n3 1\n0 1 2\n", false, "'2' where a sample is 0 or 1"},
        std::tuple{"raw_over.pgm", "P5\n2 1\n100\n\x32\xc8", false, "the sample 200 at byte"},
        std::tuple{"raw_within.pgm", "P5\n2 1\n100\n\x32\x64", true, ""}}) {
    INFO(name);
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary) << text;
    if (ok) CHECK_NOTHROW(load_texture(path, AlphaSource::kImage, nullptr));
    else CHECK_THROWS_WITH(load_texture(path, AlphaSource::kImage, nullptr), Catch::Contains(name) && Catch::Contains(why));
  }
  // A PFM's samples must be finite: NaN was read as 0 and infinity as white (an outside sweep);
  // either byte order (the scale's sign), grey and colour
  const auto pfm = [](const char* magic, float scale, const std::vector<float>& v) {
    std::string s = std::string(magic) + "\n" + std::to_string(v.size() / (magic[1] == 'F' ? 3 : 1)) + " 1\n" +
                    (scale < 0 ? "-1.0" : "1.0") + "\n";
    for (float f : v) {
      uint32_t bits;
      std::memcpy(&bits, &f, 4);
      for (int k = 0; k < 4; ++k) s += char(scale < 0 ? (bits >> (8 * k)) & 0xFF : (bits >> (8 * (3 - k))) & 0xFF);
    }
    return s;
  };
  for (const auto& [name, text, ok] :
       {std::tuple{"fine.pfm", pfm("PF", -1.0f, {0.25f, 0.5f, 1.0f}), true},
        std::tuple{"fine_big_endian.pfm", pfm("Pf", 1.0f, {0.25f, 0.75f}), true},
        std::tuple{"nan.pfm", pfm("PF", -1.0f, {0.25f, NAN, 1.0f}), false},
        std::tuple{"inf_big_endian.pfm", pfm("Pf", 1.0f, {0.25f, INFINITY}), false}}) {
    INFO(name);
    const std::string path = (dir / name).string();
    std::ofstream(path, std::ios::binary) << text;
    if (ok) CHECK_NOTHROW(load_texture(path, AlphaSource::kImage, nullptr));
    else CHECK_THROWS_WITH(load_texture(path, AlphaSource::kImage, nullptr), Catch::Contains(name) && Catch::Contains("finite"));
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("OBJ: a texture named in an MTL of another folder is read beside that MTL first, else beside the OBJ - no Kd is grey",
          "[unit][loaders]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO");
    return;
  }
  const std::filesystem::path dir =
      std::filesystem::temp_directory_path() / ("gridrt_mtl_folder_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir / "materials");
  const auto png = [&](const std::filesystem::path& p, uint8_t r, uint8_t g, uint8_t b) {
    std::vector<uint8_t> rgba = {r, g, b, 255};
    write_image_rgba8(p.string(), 1, 1, rgba, false);
  };
  png(dir / "beside_obj.png", 0, 255, 0);
  png(dir / "both.png", 0, 255, 0);
  png(dir / "materials" / "both.png", 0, 0, 255);
  std::ofstream(dir / "materials" / "lib.mtl") << "newmtl a\nKd 1 1 1\nmap_Kd both.png\nnewmtl b\nKd 1 1 1\nmap_Kd beside_obj.png\n";
  std::ofstream(dir / "m.obj") << "mtllib materials/lib.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                  "usemtl a\nf 1/1 2/2 3/3\nusemtl b\nf 1/1 3/3 2/2\n";
  Scene s;
  TextureCache cache;
  load_obj((dir / "m.obj").string(), s, cache);
  REQUIRE(s.materials.size() == 2);
  REQUIRE(s.materials[0].diffuse_texture >= 0);
  REQUIRE(s.materials[1].diffuse_texture >= 0);
  const Texture& a = s.textures[size_t(s.materials[0].diffuse_texture)];
  const Texture& b = s.textures[size_t(s.materials[1].diffuse_texture)];
  // "both.png" beside the MTL (blue), not the OBJ's of the same name (green)
  CHECK(a.rgba == std::vector<uint8_t>{0, 0, 255, 255});
  // A name only the OBJ's folder holds: read there
  CHECK(b.rgba == std::vector<uint8_t>{0, 255, 0, 255});
  // A material without Kd is the grey 0.6, with a texture (tinyobjloader's default) or without one
  // (tinyobjloader's black drew it black); a Kd given is kept, each definition's its own
  std::ofstream(dir / "materials" / "kd.mtl") << "newmtl tex\nmap_Kd both.png\nnewmtl plain\nd 1\nnewmtl set\nKd 0.2 0.3 0.4\n"
                                                  "newmtl twice\nd 1\nnewmtl twice\nKd 0.5 0.5 0.5\n";
  std::ofstream(dir / "kd.obj") << "mtllib materials/kd.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                   "usemtl tex\nf 1/1 2/2 3/3\nusemtl plain\nf 1 3 2\nusemtl set\nf 1 2 3\nusemtl twice\nf 1 3 2\n";
  {
    Scene k;
    TextureCache kc;
    load_obj((dir / "kd.obj").string(), k, kc);
    // (tinyobjloader lists both definitions of "twice"; faces take the first)
    REQUIRE(k.materials.size() == 5);
    CHECK(k.materials[0].diffuse == glm::vec3(0.6f));
    CHECK(k.materials[0].diffuse_texture >= 0);
    CHECK(k.materials[1].diffuse == glm::vec3(0.6f));
    CHECK(k.materials[2].diffuse == glm::vec3(0.2f, 0.3f, 0.4f));
    CHECK(k.materials[3].diffuse == glm::vec3(0.6f));
    CHECK(k.materials[4].diffuse == glm::vec3(0.5f));
    REQUIRE(k.meshes.size() == 1);
    CHECK(k.meshes[0].materials == std::vector<uint32_t>{0, 1, 2, 3});
  }
  // Neither: the error names the path beside the MTL
  std::ofstream(dir / "materials" / "lib.mtl") << "newmtl a\nKd 1 1 1\nmap_Kd nowhere.png\nnewmtl b\nKd 1 1 1\n";
  Scene s2;
  TextureCache cache2;
  CHECK_THROWS_WITH(load_obj((dir / "m.obj").string(), s2, cache2), Catch::Contains("materials/nowhere.png"));
  std::filesystem::remove_all(dir);
}

TEST_CASE("Textures: alpha read apart from the colour, a TIFF cut short refused, the host's memory checked first",
          "[unit][loaders][badinput]") {
  const auto scratch = texture_scratch("texture_reads");
  if (!scratch) return;
  const std::filesystem::path& dir = *scratch;
  const uint32_t w = 96, h = 80;
  std::vector<uint8_t> rgba(size_t(w) * h * 4);
  for (size_t i = 0; i < size_t(w) * h; ++i) {
    rgba[4 * i + 0] = uint8_t(i % 251);
    rgba[4 * i + 1] = uint8_t((i / w) * 3);
    rgba[4 * i + 2] = uint8_t(200 - i % 97);
    rgba[4 * i + 3] = uint8_t((i * 7) % 256);  // alpha, the last channel: read by itself
  }
  // Colour and alpha, each read by itself (an alpha past the colour's channels was read with every
  // channel between: an outside sweep), come back as written, in PNG and TIFF
  for (const char* ext : {".png", ".tif"}) {
    const std::string path = (dir / (std::string("rgba") + ext)).string();
    write_image_rgba8(path, w, h, rgba, true);
    bool has_alpha = false;
    const Texture t = load_texture(path, AlphaSource::kImage, &has_alpha);
    INFO(path);
    CHECK(has_alpha);
    REQUIRE(t.width == w);
    REQUIRE(t.height == h);
    CHECK(t.rgba == rgba);
    CHECK(t.has_alpha);
  }
  // Only still-image formats, told by their first bytes: a text file named .mp4 went to the FFmpeg
  // reader as a playlist naming other files (a FIFO hung the load), and corrupt Maya IFF files
  // crashed their reader (outside sweeps); a PNG under another extension is still a PNG
  {
    const std::string playlist = (dir / "list.mp4").string();
    std::ofstream(playlist) << "ffconcat version 1.0\nfile other.png\n";
    CHECK_THROWS_WITH(load_texture(playlist, AlphaSource::kImage, nullptr),
                      Catch::Contains("list.mp4") && Catch::Contains("not an image of a format read as a texture"));
    const std::string iff = (dir / "maya.iff").string();
    bool wrote_iff = true;
    try {
      write_image_rgba8(iff, w, h, rgba, true);
    } catch (const Error&) {
      wrote_iff = false;  // no IFF writer in this OpenImageIO
    }
    if (wrote_iff) CHECK_THROWS_WITH(load_texture(iff, AlphaSource::kImage, nullptr), Catch::Contains("not an image of a format"));
    std::filesystem::copy_file(dir / "rgba.png", dir / "misnamed.jpg");
    CHECK(load_texture((dir / "misnamed.jpg").string(), AlphaSource::kImage, nullptr).rgba == rgba);
    // Formats whose readers an outside fuzz hung, crashed or made allocate gigabytes from a few
    // header bytes are refused by name, before any reader runs (here their first bytes alone)
    for (const auto& [name, head] : std::vector<std::pair<std::string, std::string>>{
             {"DDS", "DDS |"}, {"SGI", std::string("\x01\xda\x00\x01", 4)}, {"PSD", "8BPS"},
             {"OpenEXR", "\x76\x2f\x31\x01"}, {"GIF", "GIF89a"}, {"Radiance HDR", "#?RADIANCE\n"},
             {"JPEG 2000", "\xff\x4f\xff\x51"}}) {
      const std::string file = (dir / ("refused_" + std::to_string(name.size()) + ".bin")).string();
      std::ofstream(file, std::ios::binary) << head << std::string(64, '\0');
      INFO(name);
      CHECK_THROWS_WITH(load_texture(file, AlphaSource::kImage, nullptr),
                        Catch::Contains(name + " textures are not read"));
    }
    // TGA: a true-colour one loads; a colour-mapped one is refused (OpenImageIO indexes its map
    // with the header's first-entry index unchecked: heap bytes read as texels, an outside fuzz)
    const std::string tga = (dir / "rgba.tga").string();
    write_image_rgba8(tga, w, h, rgba, true);
    CHECK(load_texture(tga, AlphaSource::kImage, nullptr).rgba == rgba);
    std::string mapped = read_input_file(tga, "texture");
    mapped[1] = 1;  // a colour map
    mapped[2] = 1;  // colour-mapped image
    std::ofstream((dir / "mapped.tga").string(), std::ios::binary) << mapped;
    CHECK_THROWS_WITH(load_texture((dir / "mapped.tga").string(), AlphaSource::kImage, nullptr),
                      Catch::Contains("colour-mapped TGA"));
    // BMP: uncompressed 24 bits loads; a compression OpenImageIO does not know (PNG, JPEG, CMYK,
    // any number) is refused (it read the bytes as pixels: a texture of noise, an outside sweep)
    std::string bmp = "BM";
    const auto put32 = [&](uint32_t v) { for (int k = 0; k < 4; ++k) bmp += char((v >> (8 * k)) & 0xFFu); };
    const auto put16 = [&](uint32_t v) { for (int k = 0; k < 2; ++k) bmp += char((v >> (8 * k)) & 0xFFu); };
    put32(54 + 16); put32(0); put32(54);                           // file size, reserved, pixel offset
    put32(40); put32(2); put32(2); put16(1); put16(24); put32(0);  // header, 2 x 2, 24 bits, BI_RGB
    put32(16); put32(2835); put32(2835); put32(0); put32(0);
    for (int row = 0; row < 2; ++row) bmp += std::string("\x00\x00\xff\x00\x00\xff\x00\x00", 8);  // red, padded
    std::ofstream((dir / "plain.bmp").string(), std::ios::binary) << bmp;
    const Texture plain = load_texture((dir / "plain.bmp").string(), AlphaSource::kImage, nullptr);
    CHECK(plain.width == 2);
    CHECK(plain.rgba[0] == 255);
    for (const uint32_t compression : {4u, 5u, 12u, 99u}) {
      std::string odd = bmp;
      odd[30] = char(compression);
      std::ofstream((dir / "odd.bmp").string(), std::ios::binary) << odd;
      INFO(compression);
      CHECK_THROWS_WITH(load_texture((dir / "odd.bmp").string(), AlphaSource::kImage, nullptr),
                        Catch::Contains("BMP compression " + std::to_string(compression)) && Catch::Contains("convert it to PNG"));
    }
  }
  // A TIFF cut short: its missing strips were decoded black without an error (an outside sweep)
  {
    const std::string whole = (dir / "rgba.tif").string();
    const std::string bytes = read_input_file(whole, "texture");
    for (const size_t keep : {bytes.size() / 2, bytes.size() * 9 / 10}) {
      const std::string cut = (dir / ("cut" + std::to_string(keep) + ".tif")).string();
      std::ofstream(cut, std::ios::binary) << bytes.substr(0, keep);
      INFO("kept " << keep << " of " << bytes.size() << " bytes");
      CHECK_THROWS_AS(load_texture(cut, AlphaSource::kImage, nullptr), Error);
    }
  }
  // The decode's memory is checked against --max-host-mib before it is allocated (ten decodes of
  // one large PNG went past it: an outside sweep): 1 MiB holds none of a 2048 x 1024 texture
  {
    const std::string big = (dir / "big.png").string();
    write_image_rgba8(big, 2048, 1024, std::vector<uint8_t>(size_t(2048) * 1024 * 4, 128), true);
    const uint64_t before = input_limits().max_host_bytes;
    input_limits().max_host_bytes = uint64_t(1) << 20;
    CHECK_THROWS_WITH(load_texture(big, AlphaSource::kImage, nullptr),
                      Catch::Contains("host memory") && Catch::Contains("--max-host-mib"));
    input_limits().max_host_bytes = before;
    CHECK_NOTHROW(load_texture(big, AlphaSource::kImage, nullptr));
  }
  std::filesystem::remove_all(dir);
}

TEST_CASE("OBJ and MTL: values tinyobjloader reads as 0 or drops are refused with their line", "[unit][loaders][badinput]") {
  // An outside sweep's finds: "Kd xyz" and "Kd spectral" read as numbers, "-NaN" and "-Inf"
  // skipped as options and read as 0, a UTF-16 file called empty, a usemtl before its library's
  // mtllib losing its material
  const std::filesystem::path dir = std::filesystem::temp_directory_path() / ("gridrt_obj_values_" + std::to_string(getpid()));
  std::filesystem::create_directories(dir);
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  const auto load = [&](const std::string& obj, const std::string& mtl) {
    std::ofstream(dir / "m.mtl") << mtl;
    std::ofstream(dir / "m.obj", std::ios::binary) << obj;
    return load_scene((dir / "m.obj").string());
  };
  const std::string use = "mtllib m.mtl\n" + tri + "usemtl a\nf 1 2 3\n";
  CHECK_THROWS_WITH(load(use, "newmtl a\nKd xyz 0.9 0.9 0.9\n"), Catch::Contains("m.mtl:2") && Catch::Contains("XYZ"));
  CHECK_THROWS_WITH(load(use, "newmtl a\nKd spectral x.spd\n"), Catch::Contains("m.mtl:2"));
  CHECK_THROWS_WITH(load(use, "newmtl a\nKd 1 -NaN 1\n"), Catch::Contains("m.mtl:2") && Catch::Contains("-NaN"));
  CHECK_THROWS_WITH(load("v -Inf 1 2\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", ""), Catch::Contains("m.obj:1"));
  CHECK_THROWS_WITH(load(std::string("v\0 0", 4) + "\n" + tri + "f 1 2 3\n", ""), Catch::Contains("NUL"));
  // A later sweep: a colour of two or four numbers read as (r, g, 0) or its fourth dropped; a NUL in
  // a library cut a texture's name
  CHECK_THROWS_WITH(load(use, "newmtl a\nKd 1 0\n"), Catch::Contains("m.mtl:2") && Catch::Contains("three"));
  CHECK_THROWS_WITH(load(use, "newmtl a\nKd 1 0 0 7\n"), Catch::Contains("m.mtl:2"));
  CHECK_THROWS_WITH(load(use, std::string("newmtl a\nmap_Kd t.png\0x.png\n", 28)), Catch::Contains("NUL"));
  CHECK_THROWS_WITH(load(tri + "usemtl a\nf 1 2 3\nmtllib m.mtl\n", "newmtl a\nKd 1 0 0\n"),
                    Catch::Contains("m.obj:4") && Catch::Contains("before the mtllib"));
  // Read right: blanks after newmtl, a texture option line; the same material twice keeps the first
  Scene s;
  REQUIRE_NOTHROW(s = load(use, "newmtl   a\nKd 1 0 0\n"));
  CHECK(s.materials[s.meshes[0].materials[0]].diffuse == glm::vec3(1, 0, 0));
  REQUIRE_NOTHROW(s = load(use, "newmtl a\nKd 1 0 0\nnewmtl a\nKd 0 0 1\n"));
  CHECK(s.materials[s.meshes[0].materials[0]].diffuse == glm::vec3(1, 0, 0));
  std::filesystem::remove_all(dir);
}

// Outside sweeps' finds: nothing bounded the decoded textures' sum. Ten glTF image entries naming
// one PNG (however spelled) decoded it ten times (5.4 GB), and an OBJ decoded the textures of
// materials no face uses (3 GB for one untextured triangle). An image whose bytes an earlier one
// had is that image; an unused material keeps its place and colour and decodes nothing.
TEST_CASE("Textures: one image under several glTF entries is decoded once, an OBJ's unused materials decode nothing",
          "[unit][loaders]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const fs::path d = temp_dir();
  const std::vector<uint8_t> rgba = {10, 20, 30, 255, 40, 50, 60, 255};
  write_image_rgba8((d / "a.png").string(), 1, 2, rgba);
  write_image_rgba8((d / "b.png").string(), 1, 2, rgba);  // a copy: another file, the same bytes
  {
    const std::string opaque = R"({"pbrMetallicRoughness":{"baseColorTexture":{"index":0}}})";
    nlohmann::json j = nlohmann::json::parse(gltf_textured(glm::vec2(0.5f), {opaque, opaque, opaque}, "a.png"));
    j["images"].push_back({{"uri", "./a.png"}});
    j["images"].push_back({{"uri", "b.png"}});
    j["textures"].push_back({{"source", 1}});
    j["textures"].push_back({{"source", 2}});
    j["materials"][1]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 1;
    j["materials"][2]["pbrMetallicRoughness"]["baseColorTexture"]["index"] = 2;
    Scene s;
    TextureCache cache;
    load_gltf(write_text(d / "three.gltf", j.dump()), s, cache);
    REQUIRE(s.materials.size() == 3);
    CHECK(s.textures.size() == 1);
    for (const Material& m : s.materials) CHECK(m.diffuse_texture == s.materials[0].diffuse_texture);
    REQUIRE(s.textures.size() >= 1);
    CHECK(s.textures[0].rgba == rgba);
  }
  {
    write_text(d / "two.mtl", "newmtl used\nKd 1 1 1\nmap_Kd a.png\nnewmtl unused\nKd 0.5 0.25 1\nmap_Kd b.png\n"
                              "map_d b.png\n");
    Scene s;
    TextureCache cache;
    load_obj(write_text(d / "one.obj", "mtllib two.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                       "usemtl used\nf 1/1 2/2 3/3\n"),
             s, cache);
    REQUIRE(s.materials.size() == 2);
    CHECK(s.materials[0].diffuse_texture >= 0);
    CHECK(s.materials[1].name == "unused");
    CHECK(s.materials[1].diffuse == glm::vec3(0.5f, 0.25f, 1.0f));
    CHECK(s.materials[1].diffuse_texture < 0);
    CHECK(s.materials[1].alpha_texture < 0);
    CHECK(s.textures.size() == 1);
  }
  fs::remove_all(d);
}

namespace {
// The faces of an OBJ of one polygon: the sum of its triangles' areas, the largest area one of them
// has against the face's winding (a triangle outside the face, or folded over it), their count.
struct FaceCover {
  double area = 0.0, against = 0.0;
  size_t triangles = 0;
};
FaceCover cover_of(const Scene& s, const glm::dvec3& face_normal) {
  FaceCover c;
  for (const Mesh& m : s.meshes)
    for (const glm::uvec3& t : m.triangles) {
      const glm::dvec3 a(m.positions[t.x]), b(m.positions[t.y]), d(m.positions[t.z]);
      const double signed_area = 0.5 * glm::dot(glm::cross(b - a, d - a), face_normal);
      c.area += std::abs(signed_area);
      c.against = std::max(c.against, -signed_area);
      ++c.triangles;
    }
  return c;
}
}  // namespace

TEST_CASE("OBJ: a face of n corners gives n - 2 triangles covering it exactly, wherever it lies, concave or not",
          "[unit][loaders]") {
  // tinyobjloader's triangulation lost triangles of concave faces without a word, depending on
  // where they lay (an L-shaped hexagon at the origin gave 4 triangles, moved by (-5, 5, 0) one: an
  // outside sweep), and split a concave quad on the diagonal outside it
  const fs::path dir = fs::temp_directory_path() / ("gridrt_obj_faces_" + std::to_string(getpid()));
  fs::create_directories(dir);
  uint64_t seed = 11;
  const auto rnd = [&seed](double lo, double hi) {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * double(seed >> 11) * 0x1p-53;
  };
  // Shapes in the plane, counter-clockwise: an L, a U, a comb, stars, a dart (a concave quad)
  std::vector<std::pair<std::string, std::vector<glm::dvec2>>> shapes{
      {"L", {{0, 0}, {2, 0}, {2, 1}, {1, 1}, {1, 2}, {0, 2}}},
      {"U", {{0, 0}, {3, 0}, {3, 3}, {2, 3}, {2, 1}, {1, 1}, {1, 3}, {0, 3}}},
      {"dart", {{0, 0}, {2, 1}, {0, 2}, {0.5, 1}}},
      {"dart2", {{0.5, 1}, {0, 0}, {2, 1}, {0, 2}}}};
  std::vector<glm::dvec2> comb{{0, 0}};
  for (int k = 0; k < 12; ++k) comb.insert(comb.end(), {{k + 0.0, 3}, {k + 0.5, 3}, {k + 0.5, 1}, {k + 1.0, 1}});
  comb.back() = {12, 0};
  std::reverse(comb.begin(), comb.end());  // counter-clockwise
  shapes.emplace_back("comb", comb);
  for (const int points : {5, 9, 40, 512}) {  // 1,024 corners: the loader's limit for a face
    std::vector<glm::dvec2> star;
    for (int k = 0; k < 2 * points; ++k) {
      const double r = k % 2 ? 0.4 : 1.0, a = M_PI * k / points;
      star.emplace_back(r * std::cos(a), r * std::sin(a));
    }
    shapes.emplace_back("star" + std::to_string(points), star);
  }
  for (const auto& [name, shape] : shapes) {
    double area = 0.0;  // the shoelace formula
    for (size_t k = 0; k < shape.size(); ++k)
      area += 0.5 * (shape[k].x * shape[(k + 1) % shape.size()].y - shape[(k + 1) % shape.size()].x * shape[k].y);
    REQUIRE(area > 0.0);
    for (int trial = 0; trial < 20; ++trial) {
      // A random place: turned about a random axis, moved up to 1e3, either winding
      const glm::dvec3 axis = glm::normalize(glm::dvec3(rnd(-1, 1), rnd(-1, 1), rnd(-1, 1)) + glm::dvec3(1e-3));
      const double angle = rnd(0, 2 * M_PI), c = std::cos(angle), s = std::sin(angle);
      const auto turn = [&](const glm::dvec3& p) {
        return p * c + glm::cross(axis, p) * s + axis * glm::dot(axis, p) * (1.0 - c);
      };
      const glm::dvec3 offset(rnd(-1e3, 1e3), rnd(-1e3, 1e3), rnd(-1e3, 1e3));
      const bool reversed = trial % 2 == 1;
      std::ostringstream obj;
      obj.precision(17);
      for (const glm::dvec2& p : shape) {
        const glm::dvec3 q = turn(glm::dvec3(p, 0.0)) + offset;
        obj << "v " << float(q.x) << ' ' << float(q.y) << ' ' << float(q.z) << '\n';
      }
      obj << 'f';
      for (size_t k = 0; k < shape.size(); ++k) obj << ' ' << (reversed ? shape.size() - k : k + 1);
      obj << '\n';
      const fs::path file = dir / (name + ".obj");
      std::ofstream(file) << obj.str();
      const Scene scene = load_scene(file.string());
      const glm::dvec3 normal = turn(glm::dvec3(0, 0, reversed ? -1 : 1));
      const FaceCover got = cover_of(scene, normal);
      INFO(name << " trial " << trial << ": area " << got.area << " of " << area << ", " << got.triangles
                << " triangles, one against the winding by " << got.against);
      CHECK(got.triangles == shape.size() - 2);
      CHECK(std::abs(got.area - area) <= 1e-4 * area);  // the vertices rounded to float at 1e3
      CHECK(got.against <= 1e-4 * area);
    }
  }
  fs::remove_all(dir);
}

// An outside sweep's find: a texture made from a file (its alpha from its first channel) was
// keyed "<path>#alpha-from-first-channel", which a file may be named: that file took the copy
TEST_CASE("Textures: a file named like another texture's derived key is its own texture", "[unit][loaders]") {
  if (!have_image_library()) return;
  const fs::path d = temp_dir();
  write_image_rgba8((d / "t.png").string(), 1, 1, std::vector<uint8_t>{200, 200, 200, 255}, false);
  write_image_rgba8((d / "u.png").string(), 1, 1, std::vector<uint8_t>{10, 20, 30, 255}, false);
  fs::rename(d / "u.png", d / "t.png#alpha-from-first-channel");
  write_text(d / "k.mtl", "newmtl a\nKd 1 1 1\nmap_d t.png\nnewmtl b\nKd 1 1 1\nmap_Kd t.png#alpha-from-first-channel\n");
  Scene s;
  TextureCache cache;
  load_obj(write_text(d / "k.obj", "mtllib k.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nusemtl a\nf 1/1 2/1 3/1\n"
                                   "usemtl b\nf 1/1 2/1 3/1\n"),
           s, cache);
  REQUIRE(s.materials.size() == 2);
  REQUIRE(s.materials[1].diffuse_texture >= 0);
  CHECK(s.materials[1].diffuse_texture != s.materials[0].alpha_texture);
  const Texture& b = s.textures[size_t(s.materials[1].diffuse_texture)];
  CHECK(b.rgba[0] == 10);
  CHECK(b.rgba[2] == 30);
}
