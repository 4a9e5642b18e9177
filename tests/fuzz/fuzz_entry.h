// fuzz_entry.h: the one entry point through which the fuzz targets and the corpus replay feed a
// file to the readers, as the tool does (load_scene for scenes and models, load_tile_map for
// tile maps). A scene that loads is also written as a .gridscene cache and loaded back: `convert`
// must never write what `render` then rejects.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>

namespace gridrt::fuzz {

enum class Kind { obj, gltf, glb, json, gridscene, map };

// The kind of a file by its extension; false for an extension no reader takes.
bool kind_of(const std::string& path, Kind& kind);
const char* extension(Kind kind);  // ".obj", ...

// Loads `path`. Returns normally when it loaded (and round-tripped); throws gridrt::Error for
// bad input; anything else escaping (another exception, a crash, a sanitizer report) is a bug.
// `scratch` is a folder for the round-trip cache.
void load_input(const std::string& path, Kind kind, const std::string& scratch);

// For libFuzzer: writes `data` to a file of the kind in a private scratch folder and loads it.
// An OBJ input may carry an MTL library after a line "@@MTL@@" (written beside it as
// input.mtl). Returns 0; aborts on anything but success or gridrt::Error.
int fuzz_one(Kind kind, const uint8_t* data, size_t size);

}  // namespace gridrt::fuzz
