// Bad input to the loaders, the scene files, image output and the binary cache: each gives an
// Error whose message names the file (and the line where one is known), never a crash.
#include <catch2/catch.hpp>

#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>
#include <vector>

#include <sys/wait.h>

#include <unistd.h>

#include "gridrt/common/image_io.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/scene_io.h"

using namespace gridrt;
using Catch::Contains;
namespace fs = std::filesystem;

namespace {
std::string fixture(const std::string& name) { return std::string(GRIDRT_DATA_DIR) + "/fixtures/" + name; }

fs::path temp_dir() {
  const fs::path d = fs::temp_directory_path() / ("gridrt-badinput-" + std::to_string(::getpid()));
  fs::create_directories(d);
  return d;
}
}  // namespace

TEST_CASE("Missing files and unknown extensions are errors naming the file", "[badinput]") {
  REQUIRE_THROWS_WITH(load_scene(fixture("no_such_file.obj")), Contains("no_such_file.obj") && Contains("no such file"));
  REQUIRE_THROWS_WITH(load_scene(fixture("no_such_file.json")), Contains("no_such_file.json"));
  REQUIRE_THROWS_WITH(load_scene(fixture("no_such_file.glb")), Contains("no_such_file.glb"));
  REQUIRE_THROWS_WITH(load_scene(fixture("no_such_file.gridscene")), Contains("no_such_file.gridscene"));
  REQUIRE_THROWS_WITH(load_scene(fixture("quad.mtl")), Contains("quad.mtl") && Contains("unknown extension"));
  REQUIRE_THROWS_WITH(load_scene("scene.fbx"), Contains("scene.fbx") && Contains("unknown extension"));
}

TEST_CASE("Malformed OBJ files: error with file and line", "[badinput]") {
  CHECK_THROWS_WITH(load_scene(fixture("garbage_number.obj")), Contains("garbage_number.obj:2") && Contains("'zero' is not a number"));
  CHECK_THROWS_WITH(load_scene(fixture("index_out_of_range.obj")),
                    Contains("index_out_of_range.obj:5") && Contains("vertex index 4 out of range"));
  CHECK_THROWS_WITH(load_scene(fixture("nan.obj")), Contains("nan.obj:2") && Contains("non-finite"));
  CHECK_THROWS_WITH(load_scene(fixture("inf.obj")), Contains("inf.obj:3") && Contains("non-finite"));
  CHECK_THROWS_WITH(load_scene(fixture("overflow.obj")), Contains("overflow.obj:3") && Contains("non-finite"));
  CHECK_THROWS_WITH(load_scene(fixture("empty.obj")), Contains("empty.obj") && Contains("empty"));
}

TEST_CASE("Missing or malformed MTL files and unknown materials are errors", "[badinput]") {
  CHECK_THROWS_WITH(load_scene(fixture("missing_mtl.obj")),
                    Contains("missing_mtl.obj:1") && Contains("does_not_exist.mtl") && Contains("not found"));
  CHECK_THROWS_WITH(load_scene(fixture("malformed_mtl.obj")), Contains("malformed.mtl:3") && Contains("'half' is not a number"));
  CHECK_THROWS_WITH(load_scene(fixture("unknown_material.obj")),
                    Contains("unknown_material.obj:5") && Contains("no_such_material"));
}

TEST_CASE("A texture that will not load is an error naming it", "[badinput]") {
  CHECK_THROWS_WITH(load_scene(fixture("missing_texture.obj")), Contains("no_such_texture.png") && Contains("no such file"));
  CHECK_THROWS_WITH(load_scene(fixture("bad_texture.obj")), Contains("not_an_image.png"));
  CHECK_THROWS_WITH(load_texture(fixture("not_an_image.png")), Contains("not_an_image.png"));
}

TEST_CASE("Malformed glTF and GLB files are errors naming the file", "[badinput]") {
  CHECK_THROWS_WITH(load_scene(fixture("bad_json.gltf")), Contains("bad_json.gltf") && Contains("line 1"));
  CHECK_THROWS_WITH(load_scene(fixture("truncated.glb")), Contains("truncated.glb"));
  CHECK_THROWS_WITH(load_scene(fixture("bad_magic.glb")), Contains("bad_magic.glb") && Contains("magic"));
  CHECK_THROWS_WITH(load_scene(fixture("lines.gltf")), Contains("lines.gltf") && Contains("mode 1"));
  CHECK_THROWS_WITH(load_scene(fixture("overrun.gltf")), Contains("overrun.gltf") && Contains("past the end"));
}

TEST_CASE("Malformed JSON scene files: syntax error with line, unknown key, wrong type", "[badinput]") {
  CHECK_THROWS_WITH(load_scene(fixture("bad_syntax.json")), Contains("bad_syntax.json:7:") && Contains("syntax error"));
  CHECK_THROWS_WITH(load_scene(fixture("unknown_key.json")), Contains("unknown_key.json") && Contains("\"translte\""));
  CHECK_THROWS_WITH(load_scene(fixture("wrong_type.json")),
                    Contains("wrong_type.json") && Contains("instances[0].translate[1]") && Contains("expected a number"));
  CHECK_THROWS_WITH(load_scene(fixture("missing_mesh_file.json")),
                    Contains("missing_mesh_file.json") && Contains("no_such_model.obj"));
}

TEST_CASE("Image output: zero size, size mismatch and unknown extensions are errors", "[badinput]") {
  const fs::path dir = temp_dir();
  const std::string png = (dir / "zero.png").string();
  CHECK_THROWS_WITH(write_image(png, 0, 4, {}), Contains("zero.png") && Contains("zero size"));
  CHECK_THROWS_WITH(write_image((dir / "short.ppm").string(), 2, 2, std::vector<glm::vec3>(3)),
                    Contains("short.ppm") && Contains("3 pixels"));
  CHECK_THROWS_WITH(write_image((dir / "x.nosuchformat").string(), 1, 1, std::vector<glm::vec3>(1)),
                    Contains("x.nosuchformat"));
  CHECK_FALSE(fs::exists(png));
  // Nothing half-written is left behind.
  for (const auto& e : fs::directory_iterator(dir)) FAIL("left behind: " << e.path());
  fs::remove_all(dir);
}

TEST_CASE("A corrupt or truncated .gridscene is an error, never a crash", "[badinput]") {
  if (!have_image_library()) {
    WARN("skipped: this build has no OpenImageIO, so no textures");
    return;
  }
  const fs::path dir = temp_dir();
  const std::string good = (dir / "good.gridscene").string();
  save_scene_binary(load_scene(fixture("scene_small.json")), good);
  std::string bytes;
  {
    std::ifstream f(good, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(f), {});
  }
  REQUIRE(bytes.size() > 100);
  auto write = [&](const std::string& name, const std::string& data) {
    const std::string p = (dir / name).string();
    std::ofstream(p, std::ios::binary).write(data.data(), std::streamsize(data.size()));
    return p;
  };
  CHECK_THROWS_WITH(load_scene(write("empty.gridscene", "")), Contains("empty.gridscene") && Contains("truncated"));
  CHECK_THROWS_WITH(load_scene(write("magic.gridscene", "NOTASCENE" + bytes.substr(9))), Contains("magic.gridscene") && Contains("magic"));
  // Every truncation point is caught.
  for (size_t n = 0; n < bytes.size(); n += std::max<size_t>(1, bytes.size() / 97))
    CHECK_THROWS_WITH(load_scene_binary(write("cut.gridscene", bytes.substr(0, n))), Contains("cut.gridscene"));
  // Every flipped byte is refused: the version, or the checksum of the rest (over half of the
  // flips loaded another scene without a word before it: an outside sweep)
  for (size_t i = 8; i < bytes.size(); i += 7) {
    std::string b = bytes;
    b[i] = char(b[i] ^ 0xA5);
    INFO("byte " << i << " of " << bytes.size());
    CHECK_THROWS_WITH(load_scene_binary(write("flip.gridscene", b)),
                      Contains("flip.gridscene") && (i < 12 ? Contains("version") : Contains("checksum mismatch")));
  }
  CHECK_THROWS_WITH(load_scene(write("trailing.gridscene", bytes + "x")), Contains("checksum mismatch"));
  // A version 1 cache (no checksum) is still read: the same scene without its last four bytes
  {
    std::string v1 = bytes.substr(0, bytes.size() - 4);
    v1[8] = 1;
    const Scene a = load_scene_binary(write("v1.gridscene", v1));
    const Scene b = load_scene_binary(good);
    CHECK(a.triangle_count() == b.triangle_count());
    CHECK_THROWS_WITH(load_scene(write("v1trailing.gridscene", v1 + "x")), Contains("after the end marker"));
  }
  fs::remove_all(dir);
}

// Inputs an outside sweep found accepted or misreported (tests/corpus has the files too, for the
// replay's clean-error check): each refused with a message that names the real problem.
TEST_CASE("glTF: a missing default scene, a rotation that is no unit quaternion, a model past the domain", "[badinput]") {
  const std::string corpus = std::string(GRIDRT_DATA_DIR) + "/../tests/corpus/";
  CHECK_THROWS_WITH(load_scene(corpus + "gltf/bad_scene_out_of_range.gltf"),
                    Contains("\"scene\": 7 does not exist") && Contains("1 scene(s)"));
  CHECK_THROWS_WITH(load_scene(corpus + "gltf/bad_rotation_not_unit.gltf"),
                    Contains("node 0") && Contains("not a unit quaternion") && Contains("length 10"));
  CHECK_THROWS_WITH(load_scene(corpus + "gltf/bad_translation_1e38.gltf"), Contains("beyond the ray domain's 2^24"));
  // Within 1e-3 of unit length: normalized, so the model keeps its size (a quarter turn about z)
  const Scene nearly = load_scene(corpus + "gltf/ok_rotation_nearly_unit.gltf");
  const Bounds b = nearly.bounds(0.0f);
  CHECK(b.lo.x == Approx(-1.0f).margin(1e-4));
  CHECK(b.hi.y == Approx(1.0f).margin(1e-4));
  CHECK(b.extent().x == Approx(1.0f).margin(1e-4));
}

TEST_CASE("A JSON scene file with a NUL byte is refused where the byte is", "[badinput]") {
  const std::string corpus = std::string(GRIDRT_DATA_DIR) + "/../tests/corpus/";
  CHECK_THROWS_WITH(load_scene(corpus + "json/bad_nul_then_garbage.json"),
                    Contains("bad_nul_then_garbage.json:1:") && Contains("NUL byte"));
}

TEST_CASE("A JSON scene file with a key given twice in one object is refused, naming its path", "[badinput]") {
  // An outside tester's find: two meshes of one name, a second "translate", a second "rotate"
  // pasted into a motion all loaded, the last one winning without a word
  const fs::path dir = fs::temp_directory_path() / "gridrt_duplicate_keys";
  fs::create_directories(dir);
  std::ofstream(dir / "tri.obj") << "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n";
  const std::string head = R"({"meshes": {"a": {"file": "tri.obj"})";
  const std::pair<std::string, std::string> cases[] = {
      {head + R"(, "a": {"file": "tri.obj"}}, "instances": [{"mesh": "a"}]})", "meshes.a"},
      {head + R"(}, "instances": [{"mesh": "a", "translate": [1, 0, 0], "translate": [2, 0, 0]}]})", "instances[].translate"},
      {head + R"(}, "instances": [{"mesh": "a", "motion": {"rotate": {"axis": [0, 1, 0], "speed": 1}, )"
                  R"("rotate": {"axis": [1, 0, 0], "speed": 2}}}]})",
       "instances[].motion.rotate"},
  };
  for (const auto& [text, where] : cases) {
    INFO(text);
    std::ofstream(dir / "scene.json") << text;
    CHECK_THROWS_WITH(load_scene((dir / "scene.json").string()), Contains(where) && Contains("given twice"));
  }
  // The same keys in different objects are fine
  std::ofstream(dir / "scene.json") << head + R"(, "b": {"file": "tri.obj"}}, "instances": [{"mesh": "a", "translate": [1, 0, 0]}, )"
                                              R"({"mesh": "b", "translate": [2, 0, 0]}]})";
  CHECK(load_scene((dir / "scene.json").string()).instances.size() == 2);
  fs::remove_all(dir);
}

// An outside sweep's find: SIGINT or SIGTERM while an output was written left its temporary file
// (".o.pfm.tmp15377.pfm", 8 MB) beside the untouched old output. The temporary file is now removed
// by the signal's handler, which then lets the signal end the process as it would have.
TEST_CASE("An output's temporary file is removed when SIGTERM ends the process while it is written", "[badinput]") {
  const fs::path dir = fs::temp_directory_path() / ("gridrt_signal_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path out = dir / "o.pfm";
  std::ofstream(out) << "OLD";
  const pid_t child = ::fork();
  REQUIRE(child >= 0);
  if (child == 0) {
    ::signal(SIGTERM, SIG_DFL);  // as the tool has it (the test runner handles the signal itself)
    try {
      write_file_atomically(out.string(), "image", [](const std::string& tmp) {
        std::ofstream(tmp) << "partial";
        ::raise(SIGTERM);  // as a user's kill would arrive, halfway through the write
      });
    } catch (...) {
    }
    ::_exit(0);  // not reached: the signal ends the child
  }
  int status = 0;
  REQUIRE(::waitpid(child, &status, 0) == child);
  CHECK(WIFSIGNALED(status));
  CHECK(WTERMSIG(status) == SIGTERM);
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
  CHECK(names == std::vector<std::string>{"o.pfm"});
  std::ifstream in(out);
  std::string text;
  in >> text;
  CHECK(text == "OLD");
  fs::remove_all(dir);
}

// An outside sweep's find: OpenEXR's and TIFF's writers stamped the time of writing, so one
// render gave other bytes a second later (CI could not compare outputs).
TEST_CASE("EXR and TIFF outputs are the same bytes when written twice", "[badinput][image]") {
  if (!have_image_library()) {
    WARN("built without OpenImageIO: no EXR or TIFF to write");
    return;
  }
  const fs::path dir = fs::temp_directory_path() / ("gridrt_stamp_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::vector<glm::vec3> rgb(4 * 3, glm::vec3(0.25f, 0.5f, 0.75f));
  for (const char* ext : {".exr", ".tif"}) {
    write_image((dir / (std::string("a") + ext)).string(), 4, 3, rgb);
    std::this_thread::sleep_for(std::chrono::milliseconds(1100));  // past the stamp's second
    write_image((dir / (std::string("b") + ext)).string(), 4, 3, rgb);
    auto bytes = [](const fs::path& p) {
      std::ifstream in(p, std::ios::binary);
      return std::string(std::istreambuf_iterator<char>(in), {});
    };
    INFO(ext);
    CHECK(bytes(dir / (std::string("a") + ext)) == bytes(dir / (std::string("b") + ext)));
  }
  fs::remove_all(dir);
}
