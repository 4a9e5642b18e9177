// obj.cpp: Wavefront OBJ + MTL through tinyobjloader, with the checks it does not make.
#include <algorithm>
#include <array>
#include <charconv>
#include <cctype>
#include <cstdlib>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <set>
#include <sstream>
#include <string_view>
#include <tuple>
#include <unordered_map>

#include <tiny_obj_loader.h>

#include "gridrt/common/loaders/loaders.h"
#include "gridrt/common/safe_io.h"

namespace gridrt {
namespace fs = std::filesystem;

int32_t TextureCache::load(Scene& scene, const std::string& path, AlphaSource alpha) {
  std::error_code ec;
  fs::path canon = fs::weakly_canonical(path, ec);
  if (ec) canon = path;
  // A file with an alpha channel gives the same texture for both alpha sources: store it once,
  // under the plain key.
  const std::string plain = canon.string();
  // (A NUL in the derived key, which no file name holds: a texture file named
  // "t.png#alpha-from-first-channel" took t.png's alpha copy, an outside sweep)
  const std::string first = plain + std::string(1, '\0') + "alpha-from-first-channel";
  if (auto it = index_.find(plain); it != index_.end() && (alpha == AlphaSource::kImage || alpha_channel_[plain]))
    return it->second;
  if (auto it = index_.find(first); it != index_.end() && alpha == AlphaSource::kFirstChannel) return it->second;
  bool has_alpha_channel = false;
  Texture tex = load_texture(path, alpha, &has_alpha_channel);
  const std::string key = alpha == AlphaSource::kImage || has_alpha_channel ? plain : first;
  if (key == plain) alpha_channel_[plain] = has_alpha_channel;
  return get_or_add(scene, key, [&] { return std::move(tex); });
}

namespace {

// The file's text with the one line-break rule applied (safe_io.h: CR, LF and CR LF end a line;
// a UTF-8 byte-order mark is dropped). The checks below and tinyobjloader both read this text,
// so they see the same lines.
std::string read_file(const std::string& path, const std::string& what) {
  return normalize_text(read_input_file(path, what));
}

std::vector<std::string_view> split_ws(std::string_view line) {
  std::vector<std::string_view> out;
  size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    size_t j = i;
    while (j < line.size() && line[j] != ' ' && line[j] != '\t') ++j;
    if (j > i) out.push_back(line.substr(i, j - i));
    i = j;
  }
  return out;
}

// Calls fn(line_number, tokens) for every non-empty, non-comment line.
template <class Fn>
void for_each_line(const std::string& text, Fn fn) {
  size_t pos = 0;
  size_t number = 0;
  while (pos < text.size()) {
    size_t end = text.find('\n', pos);
    if (end == std::string::npos) end = text.size();
    std::string_view line(text.data() + pos, end - pos);
    ++number;
    pos = end + 1;
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    const size_t hash = line.find('#');
    if (hash != std::string_view::npos) line = line.substr(0, hash);
    auto tokens = split_ws(line);
    if (!tokens.empty()) fn(number, tokens);
  }
}

// A material's name in a newmtl or usemtl statement: the rest of the line after the keyword (its
// first token `first`, a view into `text`), blanks at its ends dropped, blanks and '#' inside
// kept ("wire 008", "Material #25": 3ds Max and SketchUp write such names). tinyobjloader took
// newmtl's whole rest but only usemtl's first word, so such a name could not be used, or a
// material named by its first word was taken without a word (an outside sweep).
std::string material_name_rest(const std::string& text, std::string_view first) {
  const size_t begin = size_t(first.data() - text.data());
  size_t end = text.find('\n', begin);
  if (end == std::string::npos) end = text.size();
  std::string_view rest(text.data() + begin, end - begin);
  while (!rest.empty() && std::isspace(static_cast<unsigned char>(rest.back()))) rest.remove_suffix(1);
  return std::string(rest);
}

// A name as handed to tinyobjloader, whose usemtl reads one word: its blanks as control
// characters no name holds after the checks (a tab as 0x1E, any other blank as 0x1F), and back.
std::string name_for_tinyobj(std::string name) {
  for (char& c : name)
    if (c == '\t') c = '\x1e';
    else if (std::isspace(static_cast<unsigned char>(c))) c = '\x1f';
  return name;
}
std::string name_from_tinyobj(std::string name) {
  for (char& c : name)
    if (c == '\x1e') c = '\t';
    else if (c == '\x1f') c = ' ';
  return name;
}

// A number that overflows a double parses as +-inf (and is then rejected as non-finite); one
// that underflows as 0 or a denormal.
bool parse_float(std::string_view s, double& out) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  out = 0.0;
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  if (p != s.data() + s.size()) return false;
  if (ec == std::errc::result_out_of_range) {
    out = std::strtod(std::string(s).c_str(), nullptr);  // +-HUGE_VAL or a tiny value
    return true;
  }
  return ec == std::errc();
}

bool parse_int(std::string_view s, long& out) {
  if (!s.empty() && s[0] == '+') s.remove_prefix(1);
  auto [p, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && p == s.data() + s.size();
}

[[noreturn]] void fail_at(const std::string& path, size_t line, const std::string& what) {
  throw Error(path + ":" + std::to_string(line) + ": " + what);
}

// Every token after the keyword must be a finite number (but d's one option, -halo); at least
// `min_numbers` of them. Every other word was skipped as an option where it began with '-' and a
// letter, so "-NaN" and "-Inf" passed, and tinyobjloader read them as 0 (an outside sweep).
void check_numbers(const std::string& path, size_t line, const std::vector<std::string_view>& tok,
                   size_t min_numbers) {
  size_t numbers = 0;
  for (size_t i = 1; i < tok.size(); ++i) {
    if (tok[0] == "d" && tok[i] == "-halo") continue;
    double v;
    if (!parse_float(tok[i], v))
      fail_at(path, line, "'" + std::string(tok[0]) + "': '" + std::string(tok[i]) + "' is not a number");
    if (!std::isfinite(v))
      fail_at(path, line, "'" + std::string(tok[0]) + "': non-finite value '" + std::string(tok[i]) + "'");
    // The loader keeps floats: a value past a float's range would become inf there, and be
    // refused later without its line (vt 1e39)
    if (!std::isfinite(static_cast<float>(v)))
      fail_at(path, line, "'" + std::string(tok[0]) + "': value '" + std::string(tok[i]) +
                              "' is beyond a float's range (about 3.4e38)");
    ++numbers;
  }
  if (numbers < min_numbers)
    fail_at(path, line, "'" + std::string(tok[0]) + "' needs " + std::to_string(min_numbers) +
                            (min_numbers == 1 ? " number" : " numbers") + ", has " + std::to_string(numbers));
}

// What the pre-scan of an OBJ file learns.
struct ObjScan {
  std::vector<std::pair<std::string, size_t>> mtllibs;  // file name, line
  std::vector<std::pair<std::string, size_t>> usemtls;  // material name, first line
  // Each face's corners in file order: tinyobjloader keeps a face's count in a byte (a face of
  // 1,024 corners read as 0), so the mesh takes them from here
  std::vector<uint32_t> face_corners;
  // Free-form geometry (cstype, curv, curv2, surf and their parameter statements), which this
  // loader does not evaluate: the first such line, and the curves and surfaces
  size_t free_form_line = 0;
  size_t free_form = 0;
};

// tinyobjloader reads a malformed number as 0 and only warns about out-of-range indices (with
// the number of the last line); this pass finds such lines first.
ObjScan scan_obj(const std::string& path, const std::string& text) {
  // A NUL byte: not a text file (UTF-16 saved, or binary), which read as an empty model
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    fail_at(path, size_t(std::count(text.begin(), text.begin() + std::ptrdiff_t(nul), '\n')) + 1,
            "a NUL byte: an OBJ is a text file (UTF-8 or ASCII; UTF-16 is not read)");
  ObjScan scan;
  std::set<std::string> used;
  long counts[3] = {0, 0, 0};                     // v, vt, vn so far
  uint64_t triangles = 0;                         // the faces' triangles so far
  long max_index[3] = {0, 0, 0};                  // largest positive index used
  size_t max_line[3] = {0, 0, 0};                 // where
  static const char* kinds[3] = {"vertex", "texture coordinate", "normal"};
  for_each_line(text, [&](size_t line, const std::vector<std::string_view>& tok) {
    const std::string_view k = tok[0];
    if (k == "v") { check_numbers(path, line, tok, 3); ++counts[0]; }
    else if (k == "vt") { check_numbers(path, line, tok, 1); ++counts[1]; }
    else if (k == "vn") { check_numbers(path, line, tok, 3); ++counts[2]; }
    else if (k == "f") {
      if (tok.size() < 4) fail_at(path, line, "face with fewer than 3 vertices");
      scan.face_corners.push_back(uint32_t(tok.size() - 1));
      // Its triangles counted against the limit as they are read (a file of 2,000,000 triangles
      // was parsed whole before --max-triangles 1000 refused it)
      triangles += tok.size() - 3;
      if (triangles > input_limits().max_triangles)
        fail_at(path, line, "the faces so far make more than the limit of " +
                                std::to_string(input_limits().max_triangles) + " triangles (--max-triangles)");
      if (tok.size() - 1 > input_limits().max_face_vertices)
        fail_at(path, line, "face with " + std::to_string(tok.size() - 1) + " vertices, more than the limit of " +
                                std::to_string(input_limits().max_face_vertices));
      for (size_t i = 1; i < tok.size(); ++i) {
        std::string_view t = tok[i];
        // A corner is v, v/vt, v//vn or v/vt/vn: an empty index elsewhere ("1/", "1/2/", "/2") or a
        // fourth one was told as "zero value for face index" (an outside sweep)
        const size_t slashes = size_t(std::count(t.begin(), t.end(), '/'));
        if (slashes > 2 || t.front() == '/' || t.back() == '/')
          fail_at(path, line, "face: corner '" + std::string(tok[i]) +
                                  "' is none of v, v/vt, v//vn, v/vt/vn (an index left empty, or more than three)");
        for (int slot = 0; slot < 3 && !t.empty(); ++slot) {
          const size_t slash = t.find('/');
          const std::string_view part = t.substr(0, slash);
          t = slash == std::string_view::npos ? std::string_view() : t.substr(slash + 1);
          if (part.empty() && slot > 0) continue;  // "v//vn"
          long idx;
          if (!parse_int(part, idx) || idx == 0)
            fail_at(path, line, "face: '" + std::string(tok[i]) + "' is not a valid index (1-based, or negative)");
          if (idx < 0 && -idx > counts[slot])
            fail_at(path, line, "face: relative " + std::string(kinds[slot]) + " index " + std::to_string(idx) +
                                    " reaches before the first of " + std::to_string(counts[slot]));
          if (idx > max_index[slot]) { max_index[slot] = idx; max_line[slot] = line; }
        }
      }
    } else if (k == "curv" || k == "curv2" || k == "surf" || k == "cstype") {
      if (scan.free_form_line == 0) scan.free_form_line = line;
      scan.free_form += k == "cstype" ? 0u : 1u;
    } else if (k == "mtllib") {
      if (tok.size() < 2) fail_at(path, line, "mtllib without a file name");
      for (size_t i = 1; i < tok.size(); ++i) scan.mtllibs.emplace_back(std::string(tok[i]), line);
    } else if (k == "usemtl") {
      if (tok.size() < 2) fail_at(path, line, "usemtl without a material name");
      std::string name = material_name_rest(text, tok[1]);
      if (used.insert(name).second) scan.usemtls.emplace_back(name, line);
    }
  });
  // Free-form curves and surfaces were dropped without a word (an outside sweep): said, as the
  // polygons are all that is drawn
  if (scan.free_form_line != 0)
    std::cerr << "warning: " << path << ":" << scan.free_form_line << ": free-form geometry (" << scan.free_form
              << " curve(s) and surface(s), cstype/curv/surf) is not read: only the polygon faces (f) are drawn\n";
  for (int s = 0; s < 3; ++s)
    if (max_index[s] > counts[s])
      fail_at(path, max_line[s], "face: " + std::string(kinds[s]) + " index " + std::to_string(max_index[s]) +
                                     " out of range (the file has " + std::to_string(counts[s]) + ")");
  return scan;
}

// A texture statement's options as tinyobjloader reads them: -o, -s and -t always take three
// numbers and -mm two, where the MTL format lets the later ones be left out (-s u [v [w]]). So
// "map_Kd -s 2 2 t.png" lost its file name to the third number, and the texture was dropped
// without a word. Such a line is written out with the defaults the format gives (-o and -t: 0,
// -s: 1, -mm's gain: 1). A colour statement (Kd, Ka, Ks, Ke, Tf) with one number is written
// with it three times, as the format says (tinyobjloader read "Kd 0.5" as (0.5, 0, 0): grey drawn
// red, found by an outside sweep). Every other line is kept as it is.
std::string pad_texture_options(const std::string& path, const std::string& text) {
  std::string out;
  out.reserve(text.size());
  size_t pos = 0;
  size_t number = 0;
  while (pos < text.size()) {
    ++number;
    size_t end = text.find('\n', pos);
    const bool last = end == std::string::npos;
    if (last) end = text.size();
    const std::string_view line(text.data() + pos, end - pos);
    pos = end + 1;
    std::string_view body = line;
    const size_t hash = body.find('#');
    if (hash != std::string_view::npos) body = body.substr(0, hash);
    const std::vector<std::string_view> tok = split_ws(body);
    bool texture = !tok.empty() && (tok[0].substr(0, 4) == "map_" || tok[0] == "bump" || tok[0] == "disp" ||
                                    tok[0] == "decal" || tok[0] == "refl");
    std::string rewritten;
    bool padded = false;
    // A colour with one number: the MTL format's g and b default to r (tinyobjloader reads 0)
    const bool colour = tok.size() == 2 && (tok[0] == "Kd" || tok[0] == "Ka" || tok[0] == "Ks" || tok[0] == "Ke" ||
                                            tok[0] == "Tf");
    if (colour) {
      rewritten = std::string(tok[0]) + " " + std::string(tok[1]) + " " + std::string(tok[1]) + " " + std::string(tok[1]);
      padded = true;
    }
    for (size_t i = 0; texture && i < tok.size(); ++i) {
      rewritten += (i ? " " : "") + std::string(tok[i]);
      const std::string_view o = tok[i];
      const size_t want = (o == "-o" || o == "-s" || o == "-t") ? 3 : o == "-mm" ? 2 : 0;
      if (i == 0 || want == 0) continue;
      // Numbers up to `want`, never the last token (the file name)
      size_t have = 0;
      double v;
      while (have < want && i + 2 < tok.size() && parse_float(tok[i + 1], v)) {
        rewritten += " " + std::string(tok[++i]);
        ++have;
      }
      if (have == 0)
        fail_at(path, number, std::string(tok[0]) + ": option '" + std::string(o) + "' without a number");
      for (; have < want; ++have, padded = true) rewritten += (o == "-s" || o == "-mm") ? " 1" : " 0";
    }
    // newmtl: tinyobjloader keeps the blanks after the keyword in the name ("newmtl  leaf" defined
    // " leaf", an outside sweep): written without them. The rest of the line is kept, a '#' too,
    // as tinyobjloader reads it (a name "mat#2" cut at its '#' lost its material without a word;
    // whole, its usemtl is refused below as before). A texture statement keeps its line as well:
    // a file name may hold a '#'.
    const bool newmtl = !padded && !tok.empty() && tok[0] == "newmtl" && tok.size() > 1;
    if (newmtl) {
      std::string_view rest = line.substr(size_t(tok[0].data() + tok[0].size() - line.data()));
      while (!rest.empty() && std::isspace(static_cast<unsigned char>(rest.front()))) rest.remove_prefix(1);
      while (!rest.empty() && std::isspace(static_cast<unsigned char>(rest.back()))) rest.remove_suffix(1);
      rewritten = std::string(tok[0]) + " " + name_for_tinyobj(std::string(rest));  // one word, as usemtl's
      padded = true;
    }
    if (padded) {
      out += rewritten;
      if (hash != std::string_view::npos && !newmtl) out += " " + std::string(line.substr(hash));
    } else {
      out += line;
    }
    if (!last) out += '\n';
  }
  return out;
}

// MTL lines tinyobjloader reads leniently: scalar and colour statements must hold numbers,
// texture statements a file name.
std::string scan_mtl(const std::string& path) {
  std::string text = read_file(path, "material library");
  // A NUL byte, as in an OBJ: a map_Kd's name was cut there and the file before it opened (an
  // outside sweep)
  if (const size_t nul = text.find('\0'); nul != std::string::npos)
    fail_at(path, size_t(std::count(text.begin(), text.begin() + std::ptrdiff_t(nul), '\n')) + 1,
            "a NUL byte: a material library is a text file (UTF-8 or ASCII; UTF-16 is not read)");
  for_each_line(text, [&](size_t line, const std::vector<std::string_view>& tok) {
    const std::string_view k = tok[0];
    if (k == "Kd" || k == "Ka" || k == "Ks" || k == "Ke" || k == "Tf") {
      // tinyobjloader reads "xyz" and "spectral" as the number 0: another colour, or black
      if (tok.size() > 1 && (tok[1] == "spectral" || tok[1] == "xyz"))
        fail_at(path, line, "'" + std::string(k) + " " + std::string(tok[1]) +
                                "': CIE XYZ and spectral colours are not read; give r g b");
      check_numbers(path, line, tok, 1);
      // One number (grey) or r g b: two were read as (r, g, 0) and a fourth dropped, without a word
      // (an outside sweep)
      if (tok.size() != 2 && tok.size() != 4)
        fail_at(path, line, "'" + std::string(k) + "' takes one number (grey) or three (r g b), has " +
                                std::to_string(tok.size() - 1));
    } else if (k == "Ns" || k == "Ni" || k == "d" || k == "Tr" || k == "illum") {
      check_numbers(path, line, tok, 1);
    } else if (k == "map_Kd" || k == "map_d") {
      if (tok.size() < 2) fail_at(path, line, std::string(k) + " without a file name");
      // Options and their values with nothing after them: no file name (map_Kd -clamp on dropped
      // its texture without a word, map_Kd -o 1 was told of a missing number: an outside sweep)
      size_t i = 1;
      double v;
      while (i < tok.size()) {
        const std::string_view o = tok[i];
        const bool word = o == "-blendu" || o == "-blendv" || o == "-boost" || o == "-texres" || o == "-clamp" ||
                          o == "-bm" || o == "-imfchan" || o == "-type" || o == "-colorspace" || o == "-cc";
        const size_t numbers = (o == "-o" || o == "-s" || o == "-t") ? 3 : o == "-mm" ? 2 : 0;
        if (word) {
          i += 2;
        } else if (numbers) {
          ++i;
          for (size_t n = 0; n < numbers && i < tok.size() && parse_float(tok[i], v); ++n) ++i;
        } else {
          break;
        }
      }
      if (i >= tok.size()) fail_at(path, line, std::string(k) + ": no file name after its options");
    }
  });
  return pad_texture_options(path, text);
}

std::string texture_path(const fs::path& dir, std::string name) {
  for (char& c : name)
    if (c == '\\') c = '/';
  return (dir / name).string();
}

// A material's texture named by a relative path: beside the library that defines the material
// (as a relative path in any file means), else beside the OBJ (where exporters that write both
// into one folder, and tinyobjloader, look), else the library's path, for the error to name. An
// MTL in a subfolder with its textures beside it drew the OBJ folder's file of the same name, or
// failed to find one (an outside sweep).
std::string material_texture_path(const fs::path& library_dir, const fs::path& obj_dir, const std::string& name) {
  const std::string beside_library = texture_path(library_dir, name);
  if (why_missing(beside_library).empty() || library_dir == obj_dir) return beside_library;
  const std::string beside_obj = texture_path(obj_dir, name);
  return why_missing(beside_obj).empty() ? beside_obj : beside_library;
}

// ---- Polygons to triangles ----
// tinyobjloader's own triangulation of faces of five or more vertices lost triangles without a
// word, depending on where the face lay (its ear test's sign came from the position, not the
// orientation: an L-shaped hexagon at one place gave its 4 triangles, moved by (-5, 5, 0) one; an
// outside sweep), and its quads took the shorter diagonal even where it runs outside a concave
// quad. So the loader triangulates itself: every face of n vertices gives n - 2 triangles.

// Twice the signed area of (a, b, c) in the face's plane.
double orient2(const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
}

// Whether p lies in the closed triangle (a, b, c) of positive orientation.
bool in_triangle(const glm::dvec2& p, const glm::dvec2& a, const glm::dvec2& b, const glm::dvec2& c) {
  return orient2(a, b, p) >= 0.0 && orient2(b, c, p) >= 0.0 && orient2(c, a, p) >= 0.0;
}

// Ear clipping's work grows with the cube of a face's corners at worst (a star of many reflex
// corners): a file's faces share this budget of corner tests (seconds at most), and past it faces
// are split as fans, with a warning, so that no file makes the load hang.
constexpr uint64_t kEarClipBudget = uint64_t(1) << 30;

// The triangles of a face with corners `p` (n >= 3), as indices into `p`: n - 2 of them, each
// in the face's winding. The face is projected on the plane of its Newell normal's largest axis
// (its winding kept); a quad takes its shorter diagonal where both its triangles keep that winding,
// else the other; larger faces are ear-clipped (an ear: a convex corner whose triangle holds no
// other corner). A face with no ear left (self-intersecting, or not planar enough to project
// simply) gives the triangle at the corner the search started from and goes on, so no part is
// dropped (its cover is then not exact: such a face has none). `budget`: the
// corner tests left (kEarClipBudget); `fan` set when it ran out and the rest was split as a fan.
std::vector<glm::uvec3> triangulate_face(const std::vector<glm::dvec3>& p, uint64_t& budget, bool& fan) {
  const size_t n = p.size();
  std::vector<glm::uvec3> out;
  out.reserve(n - 2);
  if (n == 3) {
    out.emplace_back(0, 1, 2);
    return out;
  }
  glm::dvec3 normal(0.0);
  for (size_t k = 0; k < n; ++k) {
    const glm::dvec3& a = p[k];
    const glm::dvec3& b = p[(k + 1) % n];
    normal += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x), (a.x - b.x) * (a.y + b.y));
  }
  const glm::dvec3 an = glm::abs(normal);
  const int axis = an.x >= an.y && an.x >= an.z ? 0 : an.y >= an.z ? 1 : 2;
  // The two other axes, in the order that keeps the face's winding counter-clockwise in 2D
  int u = (axis + 1) % 3, v = (axis + 2) % 3;
  if (normal[axis] < 0.0) std::swap(u, v);
  std::vector<glm::dvec2> q(n);
  for (size_t k = 0; k < n; ++k) q[k] = glm::dvec2(p[k][u], p[k][v]);
  if (n == 4) {
    const bool d02 = glm::distance(p[0], p[2]) <= glm::distance(p[1], p[3]);
    const bool ok02 = orient2(q[0], q[1], q[2]) > 0.0 && orient2(q[0], q[2], q[3]) > 0.0;
    const bool ok13 = orient2(q[0], q[1], q[3]) > 0.0 && orient2(q[1], q[2], q[3]) > 0.0;
    if ((d02 && (ok02 || !ok13)) || (!d02 && ok02 && !ok13)) {
      out.emplace_back(0, 1, 2);
      out.emplace_back(0, 2, 3);
    } else {
      out.emplace_back(0, 1, 3);
      out.emplace_back(1, 2, 3);
    }
    return out;
  }
  std::vector<uint32_t> left(n);
  for (uint32_t k = 0; k < n; ++k) left[k] = k;
  const auto is_ear = [&](size_t i) {
    const size_t m = left.size();
    const uint32_t a = left[(i + m - 1) % m], b = left[i], c = left[(i + 1) % m];
    if (!(orient2(q[a], q[b], q[c]) > 0.0)) return false;
    budget -= std::min<uint64_t>(budget, m);
    for (const uint32_t k : left) {
      if (k == a || k == b || k == c) continue;
      if (q[k] == q[a] || q[k] == q[b] || q[k] == q[c]) continue;  // a corner repeated: a seam
      if (in_triangle(q[k], q[a], q[b], q[c])) return false;
    }
    return true;
  };
  size_t i = 0;
  while (left.size() > 3) {
    const size_t m = left.size();
    bool found = false;
    for (size_t tried = 0; tried < m && budget > 0; ++tried, ++i) {
      --budget;
      if ((found = is_ear(i % m))) break;
    }
    if (!found && budget == 0) {  // the rest as a fan
      fan = true;
      for (size_t k = 1; k + 1 < m; ++k) out.emplace_back(left[0], left[k], left[k + 1]);
      return out;
    }
    i %= m;  // an ear, or (none left) the corner the search started from
    out.emplace_back(left[(i + m - 1) % m], left[i], left[(i + 1) % m]);
    left.erase(left.begin() + ptrdiff_t(i));
    if (i >= left.size()) i = 0;
  }
  out.emplace_back(left[0], left[1], left[2]);
  return out;
}

struct TripleHash {
  size_t operator()(const std::array<int, 3>& t) const {
    return (size_t(uint32_t(t[0])) * 0x9E3779B97F4A7C15ull) ^ (size_t(uint32_t(t[1])) * 0xC2B2AE3D27D4EB4Full) ^
           (size_t(uint32_t(t[2])) * 0x165667B19E3779F9ull);
  }
};

// The text rewritten line by line: `f(line, rest, out)` appends each line's replacement to `out`
// (`rest`: the line from its first character that is not a blank or a tab); the line breaks, and
// so the line numbers, stay.
template <class F>
std::string rewrite_lines(const std::string& text, F&& f) {
  std::string out;
  out.reserve(text.size());
  size_t start = 0;
  while (start < text.size()) {
    size_t end = text.find('\n', start);
    if (end == std::string::npos) end = text.size();
    const std::string_view line(text.data() + start, end - start);
    const size_t k = line.find_first_not_of(" \t");
    f(line, k == std::string_view::npos ? std::string_view() : line.substr(k), out);
    if (end < text.size()) out.push_back('\n');
    start = end + 1;
  }
  return out;
}

// The text with a `#` comment cut from every line of numbers (v, vt, vn, f, l, p): the checks read
// it so, and tinyobjloader's face parser failed on the `#` of `f 1 2 3 # a note` (a review's find).
// Other lines are kept whole (a texture's file name may hold a `#`); line numbers stay.
std::string cut_number_line_comments(const std::string& text) {
  return rewrite_lines(text, [](std::string_view line, std::string_view rest, std::string& out) {
    const std::string_view word = rest.substr(0, rest.find_first_of(" \t"));
    if (word == "v" || word == "vt" || word == "vn" || word == "f" || word == "l" || word == "p")
      if (const size_t hash = line.find('#'); hash != std::string_view::npos) line = line.substr(0, hash);
    out.append(line);
  });
}

// The text with every usemtl's name (its whole rest of line, `resolved` to the material it names)
// written as one word for tinyobjloader (name_for_tinyobj); line numbers stay.
std::string write_usemtl_names(const std::string& text, const std::map<std::string, std::string>& resolved) {
  return rewrite_lines(text, [&](std::string_view line, std::string_view rest, std::string& out) {
    if (rest.size() > 7 && rest.substr(0, 6) == "usemtl" && std::isspace(static_cast<unsigned char>(rest[6]))) {
      const size_t n = rest.find_first_not_of(" \t\r", 6);
      const std::string name = n == std::string_view::npos ? std::string() : material_name_rest(text, rest.substr(n));
      const auto it = resolved.find(name);
      out += "usemtl " + name_for_tinyobj(it != resolved.end() ? it->second : name);
    } else {
      out.append(line);
    }
  });
}

// The file parsed by tinyobjloader after the checks of what it lets pass (numbers, indices,
// material libraries and names), from the same normalized text the checks read (the libraries'
// text is handed to it for every mtllib statement); every usemtl names a material of the libraries.
tinyobj::ObjReader parse_obj(const std::string& path, std::vector<uint32_t>& face_corners,
                             std::map<std::string, std::string>& library_of, std::vector<bool>& with_kd) {
  const std::string text = read_file(path, "OBJ file");
  ObjScan scan = scan_obj(path, text);
  face_corners = std::move(scan.face_corners);
  const fs::path dir = fs::path(path).parent_path();
  std::string mtl_text;  // every library, checked and normalized, in order
  std::set<std::string> mtl_seen;
  // Where each material is first defined: the line of the mtllib that reads its library, and the
  // library (tinyobjloader knows only the libraries read before a usemtl, and keeps the first of
  // two definitions of one name)
  std::map<std::string, std::pair<size_t, std::string>> defined;
  for (const auto& [name, line] : scan.mtllibs) {
    const fs::path mtl = dir / name;
    if (const std::string why = why_missing(mtl.string()); why == "no such file")
      fail_at(path, line, "material library '" + mtl.string() + "' not found");
    else if (!why.empty())
      fail_at(path, line, "material library '" + mtl.string() + "': " + why);
    if (!mtl_seen.insert(mtl.lexically_normal().string()).second) continue;
    const std::string lib = scan_mtl(mtl.string());
    const size_t lib_line = line;  // (a structured binding: clang captures none)
    for_each_line(lib, [&](size_t mline, const std::vector<std::string_view>& tok) {
      if (tok[0] == "Kd" && !with_kd.empty()) with_kd.back() = true;
      if (tok[0] != "newmtl" || tok.size() < 2) return;
      with_kd.push_back(false);  // per material in the order tinyobjloader lists them
      // the whole name ("a b" and "a c" are two), as written for tinyobjloader
      const std::string m = name_from_tinyobj(material_name_rest(lib, tok[1]));
      if (!defined.emplace(m, std::pair{lib_line, mtl.string()}).second)
        std::cerr << "warning: " << mtl.string() << ":" << mline << ": material '" << m << "' is defined again (first in "
                  << defined[m].second << "): the first definition is used\n";
    });
    mtl_text += lib;
    mtl_text += "\n";
  }
  // A usemtl's name is its whole rest of line; where no material has that name but one has the
  // part before a '#' (a comment after the name), that one
  std::map<std::string, std::string> resolved;
  for (auto& [name, line] : scan.usemtls) {
    std::string use = name;
    if (!defined.count(use))
      if (const size_t hash = use.find('#'); hash != std::string::npos) {
        std::string cut = use.substr(0, hash);
        while (!cut.empty() && std::isspace(static_cast<unsigned char>(cut.back()))) cut.pop_back();
        if (defined.count(cut)) use = cut;
      }
    resolved[name] = use;
    name = use;
  }
  // A material used before the mtllib of its library was dropped, with a warning the file
  // contradicts (an outside sweep)
  for (const auto& [name, line] : scan.usemtls)
    if (const auto d = defined.find(name); d != defined.end() && d->second.first > line)
      fail_at(path, line, "usemtl '" + name + "' before the mtllib (line " + std::to_string(d->second.first) +
                              ") of its library: put the mtllib line first");

  tinyobj::ObjReaderConfig config;
  config.triangulate = false;  // triangulate_face: every face of n vertices gives n - 2 triangles
  config.vertex_color = false;
  tinyobj::ObjReader file_reader;
  if (!file_reader.ParseFromString(write_usemtl_names(cut_number_line_comments(text), resolved), mtl_text, config) ||
      !file_reader.Error().empty()) {
    std::string err = file_reader.Error();
    while (!err.empty() && err.back() == '\n') err.pop_back();
    throw Error("cannot load OBJ '" + path + "': " + (err.empty() ? "tinyobjloader failed" : err));
  }

  // Every usemtl must name a material of the libraries.
  std::set<std::string> names;
  for (const auto& m : file_reader.GetMaterials()) names.insert(name_from_tinyobj(m.name));
  for (const auto& [name, line] : scan.usemtls)
    if (!names.count(name)) fail_at(path, line, "usemtl '" + name + "': no such material in the material libraries");

  std::istringstream warnings(file_reader.Warning());
  for (std::string w; std::getline(warnings, w);)
    if (!w.empty()) std::cerr << "warning: " << path << ": " << w << "\n";
  for (const auto& [name, where] : defined) library_of[name] = where.second;
  return file_reader;
}

// The options of a map_ line this loader does not apply ("-s, -clamp"), "" for none: a texture is
// read whole, repeating, its alpha from the image (or its first channel), as shared/alpha.h says.
std::string ignored_texture_options(const tinyobj::texture_option_t& t) {
  std::string out;
  auto add = [&](const char* name) { out += (out.empty() ? "" : ", ") + std::string(name); };
  if (t.origin_offset[0] != 0 || t.origin_offset[1] != 0 || t.origin_offset[2] != 0) add("-o");
  if (t.scale[0] != 1 || t.scale[1] != 1 || t.scale[2] != 1) add("-s");
  if (t.turbulence[0] != 0 || t.turbulence[1] != 0 || t.turbulence[2] != 0) add("-t");
  if (t.clamp) add("-clamp");
  if (t.imfchan != 'm' && t.imfchan != 'l') add("-imfchan");
  // The rest tinyobjloader parses (they were dropped without this warning: an outside sweep; -mm
  // would change every texel's colour)
  if (t.brightness != 0 || t.contrast != 1) add("-mm");
  if (t.sharpness != 1) add("-boost");
  if (t.texture_resolution != -1) add("-texres");
  if (t.bump_multiplier != 1) add("-bm");
  if (!t.blendu) add("-blendu");
  if (!t.blendv) add("-blendv");
  if (t.type != tinyobj::TEXTURE_TYPE_NONE) add("-type");
  if (!t.colorspace.empty()) add("-colorspace");
  return out;
}

// Materials appended to the scene's, with the textures of those some face uses (`used`, per
// material): a library's materials no face names keep their place and colour, and decode nothing
// (ten unused 8192 x 8192 textures took 3 GB for one untextured triangle: an outside sweep).
void add_obj_materials(const std::vector<tinyobj::material_t>& mats, const std::vector<bool>& used,
                       const std::map<std::string, std::string>& library_of, const std::vector<bool>& with_kd,
                       const fs::path& obj_dir, Scene& scene, TextureCache& textures, const std::string& path) {
  for (size_t k = 0; k < mats.size(); ++k) {
    const tinyobj::material_t& m = mats[k];
    const auto lib = library_of.find(name_from_tinyobj(m.name));
    const fs::path dir = lib != library_of.end() ? fs::path(lib->second).parent_path() : obj_dir;
    for (const auto& [key, name, opt] : {std::tuple{"map_Kd", &m.diffuse_texname, &m.diffuse_texopt},
                                         std::tuple{"map_d", &m.alpha_texname, &m.alpha_texopt}})
      if (!name->empty())
        if (const std::string ignored = ignored_texture_options(*opt); !ignored.empty())
          std::cerr << "warning: " << path << ": material '" << name_from_tinyobj(m.name) << "': " << key << "'s " << ignored
                    << " not applied: the texture is read whole and repeats\n";
    Material mat;
    mat.name = name_from_tinyobj(m.name);
    mat.diffuse = glm::vec3(float(m.diffuse[0]), float(m.diffuse[1]), float(m.diffuse[2]));
    // A material without Kd: tinyobjloader gives one with a map_Kd the grey 0.6 (its "decent
    // default", which ons-reborn's 72 materials take), one without a texture black (an outside
    // sweep: drawn black without a word). Both take 0.6 now, the second with a warning
    if (k < with_kd.size() && !with_kd[k] && m.diffuse_texname.empty()) {
      mat.diffuse = glm::vec3(0.6f);
      if (used[k])
        std::cerr << "warning: " << path << ": material '" << mat.name
                  << "' has neither Kd nor map_Kd: drawn grey (Kd 0.6 0.6 0.6, the default a map_Kd alone gets)\n";
    }
    mat.opacity = float(m.dissolve);
    if (!m.diffuse_texname.empty() && used[k])
      mat.diffuse_texture = textures.load(scene, material_texture_path(dir, obj_dir, m.diffuse_texname), AlphaSource::kImage);
    if (!m.alpha_texname.empty() && used[k])
      mat.alpha_texture = textures.load(scene, material_texture_path(dir, obj_dir, m.alpha_texname), AlphaSource::kFirstChannel);
    scene.materials.push_back(std::move(mat));
  }
}

// The mesh: one vertex per distinct (v, vt, vn) triple; faces without usemtl get one "default"
// material, added on first use. `base`: the scene's index of the file's first material.
Mesh obj_mesh(const std::string& path, const tinyobj::ObjReader& file_reader, const std::vector<uint32_t>& face_corners,
              uint32_t base, Scene& scene) {
  const tinyobj::attrib_t& attrib = file_reader.GetAttrib();
  const auto& shapes = file_reader.GetShapes();
  const auto& mats = file_reader.GetMaterials();
  int64_t default_material = -1;
  Mesh mesh;
  mesh.name = fs::path(path).stem().string();
  std::unordered_map<std::array<int, 3>, uint32_t, TripleHash> vertex_of;
  bool all_normals = true, any_uv = false;
  std::vector<glm::vec3> normals;
  size_t fans = 0, largest_fan = 0, face = 0;
  size_t keyed_without_uv = 0;   // faces of a texture-keyed material with a corner without vt
  std::string keyed_material;    // the first such face's material
  uint64_t budget = kEarClipBudget;
  for (const auto& shape : shapes) {
    const auto& idx = shape.mesh.indices;
    size_t first = 0;  // the face's first corner in idx
    for (size_t f = 0; f < shape.mesh.num_face_vertices.size(); first += face_corners[face++], ++f) {
      // The pre-scan's count (tinyobjloader's is the low byte of it)
      if (face >= face_corners.size() || face_corners[face] % 256u != shape.mesh.num_face_vertices[f] ||
          face_corners[face] < 3 || first + face_corners[face] > idx.size())
        throw Error("cannot load OBJ '" + path + "': its faces do not read back as the pre-scan counted them");
      const size_t corners = face_corners[face];
      std::vector<glm::dvec3> at(corners);
      for (size_t k = 0; k < corners; ++k) {
        const int vi = idx[first + k].vertex_index;
        if (vi < 0 || 3 * size_t(vi) + 2 >= attrib.vertices.size())
          throw Error("cannot load OBJ '" + path + "': vertex index out of range");
        at[k] = glm::dvec3(attrib.vertices[3 * size_t(vi)], attrib.vertices[3 * size_t(vi) + 1],
                           attrib.vertices[3 * size_t(vi) + 2]);
      }
      bool fan = false;
      const std::vector<glm::uvec3> pieces = triangulate_face(at, budget, fan);
      if (fan) ++fans, largest_fan = std::max(largest_fan, corners);
      for (const glm::uvec3& piece : pieces) {
        glm::uvec3 tri;
        for (int k = 0; k < 3; ++k) {
          const tinyobj::index_t& ix = idx[first + piece[k]];
          const std::array<int, 3> key{ix.vertex_index, ix.texcoord_index, ix.normal_index};
          auto [it, fresh] = vertex_of.try_emplace(key, uint32_t(mesh.positions.size()));
          if (fresh) {
            const size_t v = size_t(ix.vertex_index);
            if (ix.vertex_index < 0 || 3 * v + 2 >= attrib.vertices.size())
              throw Error("cannot load OBJ '" + path + "': vertex index out of range");
            mesh.positions.emplace_back(attrib.vertices[3 * v], attrib.vertices[3 * v + 1], attrib.vertices[3 * v + 2]);
            glm::vec2 uv(0.0f);
            if (ix.texcoord_index >= 0) {
              const size_t t = size_t(ix.texcoord_index);
              if (2 * t + 1 >= attrib.texcoords.size()) throw Error("cannot load OBJ '" + path + "': texcoord index out of range");
              uv = {attrib.texcoords[2 * t], attrib.texcoords[2 * t + 1]};
              any_uv = true;
            }
            mesh.uvs.push_back(uv);
            glm::vec3 n(0.0f);
            if (ix.normal_index >= 0) {
              const size_t t = size_t(ix.normal_index);
              if (3 * t + 2 >= attrib.normals.size()) throw Error("cannot load OBJ '" + path + "': normal index out of range");
              n = {attrib.normals[3 * t], attrib.normals[3 * t + 1], attrib.normals[3 * t + 2]};
            } else {
              all_normals = false;
            }
            normals.push_back(n);
          }
          tri[k] = it->second;
        }
        mesh.triangles.push_back(tri);
        int mid = f < shape.mesh.material_ids.size() ? shape.mesh.material_ids[f] : -1;
        if (&piece == &pieces.front() && mid >= 0 && size_t(mid) < mats.size() &&
            scene.materials[base + uint32_t(mid)].alpha_keyed())
          for (size_t k = 0; k < corners; ++k)
            if (idx[first + k].texcoord_index < 0) {
              if (keyed_without_uv++ == 0) keyed_material = scene.materials[base + uint32_t(mid)].name;
              break;
            }
        if (mid < 0 || size_t(mid) >= mats.size()) {
          if (default_material < 0) {
            default_material = int64_t(scene.materials.size());
            scene.materials.push_back(Material{.name = "default"});
          }
          mesh.materials.push_back(uint32_t(default_material));
        } else {
          mesh.materials.push_back(base + uint32_t(mid));
        }
      }
    }
  }
  // Every face the pre-scan counted was read (a face tinyobjloader dropped would shift the counts)
  if (face != face_corners.size())
    throw Error("cannot load OBJ '" + path + "': its faces do not read back as the pre-scan counted them");
  if (fans)
    std::cerr << "warning: " << path << ": " << fans << " face(s) (the largest of " << largest_fan
              << " corners) split as fans after the ear clipping's budget of corner tests ran out: a concave face "
              "is covered wrongly so; triangulate such faces before\n";
  // A corner without texture coordinates reads uv (0, 0): one texel keeps or cuts such a face of a
  // keyed material whole (an outside sweep: said for glTF, not for OBJ)
  if (keyed_without_uv)
    std::cerr << "warning: " << path << ": " << keyed_without_uv << " face(s) of material '" << keyed_material
              << "' (keyed with a texture) have corners without texture coordinates (vt): such a corner reads its "
                 "texel at uv (0, 0)\n";
  if (mesh.triangles.empty()) throw Error("OBJ '" + path + "' has no faces: an empty model");
  if (all_normals) mesh.normals = std::move(normals);  // a vertex without a normal: flat shading
  if (!any_uv) mesh.uvs.clear();

  // Positions must be finite (the scan checked the text; this guards the conversion to float).
  for (size_t i = 0; i < mesh.positions.size(); ++i)
    if (!std::isfinite(mesh.positions[i].x) || !std::isfinite(mesh.positions[i].y) || !std::isfinite(mesh.positions[i].z))
      throw Error("OBJ '" + path + "': vertex " + std::to_string(i) + " has a non-finite coordinate (out of float range)");

  return mesh;
}

}  // namespace

std::vector<Instance> load_obj(const std::string& path, Scene& scene, TextureCache& textures) {
  std::vector<uint32_t> face_corners;
  std::map<std::string, std::string> library_of;  // material name -> the library that defines it
  std::vector<bool> with_kd;                      // per material, whether its definition has a Kd line
  const tinyobj::ObjReader file_reader = parse_obj(path, face_corners, library_of, with_kd);
  const uint32_t base = uint32_t(scene.materials.size());
  std::vector<bool> used(file_reader.GetMaterials().size(), false);
  for (const auto& shape : file_reader.GetShapes())
    for (const int id : shape.mesh.material_ids)
      if (id >= 0 && size_t(id) < used.size()) used[size_t(id)] = true;
  add_obj_materials(file_reader.GetMaterials(), used, library_of, with_kd, fs::path(path).parent_path(), scene, textures,
                    path);
  Mesh mesh = obj_mesh(path, file_reader, face_corners, base, scene);
  Instance inst;
  inst.name = mesh.name;
  inst.mesh = uint32_t(scene.meshes.size());
  scene.meshes.push_back(std::move(mesh));
  return {inst};
}

}  // namespace gridrt
