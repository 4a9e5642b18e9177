// scene_io.h: scenes from files: the dispatcher, JSON scene files, bare meshes and the binary
// scene cache. The JSON format is documented in docs/SCENE_FORMAT.md.
#pragma once

#include <string>
#include <string_view>

#include "gridrt/common/scene.h"

namespace gridrt {

// Load any scene the tool accepts, finalized (Scene::finalize):
//   builtin:NAME           make_builtin(NAME)
//   *.json                 a scene file (load_scene_file)
//   *.obj, *.gltf, *.glb   a bare mesh: one static instance, a camera and a light that frame it
//   *.gridscene            the binary cache (load_scene_binary)
// Throws Error for an unknown extension, a missing file or anything wrong inside.
Scene load_scene(std::string_view spec);

// A JSON scene file (docs/SCENE_FORMAT.md). Paths inside are relative to the file; the prefix
// ${GRIDRT_SCENES} expands to real_scenes_dir(). The scene is finalized.
Scene load_scene_file(const std::string& path);

// One model file as a scene: one static instance per model instance, camera and light framing it.
Scene load_model_scene(const std::string& path);

// Where the real third-party scenes live: $GRIDRT_SCENES, else the compile-time default
// (<source dir>/../shared/data/scenes). Not checked for existence.
std::string real_scenes_dir();

// Binary scene cache (.gridscene): a versioned little-endian dump of a finalized scene,
// textures included, loadable without OpenImageIO. save writes atomically (temp file + rename).
// load checks every size before it reads: a corrupt or truncated file is an Error, never a crash.
// The path of the first key given twice in one object of the JSON `text` ("nodes[].translation"),
// empty if none (the parsers keep the last without a word).
std::string json_first_duplicate_key(const std::string& text);

// Version 2 ends with a CRC-32 of every byte before it; version 1 (no checksum) is still read.
inline constexpr uint32_t kSceneBinaryVersion = 2;
void save_scene_binary(const Scene& scene, const std::string& path);
Scene load_scene_binary(const std::string& path);

}  // namespace gridrt
