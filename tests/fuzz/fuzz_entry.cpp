#include "tests/fuzz/fuzz_entry.h"

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string_view>

#include <unistd.h>

#include "gridrt/common/scene_io.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/reference/portal/instance.h"
#include "gridrt/reference/portal/world.h"

namespace gridrt::fuzz {
namespace fs = std::filesystem;

bool kind_of(const std::string& path, Kind& kind) {
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".obj") kind = Kind::obj;
  else if (ext == ".gltf") kind = Kind::gltf;
  else if (ext == ".glb") kind = Kind::glb;
  else if (ext == ".json") kind = Kind::json;
  else if (ext == ".gridscene") kind = Kind::gridscene;
  else if (ext == ".map") kind = Kind::map;
  else return false;
  return true;
}

const char* extension(Kind kind) {
  switch (kind) {
    case Kind::obj: return ".obj";
    case Kind::gltf: return ".gltf";
    case Kind::glb: return ".glb";
    case Kind::json: return ".json";
    case Kind::gridscene: return ".gridscene";
    case Kind::map: return ".map";
  }
  return "";
}

void load_input(const std::string& path, Kind kind, const std::string& scratch) {
  if (kind == Kind::map) {
    // A block map (first keyword `scale`) or a tile map, as the tool reads them.
    const std::string text = normalize_text(read_input_file(path, "tile map"));
    if (portal::is_block_map(text)) portal::parse_block_map(text, path, false);
    else portal::load_tile_map(path, false);
    return;
  }
  const Scene scene = load_scene(path);
  // convert's round trip: what was accepted is written and must load again.
  const std::string cache = scratch + "/roundtrip.gridscene";
  save_scene_binary(scene, cache);
  try {
    load_scene_binary(cache);
  } catch (const Error& e) {
    std::fprintf(stderr, "round trip: the cache of '%s' does not load back: %s\n", path.c_str(), e.what());
    std::abort();
  }
}

// The process's scratch folder, removed when it exits normally.
struct ScratchDir {
  std::string path;
  ScratchDir() {
    const fs::path d = fs::temp_directory_path() / ("gridrt-fuzz-" + std::to_string(::getpid()));
    fs::create_directories(d);
    path = d.string();
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
};

int fuzz_one(Kind kind, const uint8_t* data, size_t size) {
  static const ScratchDir scratch_dir;
  const std::string& scratch = scratch_dir.path;
  std::string_view text(reinterpret_cast<const char*>(data), size);
  std::string_view mtl;
  if (kind == Kind::obj) {
    const size_t at = text.find("\n@@MTL@@\n");
    if (at != std::string_view::npos) {
      mtl = text.substr(at + 9);
      text = text.substr(0, at + 1);
    }
  }
  const std::string path = scratch + "/input" + extension(kind);
  {
    std::ofstream f(path, std::ios::binary | std::ios::trunc);
    f.write(text.data(), std::streamsize(text.size()));
  }
  {
    std::ofstream f(scratch + "/input.mtl", std::ios::binary | std::ios::trunc);
    f.write(mtl.data(), std::streamsize(mtl.size()));
  }
  try {
    load_input(path, kind, scratch);
  } catch (const Error&) {
    // a clean error: what bad input must give
  }
  // Anything else (std::bad_alloc, std::length_error, ...) propagates: libFuzzer reports it.
  return 0;
}

}  // namespace gridrt::fuzz
