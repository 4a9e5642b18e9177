// gltf.cpp: glTF 2.0 (.gltf, .glb) through TinyGLTF.
#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <string_view>
#include <cstring>
#include <filesystem>
#include <cstdio>
#include <functional>
#include <iostream>
#include <sstream>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtc/type_ptr.hpp>
#include <nlohmann/json.hpp>
#include <tiny_gltf.h>

#include "gridrt/common/image_io.h"
#include "gridrt/common/loaders/loaders.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/scene_io.h"
#include "gridrt/common/util.h"

namespace gridrt {
namespace fs = std::filesystem;

namespace {

struct Ctx {
  const std::string& path;
  const tinygltf::Model& model;
  // An image whose encoded bytes are an earlier image's: that image (decoded once)
  const std::map<int, int>& image_alias;
  [[noreturn]] void fail(const std::string& what) const { throw Error("glTF '" + path + "': " + what); }
};

size_t component_size(int type) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_BYTE:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return 1;
    case TINYGLTF_COMPONENT_TYPE_SHORT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: return 2;
    case TINYGLTF_COMPONENT_TYPE_INT:
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT:
    case TINYGLTF_COMPONENT_TYPE_FLOAT: return 4;
    default: return 0;
  }
}

// The bytes of element i of an accessor, after checking that all `count` elements lie inside
// the buffer. Calls fn(const unsigned char* element, size_t i) for each.
void for_each_element(const Ctx& c, int accessor_index, const char* what, int want_type,
                      const std::function<void(const unsigned char*, size_t)>& fn, size_t& count_out,
                      int& component_type_out, bool& normalized_out) {
  if (accessor_index < 0 || size_t(accessor_index) >= c.model.accessors.size())
    c.fail(std::string(what) + ": accessor " + std::to_string(accessor_index) + " does not exist");
  const tinygltf::Accessor& a = c.model.accessors[size_t(accessor_index)];
  const std::string where = std::string(what) + " (accessor " + std::to_string(accessor_index) + ")";
  if (a.type != want_type) c.fail(where + ": unexpected element type " + std::to_string(a.type));
  if (a.sparse.isSparse) c.fail(where + ": sparse accessors are not supported");
  if (a.bufferView < 0 || size_t(a.bufferView) >= c.model.bufferViews.size())
    c.fail(where + ": no valid buffer view");
  const tinygltf::BufferView& view = c.model.bufferViews[size_t(a.bufferView)];
  if (view.buffer < 0 || size_t(view.buffer) >= c.model.buffers.size()) c.fail(where + ": no valid buffer");
  const tinygltf::Buffer& buffer = c.model.buffers[size_t(view.buffer)];
  const size_t comp = component_size(a.componentType);
  const int ncomp = tinygltf::GetNumComponentsInType(uint32_t(a.type));
  if (comp == 0 || ncomp <= 0) c.fail(where + ": unknown component type");
  const size_t elem = comp * size_t(ncomp);
  if (view.byteStride != 0 && view.byteStride < elem)
    c.fail(where + ": buffer view " + std::to_string(a.bufferView) + " has byteStride " + std::to_string(view.byteStride) +
           ", smaller than its " + std::to_string(elem) + "-byte elements");
  const int stride_i = a.ByteStride(view);
  if (stride_i <= 0) c.fail(where + ": invalid byte stride");
  const size_t stride = size_t(stride_i);
  // Overflow-safe: every sum and product is checked against the buffer's size before it is
  // formed, so that a count near 2^63 cannot wrap past the check.
  const size_t size = buffer.data.size();
  if (view.byteOffset > size || view.byteLength > size - view.byteOffset)
    c.fail(where + ": buffer view " + std::to_string(a.bufferView) + " (offset " + std::to_string(view.byteOffset) +
           ", length " + std::to_string(view.byteLength) + ") runs past the end of its buffer (" + std::to_string(size) +
           " bytes)");
  if (a.byteOffset > view.byteLength)
    c.fail(where + ": byteOffset " + std::to_string(a.byteOffset) + " lies past the end of its buffer view");
  const size_t start = view.byteOffset + a.byteOffset;
  const size_t room = view.byteLength - a.byteOffset;  // bytes from the first element to the view's end
  if (a.count > 0 && (room < elem || a.count - 1 > (room - elem) / stride))
    c.fail(where + ": " + std::to_string(a.count) + " elements of " + std::to_string(elem) + " bytes every " +
           std::to_string(stride) + " run past the end of the buffer view (" + std::to_string(room) + " bytes)");
  count_out = a.count;
  component_type_out = a.componentType;
  normalized_out = a.normalized;
  for (size_t i = 0; i < a.count; ++i) fn(buffer.data.data() + start + i * stride, i);
}

float read_component(const unsigned char* p, int type, bool normalized) {
  switch (type) {
    case TINYGLTF_COMPONENT_TYPE_FLOAT: { float f; std::memcpy(&f, p, 4); return f; }
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE: return normalized ? float(*p) / 255.0f : float(*p);
    case TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT: {
      uint16_t v; std::memcpy(&v, p, 2); return normalized ? float(v) / 65535.0f : float(v);
    }
    case TINYGLTF_COMPONENT_TYPE_BYTE: {
      int8_t v; std::memcpy(&v, p, 1); return normalized ? std::max(float(v) / 127.0f, -1.0f) : float(v);
    }
    case TINYGLTF_COMPONENT_TYPE_SHORT: {
      int16_t v; std::memcpy(&v, p, 2); return normalized ? std::max(float(v) / 32767.0f, -1.0f) : float(v);
    }
    default: return 0.0f;
  }
}

template <int N>
std::vector<glm::vec<N, float>> read_vectors(const Ctx& c, int accessor, const char* what) {
  std::vector<glm::vec<N, float>> out;
  size_t count; int ctype; bool norm;
  const int want = N == 2 ? TINYGLTF_TYPE_VEC2 : TINYGLTF_TYPE_VEC3;
  // Floats, or (normalized) bytes and shorts: what glTF and KHR_mesh_quantization allow a vertex
  // attribute (an unsigned int one was read as zeros)
  if (accessor >= 0 && size_t(accessor) < c.model.accessors.size()) {
    const int t = c.model.accessors[size_t(accessor)].componentType;
    if (t != TINYGLTF_COMPONENT_TYPE_FLOAT && t != TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE &&
        t != TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT && t != TINYGLTF_COMPONENT_TYPE_BYTE &&
        t != TINYGLTF_COMPONENT_TYPE_SHORT)
      c.fail(std::string(what) + " (accessor " + std::to_string(accessor) + "): component type " + std::to_string(t) +
             " is none a vertex attribute may have (float, byte, short, their unsigned and normalized forms)");
  }
  // First pass sizes `out` through the count; elements are written as they come.
  for_each_element(
      c, accessor, what, want,
      [&](const unsigned char* p, size_t i) {
        if (out.empty()) out.resize(c.model.accessors[size_t(accessor)].count);
        const int t = c.model.accessors[size_t(accessor)].componentType;
        const size_t cs = component_size(t);
        for (int k = 0; k < N; ++k)
          out[i][k] = read_component(p + size_t(k) * cs, t, c.model.accessors[size_t(accessor)].normalized);
      },
      count, ctype, norm);
  return out;
}

std::vector<uint32_t> read_indices(const Ctx& c, int accessor) {
  std::vector<uint32_t> out;
  size_t count; int ctype; bool norm;
  for_each_element(
      c, accessor, "indices", TINYGLTF_TYPE_SCALAR,
      [&](const unsigned char* p, size_t) {
        const int t = c.model.accessors[size_t(accessor)].componentType;
        uint32_t v = 0;
        if (t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE) v = *p;
        else if (t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT) { uint16_t s; std::memcpy(&s, p, 2); v = s; }
        else if (t == TINYGLTF_COMPONENT_TYPE_UNSIGNED_INT) std::memcpy(&v, p, 4);
        else c.fail("indices (accessor " + std::to_string(accessor) + ") must be unsigned byte, short or int");
        out.push_back(v);
      },
      count, ctype, norm);
  return out;
}

// A decoded glTF image as an RGBA8 texture.
Texture image_texture(const Ctx& c, int image_index) {
  if (image_index < 0 || size_t(image_index) >= c.model.images.size())
    c.fail("image " + std::to_string(image_index) + " does not exist");
  const tinygltf::Image& img = c.model.images[size_t(image_index)];
  const std::string what = "image " + std::to_string(image_index) + (img.uri.empty() ? "" : " ('" + img.uri + "')");
  if (img.width <= 0 || img.height <= 0)
    c.fail(what + ": not decoded (no image data was read for it: its file, buffer view or data URI is missing, "
                  "empty or not a PNG or JPEG)");
  if (img.component < 1 || img.component > 4 || (img.bits != 8 && img.bits != 16))
    c.fail(what + ": not decoded (" + std::to_string(img.width) + " x " + std::to_string(img.height) + ", " +
           std::to_string(img.component) + " channels of " + std::to_string(img.bits) + " bits)");
  const size_t n = size_t(img.width) * size_t(img.height);
  const size_t bpc = size_t(img.bits / 8);
  const size_t nc = size_t(img.component);
  if (img.image.size() < n * nc * bpc) c.fail(what + ": decoded data too short");
  Texture tex;
  tex.path = c.path + "#image" + std::to_string(image_index);
  tex.width = uint32_t(img.width);
  tex.height = uint32_t(img.height);
  tex.rgba.resize(n * 4);
  auto chan = [&](size_t i, size_t k) -> uint8_t {
    const unsigned char* p = img.image.data() + (i * nc + k) * bpc;
    return bpc == 1 ? p[0] : p[1];  // 16-bit little-endian: keep the high byte
  };
  for (size_t i = 0; i < n; ++i) {
    uint8_t* q = tex.rgba.data() + i * 4;
    if (nc >= 3) { q[0] = chan(i, 0); q[1] = chan(i, 1); q[2] = chan(i, 2); }
    else { q[0] = q[1] = q[2] = chan(i, 0); }
    q[3] = (nc == 2 || nc == 4) ? chan(i, nc - 1) : 255;
    if (q[3] < 255) tex.has_alpha = true;
  }
  return tex;
}

// glTF puts v = 0 at an image's first row, alpha.h's rule at its last: v is flipped, to 1 - v,
// which keeps glTF's nearest texel, floor(frac(v) h) from the top, ties included. Where 1 - v is
// a whole number (v a whole number, or within about 3e-8 of one, rounded) the rule's frac() would
// give 0, the last row, where glTF reads the first: the next float below it reads the first row.
// (Stored as they come, with v unflipped, put every tie v = k / h a row off.)
glm::vec2 gltf_uv(glm::vec2 uv) {
  float v = 1.0f - uv.y;
  if (v == std::floor(v)) v = std::nextafter(v, -std::numeric_limits<float>::infinity());
  return {uv.x, v};
}

// A node's local transform: its matrix, else T * R * S. The rotation must be a unit quaternion
// (glTF 2.0, node.rotation): one within 1e-3 of unit length (an exporter's rounding) is normalized,
// any other refused (as is a non-finite one), where glm would scale the model by its squared length.
// A matrix must be an affine transform (its last row 0 0 0 1): another is an error naming the node
// (it passed without a word: an outside sweep). With a matrix, TinyGLTF reads no translation,
// rotation or scale (glTF 2.0 allows one or the other).
glm::mat4 local_matrix(const Ctx& c, int ni, const tinygltf::Node& n) {
  if (!n.matrix.empty() && n.matrix.size() != 16)
    c.fail("node " + std::to_string(ni) + ": a matrix has 16 numbers, not " + std::to_string(n.matrix.size()));
  if (n.matrix.size() == 16) {
    if (n.matrix[3] != 0.0 || n.matrix[7] != 0.0 || n.matrix[11] != 0.0 || n.matrix[15] != 1.0)
      c.fail("node " + std::to_string(ni) + ": the matrix's last row is not 0 0 0 1 (not an affine transform)");
    glm::mat4 m;
    for (int i = 0; i < 16; ++i) glm::value_ptr(m)[i] = float(n.matrix[size_t(i)]);
    return m;
  }
  glm::mat4 m(1.0f);
  if (n.translation.size() == 3)
    m = glm::translate(m, glm::vec3(float(n.translation[0]), float(n.translation[1]), float(n.translation[2])));
  if (n.rotation.size() == 4) {
    const glm::dvec4 q(n.rotation[0], n.rotation[1], n.rotation[2], n.rotation[3]);
    const double len = glm::length(q);
    if (!(std::abs(len - 1.0) <= 1e-3))
      c.fail("node " + std::to_string(ni) + ": rotation (" + std::to_string(q.x) + ", " + std::to_string(q.y) + ", " +
             std::to_string(q.z) + ", " + std::to_string(q.w) + ") is not a unit quaternion (length " +
             std::to_string(len) + ")");
    const glm::dvec4 u = q / len;
    m *= glm::mat4_cast(glm::quat(float(u.w), float(u.x), float(u.y), float(u.z)));
  }
  if (n.scale.size() == 3) m = glm::scale(m, glm::vec3(float(n.scale[0]), float(n.scale[1]), float(n.scale[2])));
  return m;
}

// The JSON chunk of a GLB (the whole data when the header does not parse: TinyGLTF then reports
// what is wrong).
std::string_view glb_json_chunk(const std::string& data) {
  if (data.size() < 20 || data.compare(0, 4, "glTF") != 0) return data;
  uint32_t len = 0;
  std::memcpy(&len, data.data() + 12, 4);
  return std::string_view(data).substr(20, std::min<size_t>(len, data.size() - 20));
}

// External buffers and images: regular files within the size bound only (a directory or a
// device as a uri is an error, not an allocation failure or a hang).
bool read_external(std::vector<unsigned char>* out, std::string* err, const std::string& path, void*) {
  try {
    const std::string bytes = read_input_file(path, "glTF resource");
    out->assign(bytes.begin(), bytes.end());
    return true;
  } catch (const Error& e) {
    if (err) *err += std::string(e.what()) + "\n";
    return false;
  }
}

// Width and height from a PNG or JPEG header; false for anything else.
bool image_header_size(const unsigned char* p, size_t n, uint64_t& w, uint64_t& h) {
  auto be16 = [&](size_t i) { return uint32_t(p[i]) << 8 | p[i + 1]; };
  auto be32 = [&](size_t i) { return be16(i) << 16 | be16(i + 2); };
  if (n >= 24 && std::memcmp(p, "\x89PNG\r\n\x1a\n", 8) == 0 && std::memcmp(p + 12, "IHDR", 4) == 0) {
    w = be32(16);
    h = be32(20);
    return true;
  }
  if (n >= 4 && p[0] == 0xFF && p[1] == 0xD8) {
    size_t i = 2;
    while (i + 9 < n) {
      if (p[i] != 0xFF) return false;
      const unsigned char m = p[i + 1];
      if (m == 0xFF) { ++i; continue; }
      if (m >= 0xC0 && m <= 0xCF && m != 0xC4 && m != 0xC8 && m != 0xCC) {
        h = be16(i + 5);
        w = be16(i + 7);
        return true;
      }
      if (m == 0xD8 || (m >= 0xD0 && m <= 0xD7) || m == 0x01) { i += 2; continue; }
      i += 2 + be16(i + 2);
    }
  }
  return false;
}

// The values TinyGLTF reads leniently: a property of the wrong type or length, or an index below
// -1, was dropped and read as absent (a node's translation ["a", 0, 0], a scale of two numbers, a
// mesh or material index of -2, a string alphaCutoff: exit 0 and another picture, an outside
// sweep). Checked on the JSON first, each named by its path. Also: the images a material's base
// colour names, the only ones this loader reads (`used`).
void check_gltf_json(const std::string& path, std::string_view text, std::set<int>& used) {
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text.begin(), text.end());
  } catch (const nlohmann::json::exception&) {
    return;  // TinyGLTF names the syntax error
  }
  const auto fail = [&](const std::string& where, const std::string& what) {
    throw Error("cannot load glTF '" + path + "': " + where + ": " + what);
  };
  // A key given twice in one object: TinyGLTF keeps the last without a word (a node's second
  // "translation" moved it: an outside sweep), as the scene files refuse it
  if (const std::string dup = json_first_duplicate_key(std::string(text)); !dup.empty())
    fail(dup, "the key is given twice in its object (the last would win without a word)");
  // The extensions a file requires or uses, as arrays of names: given as one string, TinyGLTF
  // read none, and a required extension this loader does not implement went unrefused (an
  // outside sweep)
  if (j.is_object())
    for (const char* key : {"extensionsRequired", "extensionsUsed"})
      if (j.contains(key)) {
        const nlohmann::json& a = j[key];
        bool names = a.is_array();
        for (size_t i = 0; names && i < a.size(); ++i) names = a[i].is_string();
        if (!names) fail(key, "expected an array of extension names, found " + a.dump().substr(0, 64));
      }
  // asset.minVersion: the least version a reader must implement; this loader reads glTF 2.0, and
  // a file that asks for more ("3.0", "2.1") was read as if it did not (an outside sweep)
  if (j.is_object() && j.contains("asset") && j["asset"].is_object() && j["asset"].contains("minVersion")) {
    const nlohmann::json& m = j["asset"]["minVersion"];
    if (!m.is_string() || m.get<std::string>() != "2.0")
      fail("asset.minVersion", "is " + m.dump().substr(0, 32) + "; gridrt reads glTF 2.0 (a file asking for a later "
                               "version needs a reader of it)");
  }
  const auto numbers = [&](const nlohmann::json& o, const char* key, size_t n, const std::string& where) {
    if (!o.contains(key)) return;
    const nlohmann::json& a = o[key];
    if (!a.is_array() || a.size() != n) fail(where + "." + key, "expected an array of " + std::to_string(n) + " numbers");
    for (const nlohmann::json& v : a)
      if (!v.is_number()) fail(where + "." + key, "expected an array of " + std::to_string(n) + " numbers");
  };
  const auto index = [&](const nlohmann::json& o, const char* key, const std::string& where) {
    if (!o.is_object() || !o.contains(key)) return;
    const nlohmann::json& v = o[key];
    if (!v.is_number_integer() || v.get<int64_t>() < 0 || v.get<int64_t>() > INT32_MAX)
      fail(where + "." + key, "expected an index (an integer from 0), found " + v.dump());
  };
  const auto array = [&](const char* key) -> const nlohmann::json* {
    return j.is_object() && j.contains(key) && j[key].is_array() ? &j[key] : nullptr;
  };
  // An index is an integer from 0 below 2^31 wherever the file gives one: TinyGLTF reads a larger
  // one modulo 2^32 ("scene": 4294967297 chose scene 1, "POSITION": 4294967298 accessor 2) and a
  // string or a fraction as absent (scene 0), without a word (an outside sweep)
  const auto is_index = [](const nlohmann::json& v) {
    return v.is_number_integer() && v.get<int64_t>() >= 0 && v.get<int64_t>() <= INT32_MAX;
  };
  if (j.is_object() && j.contains("scene") && !is_index(j["scene"]))
    fail("scene", "expected an index (an integer from 0), found " + j["scene"].dump().substr(0, 64));
  if (const nlohmann::json* scenes = array("scenes"))
    for (size_t i = 0; i < scenes->size(); ++i) {
      const nlohmann::json& s = (*scenes)[i];
      if (!s.is_object() || !s.contains("nodes")) continue;
      const std::string where = "scenes[" + std::to_string(i) + "].nodes";
      if (!s["nodes"].is_array()) fail(where, "expected an array of node indices");
      for (const nlohmann::json& n : s["nodes"])
        if (!is_index(n)) fail(where, "expected an array of node indices, found " + n.dump().substr(0, 64));
    }
  if (const nlohmann::json* nodes = array("nodes"))
    for (size_t i = 0; i < nodes->size(); ++i) {
      const nlohmann::json& n = (*nodes)[i];
      if (!n.is_object()) continue;
      const std::string where = "nodes[" + std::to_string(i) + "]";
      numbers(n, "translation", 3, where);
      numbers(n, "rotation", 4, where);
      numbers(n, "scale", 3, where);
      numbers(n, "matrix", 16, where);
      for (const char* key : {"mesh", "camera", "skin"}) index(n, key, where);
      if (n.contains("children")) {
        if (!n["children"].is_array()) fail(where + ".children", "expected an array of indices");
        for (const nlohmann::json& c : n["children"])
          if (!is_index(c)) fail(where + ".children", "expected an array of indices, found " + c.dump().substr(0, 64));
      }
    }
  if (const nlohmann::json* meshes = array("meshes"))
    for (size_t i = 0; i < meshes->size(); ++i) {
      const nlohmann::json& m = (*meshes)[i];
      if (!m.is_object() || !m.contains("primitives") || !m["primitives"].is_array()) continue;
      for (size_t k = 0; k < m["primitives"].size(); ++k) {
        const nlohmann::json& p = m["primitives"][k];
        const std::string where = "meshes[" + std::to_string(i) + "].primitives[" + std::to_string(k) + "]";
        for (const char* key : {"material", "indices", "mode"}) index(p, key, where);
        if (p.is_object() && p.contains("attributes") && p["attributes"].is_object())
          for (auto a = p["attributes"].begin(); a != p["attributes"].end(); ++a)
            if (!is_index(*a)) fail(where + ".attributes." + a.key(), "expected an accessor index, found " + a->dump());
      }
    }
  // Offsets, strides, counts and flags of the buffer views and accessors: TinyGLTF read a string,
  // a negative number or a fraction there as absent or 0, and the indices came from the positions'
  // bytes, exit 0 (an outside sweep)
  const auto whole = [&](const nlohmann::json& o, const char* key, const std::string& where, int64_t least) {
    if (!o.is_object() || !o.contains(key)) return;
    const nlohmann::json& v = o[key];
    if (!v.is_number_integer() || v.get<int64_t>() < least)
      fail(where + "." + key, "expected an integer from " + std::to_string(least) + ", found " + v.dump());
  };
  if (const nlohmann::json* views = array("bufferViews"))
    for (size_t i = 0; i < views->size(); ++i) {
      const std::string where = "bufferViews[" + std::to_string(i) + "]";
      index((*views)[i], "buffer", where);
      whole((*views)[i], "byteOffset", where, 0);
      whole((*views)[i], "byteLength", where, 1);
      whole((*views)[i], "byteStride", where, 4);
      whole((*views)[i], "target", where, 0);
    }
  // A URI's NUL (raw, or %00 once decoded) cut the name there, and the file before it was read (an
  // outside sweep)
  for (const char* kind : {"buffers", "images"})
    if (const nlohmann::json* list = array(kind))
      for (size_t i = 0; i < list->size(); ++i) {
        const nlohmann::json& b = (*list)[i];
        const std::string where = std::string(kind) + "[" + std::to_string(i) + "]";
        if (std::string(kind) == "buffers") whole(b, "byteLength", where, 1);
        else index(b, "bufferView", where);
        if (!b.is_object() || !b.contains("uri")) continue;
        if (!b["uri"].is_string()) fail(where + ".uri", "expected a string");
        const std::string uri = b["uri"].get<std::string>();
        if (uri.find('\0') != std::string::npos || uri.find("%00") != std::string::npos)
          fail(where + ".uri", "a NUL byte (or %00) in a file name");
      }
  if (const nlohmann::json* accessors = array("accessors"))
    for (size_t i = 0; i < accessors->size(); ++i) {
      const nlohmann::json& a = (*accessors)[i];
      const std::string where = "accessors[" + std::to_string(i) + "]";
      index(a, "bufferView", where);
      whole(a, "byteOffset", where, 0);
      whole(a, "count", where, 1);
      whole(a, "componentType", where, 0);
      if (a.is_object() && a.contains("normalized") && !a["normalized"].is_boolean())
        fail(where + ".normalized", "expected true or false, found " + a["normalized"].dump());
      if (a.is_object() && a.contains("type") && !a["type"].is_string())
        fail(where + ".type", "expected a string, found " + a["type"].dump());
    }
  std::set<int> textures;
  if (const nlohmann::json* materials = array("materials"))
    for (size_t i = 0; i < materials->size(); ++i) {
      const nlohmann::json& m = (*materials)[i];
      if (!m.is_object()) continue;
      const std::string where = "materials[" + std::to_string(i) + "]";
      if (m.contains("alphaCutoff") && !m["alphaCutoff"].is_number()) fail(where + ".alphaCutoff", "expected a number");
      if (m.contains("alphaMode") && !m["alphaMode"].is_string()) fail(where + ".alphaMode", "expected a string");
      if (m.contains("pbrMetallicRoughness") && m["pbrMetallicRoughness"].is_object()) {
        const nlohmann::json& pbr = m["pbrMetallicRoughness"];
        numbers(pbr, "baseColorFactor", 4, where + ".pbrMetallicRoughness");
        if (pbr.contains("baseColorTexture")) {
          index(pbr["baseColorTexture"], "index", where + ".pbrMetallicRoughness.baseColorTexture");
          index(pbr["baseColorTexture"], "texCoord", where + ".pbrMetallicRoughness.baseColorTexture");
          if (pbr["baseColorTexture"].is_object() && pbr["baseColorTexture"].contains("index"))
            textures.insert(pbr["baseColorTexture"]["index"].get<int>());
        }
      }
    }
  if (const nlohmann::json* texs = array("textures"))
    for (size_t t = 0; t < texs->size(); ++t) {
      index((*texs)[t], "source", "textures[" + std::to_string(t) + "]");
      index((*texs)[t], "sampler", "textures[" + std::to_string(t) + "]");
      if (textures.count(int(t)) && (*texs)[t].is_object() && (*texs)[t].contains("source"))
        used.insert((*texs)[t]["source"].get<int>());
    }
}

// The model being parsed and the images its materials use, for the image callback; the encoded
// bytes of each image decoded (by size and hash), and the images whose bytes were an earlier one's.
struct ImageLoad {
  const tinygltf::Model* model = nullptr;
  std::set<int> used;
  // (an image in a buffer view is seen where it lies, in the model's buffer, which outlives the
  // parse; one from a file or data URI is copied: its bytes are gone after the callback)
  struct Seen {
    int index;
    std::string copy;
    std::string_view view;
  };
  std::map<std::pair<size_t, size_t>, std::vector<Seen>> decoded;
  std::map<int, int> alias;
};

// TinyGLTF's image decoder, after the header's size was checked against the pixel limit.
// `user`: the model being parsed (its buffers and buffer views are read before its images). An
// image in a buffer view is handed over as the buffer's bytes from the view's offset, unchecked:
// a view past its buffer is refused here, before a byte is read.
bool load_image_checked(tinygltf::Image* image, const int index, std::string* err, std::string* warn, int req_w,
                        int req_h, const unsigned char* bytes, int size, void* user) {
  // An image no material's base colour names is not decoded: twelve unused entries of one 8192 x
  // 8192 PNG took 3.5 GB (an outside sweep)
  ImageLoad* load = static_cast<ImageLoad*>(user);
  if (load && !load->used.count(index)) return true;
  if (image->bufferView >= 0 && load && load->model) {
    const tinygltf::Model& model = *load->model;
    if (size_t(image->bufferView) >= model.bufferViews.size()) {
      if (err) *err += "image " + std::to_string(index) + ": buffer view " + std::to_string(image->bufferView) + " does not exist\n";
      return false;
    }
    const tinygltf::BufferView& view = model.bufferViews[size_t(image->bufferView)];
    const size_t have = view.buffer >= 0 && size_t(view.buffer) < model.buffers.size()
                            ? model.buffers[size_t(view.buffer)].data.size()
                            : 0;
    if (view.byteOffset > have || view.byteLength > have - view.byteOffset) {
      if (err)
        *err += "image " + std::to_string(index) + ": buffer view " + std::to_string(image->bufferView) + " (offset " +
                std::to_string(view.byteOffset) + ", " + std::to_string(view.byteLength) + " bytes) lies past buffer " +
                std::to_string(view.buffer) + " (" + std::to_string(have) + " bytes)\n";
      return false;
    }
  }
  uint64_t w = 0, h = 0;
  if (size <= 0 || !image_header_size(bytes, size_t(size), w, h)) {
    if (err) *err += "image " + std::to_string(index) + ": not a PNG or JPEG with a readable header\n";
    return false;
  }
  if (w == 0 || h == 0 || w * h > input_limits().max_texture_pixels) {
    if (err)
      *err += "image " + std::to_string(index) + ": its header declares " + std::to_string(w) + " x " + std::to_string(h) +
              " pixels, zero or more than the limit of " + std::to_string(input_limits().max_texture_pixels) +
              " (--max-texture-pixels)\n";
    return false;
  }
  // An image whose bytes an earlier one had (entries naming one file or buffer view, however
  // spelled) is that image: decoded once (ten entries of one 8192 x 8192 PNG took 5.4 GB: an outside
  // sweep)
  // (after the checks above: the bytes of a view past its buffer are not to be read)
  if (load && bytes && size > 0) {
    const std::string_view encoded(reinterpret_cast<const char*>(bytes), size_t(size));
    auto& same = load->decoded[{encoded.size(), std::hash<std::string_view>{}(encoded)}];
    for (const ImageLoad::Seen& seen : same)
      if ((seen.copy.empty() ? seen.view : std::string_view(seen.copy)) == encoded) {
        load->alias[index] = seen.index;
        return true;
      }
    if (image->bufferView >= 0) same.push_back({index, std::string(), encoded});
    else same.push_back({index, std::string(encoded), std::string_view()});
  }
  // The decoded pixels (up to 16 bits a channel) and their RGBA8 copy must fit the host's memory
  require_host_memory(w * h * 12, "glTF image " + std::to_string(index) + " (" + std::to_string(w) + " x " +
                                      std::to_string(h) + " pixels, decoded)",
                      "lower --max-texture-pixels, or use smaller textures");
  // Decoded as the OBJ's textures are (image_io.h decode_image): TinyGLTF's decoder (stb_image)
  // read a JPEG cut short as texels of filler, one whose header claimed 8000 x 8000 as 64
  // megapixels of it, and a PNG whose data fails its checksum, all without a word (an outside
  // sweep). A build without OpenImageIO (the GPU machine's, which loads .gridscene caches) keeps
  // TinyGLTF's decoder.
  if (!have_image_library())
    return tinygltf::LoadImageData(image, index, err, warn, req_w, req_h, bytes, size, nullptr);  // its options: none
  try {
    const std::string name = "image " + std::to_string(index) + (image->uri.empty() ? "" : " ('" + image->uri + "')");
    DecodedImage d = decode_image(name, bytes, size_t(size));
    image->width = int(d.width);
    image->height = int(d.height);
    image->component = d.channels;
    image->bits = d.bits;
    image->pixel_type = d.bits == 16 ? TINYGLTF_COMPONENT_TYPE_UNSIGNED_SHORT : TINYGLTF_COMPONENT_TYPE_UNSIGNED_BYTE;
    image->image = std::move(d.data);
    return true;
  } catch (const Error& e) {
    if (err) *err += std::string(e.what()) + "\n";
    return false;
  }
}

// TinyGLTF's FileExists probes a path by opening it (fopen): a FIFO blocked there forever, before
// read_external could refuse it (an outside sweep). Existence by the entry alone (stat, no open);
// read_external then names what the entry is. An entry whose existence cannot be told (a loop of
// symbolic links, a folder without search permission) is taken as there, so that read_external
// names the error rather than TinyGLTF's "File not found" (an outside sweep).
bool file_exists_unopened(const std::string& abs_filename, void*) {
  std::error_code ec;
  const bool exists = fs::exists(fs::path(abs_filename), ec);
  return exists || (ec && ec != std::errc::no_such_file_or_directory && ec != std::errc::not_a_directory);
}

// The model: the file read here (a regular file within the size bound), the JSON's nesting depth
// checked before TinyGLTF's recursive parser sees it, external buffers and images read and decoded
// only through the checked callbacks above.
tinygltf::Model parse_model(const std::string& path, std::map<int, int>& image_alias) {
  const std::string data = read_input_file(path, "glTF");
  tinygltf::TinyGLTF loader;
  tinygltf::Model model;
  std::string err, warn;
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char ch) { return char(std::tolower(ch)); });
  const bool binary = ext == ".glb";
  check_json_depth(binary ? glb_json_chunk(data) : std::string_view(data), path, input_limits().max_json_depth);
  ImageLoad images;
  images.model = &model;
  check_gltf_json(path, binary ? glb_json_chunk(data) : std::string_view(data), images.used);
  if (data.size() > UINT32_MAX) throw Error("cannot load glTF '" + path + "': larger than 4 GiB");
  tinygltf::FsCallbacks fs_callbacks{&file_exists_unopened, &tinygltf::ExpandFilePath, &read_external, nullptr, nullptr};
  loader.SetFsCallbacks(fs_callbacks);
  loader.SetImageLoader(&load_image_checked, &images);
  std::string base_dir = fs::path(path).parent_path().string();
  if (base_dir.empty()) base_dir = ".";
  bool ok = false;
  try {
    ok = binary ? loader.LoadBinaryFromMemory(&model, &err, &warn, reinterpret_cast<const unsigned char*>(data.data()),
                                              unsigned(data.size()), base_dir)
                : loader.LoadASCIIFromString(&model, &err, &warn, data.data(), unsigned(data.size()), base_dir);
  } catch (const std::bad_alloc&) {
    throw Error("cannot load glTF '" + path + "': out of memory while parsing");
  } catch (const std::length_error& e) {
    throw Error("cannot load glTF '" + path + "': a size in the file is too large (" + e.what() + ")");
  }
  if (!ok || !err.empty()) {
    while (!err.empty() && err.back() == '\n') err.pop_back();
    throw Error("cannot load glTF '" + path + "': " + (err.empty() ? std::string("TinyGLTF failed") : printable_message(err)));
  }
  // glTF 2.x only: the spec asks a loader to refuse another major version ("3.0" was read as 2.0:
  // an outside sweep)
  if (const std::string& v = model.asset.version; !v.empty() && !(v == "2" || v.rfind("2.", 0) == 0))
    throw Error("cannot load glTF '" + path + "': asset.version is '" + v.substr(0, 32) +
                "'; gridrt reads glTF 2.x");
  // A file may require extensions; one this loader does not implement would be read as if it
  // were plain glTF (meshopt's compressed buffer views as raw vertices, Draco's geometry missing,
  // texture transforms ignored): refused, as the glTF spec asks. Quantized attributes (integer
  // and normalized component types) are read as such.
  for (const std::string& required : model.extensionsRequired)
    if (required != "KHR_mesh_quantization")
      throw Error("cannot load glTF '" + path + "': it requires the extension " + required +
                  ", which gridrt does not implement (supported: KHR_mesh_quantization)");
  // KHR_texture_transform (not required): said only where a texture this loader reads (the base
  // colour, for the diffuse colour and the alpha mask) carries a transform; a normal or occlusion
  // texture's transform changes nothing here
  for (size_t m = 0; m < model.materials.size(); ++m) {
    const tinygltf::TextureInfo& base = model.materials[m].pbrMetallicRoughness.baseColorTexture;
    if (base.index >= 0 && base.extensions.count("KHR_texture_transform"))
      std::cerr << "warning: " << path << ": material " << m
                << (model.materials[m].name.empty() ? "" : " ('" + model.materials[m].name + "')")
                << ": its base colour texture's KHR_texture_transform is not applied, the texture coordinates are "
                   "read as stored\n";
  }
  if (!warn.empty()) {
    std::istringstream ws(warn);
    for (std::string w; std::getline(ws, w);)
      if (!w.empty()) std::cerr << "warning: " << path << ": " << w << "\n";
  }
  image_alias = images.alias;
  return model;
}

// Materials and their textures, appended to the scene's.
void add_materials(const Ctx& c, Scene& scene, TextureCache& textures) {
  const std::string& path = c.path;
  auto texture_of = [&](int texture_index) -> int {
    if (texture_index < 0 || size_t(texture_index) >= c.model.textures.size())
      c.fail("texture " + std::to_string(texture_index) + " does not exist");
    const int source = c.model.textures[size_t(texture_index)].source;
    if (source < 0)
      c.fail("texture " + std::to_string(texture_index) + " has no source image gridrt reads (a source given only "
             "through an extension, such as EXT_texture_webp, is not read)");
    const auto same = c.image_alias.find(source);
    return same != c.image_alias.end() ? same->second : source;
  };
  std::set<int> warned_samplers;
  for (size_t mi = 0; mi < c.model.materials.size(); ++mi) {
    const tinygltf::Material& gm = c.model.materials[mi];
    const auto& pbr = gm.pbrMetallicRoughness;
    Material mat;
    mat.name = gm.name.empty() ? "material" + std::to_string(mi) : gm.name;
    float factor_alpha = 1.0f;
    if (pbr.baseColorFactor.size() == 4) {
      mat.diffuse = glm::vec3(float(pbr.baseColorFactor[0]), float(pbr.baseColorFactor[1]), float(pbr.baseColorFactor[2]));
      factor_alpha = float(pbr.baseColorFactor[3]);
      mat.opacity = factor_alpha;
    }
    // alphaMode: OPAQUE, MASK (keyed) or BLEND (traced as opaque: this tracer keys, it does not
    // blend); any other name is not glTF
    if (gm.alphaMode != "OPAQUE" && gm.alphaMode != "MASK" && gm.alphaMode != "BLEND")
      c.fail("material '" + mat.name + "': alphaMode '" + gm.alphaMode + "' is none of OPAQUE, MASK, BLEND");
    if (gm.alphaMode == "MASK" && !(gm.alphaCutoff >= 0.0))
      c.fail("material '" + mat.name + "': alphaCutoff " + std::to_string(gm.alphaCutoff) + " is below 0");
    if (gm.alphaMode == "BLEND")
      std::cerr << "warning: " << path << ": material '" << mat.name
                << "' has alphaMode BLEND, traced as opaque (gridrt keys MASK materials, it does not blend)\n";
    if (pbr.baseColorTexture.index >= 0) {
      const int image = texture_of(pbr.baseColorTexture.index);
      // Samplers: every texture repeats, nearest texel (shared/alpha.h); another wrap mode is said
      const int sampler = c.model.textures[size_t(pbr.baseColorTexture.index)].sampler;
      if (sampler >= 0) {
        if (size_t(sampler) >= c.model.samplers.size())
          c.fail("texture " + std::to_string(pbr.baseColorTexture.index) + ": sampler " + std::to_string(sampler) +
                 " does not exist");
        const tinygltf::Sampler& smp = c.model.samplers[size_t(sampler)];
        if ((smp.wrapS != TINYGLTF_TEXTURE_WRAP_REPEAT || smp.wrapT != TINYGLTF_TEXTURE_WRAP_REPEAT) &&
            warned_samplers.insert(sampler).second)  // once a sampler
          std::cerr << "warning: " << path << ": material '" << mat.name << "': sampler " << sampler
                    << "'s wrap modes are not read: its texture repeats (gridrt's one uv rule)\n";
      }
      if (pbr.baseColorTexture.texCoord != 0)
        std::cerr << "warning: " << path << ": material '" << mat.name << "' uses TEXCOORD_"
                  << pbr.baseColorTexture.texCoord << "; only TEXCOORD_0 is read\n";
      // (Keys of textures made from a file hold a NUL, which no file name can: a texture file
      // named like another's key, "<model>#image0", took that texture, an outside sweep)
      const std::string key = path + std::string(1, '\0') + "image" + std::to_string(image);
      mat.diffuse_texture = textures.get_or_add(scene, key, [&] { return image_texture(c, image); });
      if (gm.alphaMode == "MASK") {
        const float cutoff = float(gm.alphaCutoff);
        if (cutoff == 0.5f && factor_alpha == 1.0f) {
          mat.alpha_texture = mat.diffuse_texture;
        } else {
          // Bake factor and cutoff into a copy, so that alpha.h's fixed cutoff (128) applies.
          // Keyed by the two floats' exact values (6 digits made 0.5019606 and 0.5019612 one key)
          std::ostringstream k;
          k << key << '\0' << "mask" << std::hexfloat << cutoff << "x" << factor_alpha;
          const int32_t src = mat.diffuse_texture;
          mat.alpha_texture = textures.get_or_add(scene, k.str(), [&] {
            require_host_memory(scene.textures[size_t(src)].rgba.size(),
                                "glTF material '" + mat.name + "': its alpha mask (a copy of its texture)",
                                "fewer distinct alphaCutoff values, or smaller textures");
            Texture t = scene.textures[size_t(src)];
            t.path = k.str();
            t.has_alpha = false;
            for (size_t i = 3; i < t.rgba.size(); i += 4) {
              t.rgba[i] = float(t.rgba[i]) / 255.0f * factor_alpha >= cutoff ? 255 : 0;
              if (t.rgba[i] < 255) t.has_alpha = true;
            }
            return t;
          });
        }
      }
    }
    // MASK without a texture: the factor's alpha alone decides (glTF 2.0: alpha = the factor's),
    // the whole material kept or cut. Cut: a 1x1 mask of alpha 0 (every uv reads it)
    if (pbr.baseColorTexture.index < 0 && gm.alphaMode == "MASK" && factor_alpha < float(gm.alphaCutoff)) {
      mat.alpha_texture = textures.get_or_add(scene, path + std::string(1, '\0') + "cut", [&] {
        Texture t;
        t.path = path + "#cut";
        t.width = t.height = 1;
        t.rgba = {255, 255, 255, 0};
        t.has_alpha = true;
        return t;
      });
    }
    scene.materials.push_back(std::move(mat));
  }
}

// Meshes: triangle primitives merged, one Mesh per glTF mesh. A primitive without a material gets
// one "default" material, added on first use.
// Returns the primitives left out (points and lines), "" if none: "mode 1", "modes 0, 1".
std::string add_meshes(const Ctx& c, Scene& scene, uint32_t material_base) {
  // The triangles and vertices every primitive will add, from its accessors' counts, against the
  // limits before any is read: primitives may share one accessor, so the file's size bounds
  // nothing (a 2 MB file of 2,000 primitives naming one index accessor asked for tens of GB
  // before --max-triangles refused the scene: an outside sweep)
  {
    uint64_t triangles = 0, vertices = 0;
    const auto count_of = [&](int accessor) -> uint64_t {
      return accessor >= 0 && size_t(accessor) < c.model.accessors.size() ? uint64_t(c.model.accessors[size_t(accessor)].count)
                                                                           : 0;
    };
    for (size_t mi = 0; mi < c.model.meshes.size(); ++mi)
      for (size_t pi = 0; pi < c.model.meshes[mi].primitives.size(); ++pi) {
        const tinygltf::Primitive& prim = c.model.meshes[mi].primitives[pi];
        const int mode = prim.mode == -1 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
        if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
          continue;
        const auto pos = prim.attributes.find("POSITION");
        const uint64_t n_vertices = pos == prim.attributes.end() ? 0 : count_of(pos->second);
        const uint64_t n = prim.indices >= 0 ? count_of(prim.indices) : n_vertices;
        vertices = std::min<uint64_t>(vertices + n_vertices, uint64_t(1) << 62);
        triangles = std::min<uint64_t>(triangles + (mode == TINYGLTF_MODE_TRIANGLES ? n / 3 : n >= 3 ? n - 2 : 0),
                                       uint64_t(1) << 62);
        const std::string where = "meshes[" + std::to_string(mi) + "].primitives[" + std::to_string(pi) + "]";
        if (triangles > input_limits().max_triangles)
          c.fail(where + ": the primitives so far make " + std::to_string(triangles) + " triangles, more than the limit of " +
                 std::to_string(input_limits().max_triangles) + " (--max-triangles)");
        if (vertices > input_limits().max_vertices)
          c.fail(where + ": the primitives so far make " + std::to_string(vertices) + " vertices, more than the limit of " +
                 std::to_string(input_limits().max_vertices));
      }
  }
  std::vector<int> left_out;
  int64_t default_material = -1;
  for (size_t mi = 0; mi < c.model.meshes.size(); ++mi) {
    const tinygltf::Mesh& gmesh = c.model.meshes[mi];
    Mesh mesh;
    mesh.name = gmesh.name.empty() ? fs::path(c.path).stem().string() + "/mesh" + std::to_string(mi) : gmesh.name;
    bool all_normals = true, any_uv = false;
    std::vector<glm::vec3> normals;
    for (size_t pi = 0; pi < gmesh.primitives.size(); ++pi) {
      const tinygltf::Primitive& prim = gmesh.primitives[pi];
      const std::string where = "mesh '" + mesh.name + "' primitive " + std::to_string(pi);
      const int mode = prim.mode == -1 ? TINYGLTF_MODE_TRIANGLES : prim.mode;
      if (mode == TINYGLTF_MODE_POINTS || mode == TINYGLTF_MODE_LINE || mode == TINYGLTF_MODE_LINE_LOOP ||
          mode == TINYGLTF_MODE_LINE_STRIP) {
        // Points and lines have no surface a ray can meet: left out, said once per primitive
        std::fprintf(stderr, "gltf: '%s': %s: mode %d (%s) has no surface to trace: left out\n", c.path.c_str(),
                     where.c_str(), mode, mode == TINYGLTF_MODE_POINTS ? "points" : "lines");
        if (std::find(left_out.begin(), left_out.end(), mode) == left_out.end()) left_out.push_back(mode);
        continue;
      }
      if (mode != TINYGLTF_MODE_TRIANGLES && mode != TINYGLTF_MODE_TRIANGLE_STRIP && mode != TINYGLTF_MODE_TRIANGLE_FAN)
        c.fail(where + ": mode " + std::to_string(prim.mode) +
               " is not a glTF primitive mode (0-6; triangles 4, strip 5 and fan 6 are traced)");
      auto pos_it = prim.attributes.find("POSITION");
      if (pos_it == prim.attributes.end()) c.fail(where + ": no POSITION attribute");
      const auto positions = read_vectors<3>(c, pos_it->second, "POSITION");
      std::vector<glm::vec3> prim_normals;
      if (auto it = prim.attributes.find("NORMAL"); it != prim.attributes.end()) {
        prim_normals = read_vectors<3>(c, it->second, "NORMAL");
        if (prim_normals.size() != positions.size()) c.fail(where + ": NORMAL count differs from POSITION count");
      } else {
        all_normals = false;
      }
      std::vector<glm::vec2> prim_uvs;
      if (auto it = prim.attributes.find("TEXCOORD_0"); it != prim.attributes.end()) {
        prim_uvs = read_vectors<2>(c, it->second, "TEXCOORD_0");
        if (prim_uvs.size() != positions.size()) c.fail(where + ": TEXCOORD_0 count differs from POSITION count");
        any_uv = true;
      }
      std::vector<uint32_t> indices;
      if (prim.indices >= 0) {
        indices = read_indices(c, prim.indices);
      } else {
        indices.resize(positions.size());
        for (uint32_t i = 0; i < indices.size(); ++i) indices[i] = i;
      }
      if (mode == TINYGLTF_MODE_TRIANGLES && indices.size() % 3 != 0)
        c.fail(where + ": " + std::to_string(indices.size()) + " indices is not a multiple of 3");
      if (mode != TINYGLTF_MODE_TRIANGLES && indices.size() < 3)
        c.fail(where + ": a triangle " + (mode == TINYGLTF_MODE_TRIANGLE_STRIP ? "strip" : "fan") + " of " +
               std::to_string(indices.size()) + " vertices (at least 3)");
      for (uint32_t i : indices)
        if (i >= positions.size())
          c.fail(where + ": index " + std::to_string(i) + " out of range (" + std::to_string(positions.size()) + " vertices)");

      uint32_t material;
      if (prim.material >= 0) {
        if (size_t(prim.material) >= c.model.materials.size()) c.fail(where + ": material " + std::to_string(prim.material) + " does not exist");
        material = material_base + uint32_t(prim.material);
      } else {
        if (default_material < 0) {
          default_material = int64_t(scene.materials.size());
          scene.materials.push_back(Material{.name = "default"});
        }
        material = uint32_t(default_material);
      }
      // A texture without texture coordinates reads uv (0, 0) everywhere: one texel keeps or cuts
      // a keyed primitive whole, said
      // (not a material cut whole by its factor: its 1x1 mask reads the same texel at every uv)
      if (prim_uvs.empty() && material < scene.materials.size() && scene.materials[material].alpha_keyed() &&
          !scene.textures[size_t(scene.materials[material].alpha_texture)].path.ends_with("#cut"))
        std::cerr << "warning: " << c.path << ": " << where << " has no TEXCOORD_0, but its material '"
                  << scene.materials[material].name << "' keys with a texture: every point reads its texel at uv (0, 0)\n";
      const uint32_t first = uint32_t(mesh.positions.size());
      for (size_t v = 0; v < positions.size(); ++v) {
        mesh.positions.push_back(positions[v]);
        normals.push_back(prim_normals.empty() ? glm::vec3(0.0f) : prim_normals[v]);
        mesh.uvs.push_back(prim_uvs.empty() ? glm::vec2(0.0f) : gltf_uv(prim_uvs[v]));
      }
      // Triangle i of a strip is (v_i, v_i+1, v_i+2) with every odd one's last two swapped, so that
      // all keep the first one's winding; of a fan (v_i+1, v_i+2, v_0) (the glTF 2.0 specification,
      // "Primitive topology")
      const auto add = [&](uint32_t a, uint32_t b, uint32_t d) {
        mesh.triangles.emplace_back(first + a, first + b, first + d);
        mesh.materials.push_back(material);
      };
      if (mode == TINYGLTF_MODE_TRIANGLES) {
        for (size_t t = 0; t < indices.size(); t += 3) add(indices[t], indices[t + 1], indices[t + 2]);
      } else if (mode == TINYGLTF_MODE_TRIANGLE_STRIP) {
        for (size_t i = 0; i + 2 < indices.size(); ++i)
          if (i % 2 == 0) add(indices[i], indices[i + 1], indices[i + 2]);
          else add(indices[i], indices[i + 2], indices[i + 1]);
      } else {
        for (size_t i = 0; i + 2 < indices.size(); ++i) add(indices[i + 1], indices[i + 2], indices[0]);
      }
    }
    if (all_normals) mesh.normals = std::move(normals);
    if (!any_uv) mesh.uvs.clear();
    scene.meshes.push_back(std::move(mesh));
  }
  std::sort(left_out.begin(), left_out.end());
  std::string modes;
  for (int m : left_out) modes += (modes.empty() ? "" : ", ") + std::to_string(m);
  return modes.empty() ? "" : (left_out.size() == 1 ? "mode " : "modes ") + modes;
}

// Nodes: one instance per node with a mesh, at its world matrix (every mesh once, untransformed,
// where there are no nodes at all).
std::vector<Instance> node_instances(const Ctx& c, const Scene& scene, uint32_t mesh_base) {
  std::vector<Instance> instances;
  std::vector<int> depth_of(c.model.nodes.size(), -1);
  std::function<void(int, const glm::mat4&, int)> visit = [&](int ni, const glm::mat4& parent, int depth) {
    if (ni < 0 || size_t(ni) >= c.model.nodes.size()) c.fail("node " + std::to_string(ni) + " does not exist");
    if (depth > int(input_limits().max_node_depth))
      c.fail("node " + std::to_string(ni) + ": the node hierarchy is deeper than " +
             std::to_string(input_limits().max_node_depth) + " levels (the limit)");
    if (depth_of[size_t(ni)] >= 0) c.fail("node " + std::to_string(ni) + " is reached twice (a cycle or a shared child)");
    depth_of[size_t(ni)] = depth;
    const tinygltf::Node& node = c.model.nodes[size_t(ni)];
    const glm::mat4 world = parent * local_matrix(c, ni, node);
    if (node.mesh >= 0) {
      if (size_t(node.mesh) >= c.model.meshes.size()) c.fail("node " + std::to_string(ni) + ": mesh " + std::to_string(node.mesh) + " does not exist");
      // Skins and morph targets are not applied: said, not drawn in another pose silently
      if (node.skin >= 0)
        std::cerr << "warning: " << c.path << ": node " << ni << " is skinned (skin " << node.skin
                  << "): drawn as its mesh at the node's transform, not posed by its joints (skins are not supported)\n";
      const tinygltf::Mesh& gm = c.model.meshes[size_t(node.mesh)];
      bool morphs = false;
      for (const auto& p : gm.primitives) morphs = morphs || !p.targets.empty();
      const std::vector<double>& w = node.weights.empty() ? gm.weights : node.weights;
      bool weighted = false;
      for (double x : w) weighted = weighted || x != 0.0;
      if (morphs && weighted)
        std::cerr << "warning: " << c.path << ": node " << ni << ": mesh " << node.mesh
                  << " has morph targets with non-zero weights: drawn without them (morph targets are not supported)\n";
      Instance inst;
      inst.name = node.name.empty() ? "node" + std::to_string(ni) : node.name;
      inst.mesh = mesh_base + uint32_t(node.mesh);
      inst.transform = world;
      instances.push_back(inst);
    }
    for (int child : node.children) visit(child, world, depth + 1);
  };
  std::vector<int> roots;
  // "scene" names the one to show (none: the first); one that does not exist is an error
  if (c.model.defaultScene >= 0 && size_t(c.model.defaultScene) >= c.model.scenes.size())
    c.fail("\"scene\": " + std::to_string(c.model.defaultScene) + " does not exist (the file has " +
           std::to_string(c.model.scenes.size()) + " scene(s))");
  if (!c.model.scenes.empty()) {
    const int s = c.model.defaultScene >= 0 ? c.model.defaultScene : 0;
    roots = c.model.scenes[size_t(s)].nodes;
  } else {
    std::vector<bool> is_child(c.model.nodes.size(), false);
    for (const auto& n : c.model.nodes)
      for (int ch : n.children)
        if (ch >= 0 && size_t(ch) < c.model.nodes.size()) is_child[size_t(ch)] = true;
    for (size_t i = 0; i < c.model.nodes.size(); ++i)
      if (!is_child[i]) roots.push_back(int(i));
  }
  for (int r : roots) visit(r, glm::mat4(1.0f), 0);
  if (instances.empty() && c.model.nodes.empty()) {
    // No nodes at all: every mesh once, untransformed.
    for (size_t mi = 0; mi < c.model.meshes.size(); ++mi)
      instances.push_back(Instance{.name = scene.meshes[mesh_base + mi].name, .mesh = mesh_base + uint32_t(mi)});
  }
  return instances;
}

}  // namespace

std::vector<Instance> load_gltf(const std::string& path, Scene& scene, TextureCache& textures) {
  std::map<int, int> image_alias;
  const tinygltf::Model model = parse_model(path, image_alias);
  const Ctx c{path, model, image_alias};
  const uint32_t material_base = uint32_t(scene.materials.size());
  add_materials(c, scene, textures);
  const uint32_t mesh_base = uint32_t(scene.meshes.size());
  const std::string left_out = add_meshes(c, scene, material_base);
  const std::vector<Instance> instances = node_instances(c, scene, mesh_base);
  uint64_t triangles = 0;
  for (const Instance& inst : instances) triangles += scene.meshes[inst.mesh].triangle_count();
  if (triangles == 0)
    throw Error("glTF '" + path + "' has no triangles: an empty model" +
                (left_out.empty() ? std::string() : " (its primitives of " + left_out + " are points or lines, left out)"));
  return instances;
}

}  // namespace gridrt
