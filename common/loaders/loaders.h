// loaders.h: model files -> meshes, materials and textures appended to a Scene.
//
// Each loader appends what it reads to `scene` (mesh and material indices are offset by what
// the scene already holds) and returns the instances the file describes, with the file's own
// transforms (identity for OBJ, node world matrices for glTF). The caller adds them to
// scene.instances, possibly after composing its own transform. Textures are shared through a
// TextureCache, so a file used by several materials (or meshes) is decoded once.
//
// Errors throw gridrt::Error naming the file, and the line where one is known.
#pragma once

#include <map>
#include <string>
#include <vector>

#include "gridrt/common/image_io.h"
#include "gridrt/common/scene.h"

namespace gridrt {

// Textures of one scene, by key: a file's canonical path, or for a texture made from one (its alpha
// from the first channel, a glTF image, a baked mask) that path, a NUL and how it was made, so
// that no file's name can spell another's key.
class TextureCache {
 public:
  // Index into scene.textures of the file at `path`, loading it on first use.
  int32_t load(Scene& scene, const std::string& path, AlphaSource alpha);
  // Index of the texture stored under `key`, adding `make()` on first use.
  template <class Make>
  int32_t get_or_add(Scene& scene, const std::string& key, Make make) {
    auto it = index_.find(key);
    if (it != index_.end()) return it->second;
    const int32_t i = int32_t(scene.textures.size());
    scene.textures.push_back(make());
    index_.emplace(key, i);
    return i;
  }

 private:
  std::map<std::string, int32_t> index_;
  std::map<std::string, bool> alpha_channel_;  // by key of a file loaded as AlphaSource::kImage
};

// Wavefront OBJ + MTL (tinyobjloader): one mesh for the whole file, polygons triangulated as
// fans, one vertex per distinct (position, texcoord, normal) index triple, one material per MTL
// material (plus a "default" one for faces without usemtl). Reads Kd, map_Kd, map_d (the alpha
// channel of that image, or its first channel when it has none), d / Tr. Glossiness is 0.
//
// What tinyobjloader lets pass and this loader rejects (Error with file and line): numbers that
// do not parse or are not finite on v/vt/vn and MTL colour/scalar lines, face indices out of
// range or 0, a missing mtllib file, usemtl of a material no MTL defines, a texture that does not
// load. Other tinyobjloader warnings go to stderr, prefixed with the file name.
std::vector<Instance> load_obj(const std::string& path, Scene& scene, TextureCache& textures);

// glTF 2.0, .gltf (JSON, buffers embedded or beside it) or .glb (TinyGLTF): one mesh per glTF
// mesh (its triangle primitives merged), one instance per node with a mesh, at the node's world
// matrix, for the nodes of the default scene (or of every root when there is no scene).
// Materials: pbrMetallicRoughness baseColorFactor (rgb -> diffuse, a -> opacity) and
// baseColorTexture; alphaMode MASK makes the base colour texture the alpha mask (a cutoff other
// than 0.5 is baked into a copy of the texture, so that alpha.h's fixed cutoff applies).
// Texture coordinates get v -> 1 - v, so that alpha.h's rule (v = 0 at the last row) holds.
std::vector<Instance> load_gltf(const std::string& path, Scene& scene, TextureCache& textures);

}  // namespace gridrt
