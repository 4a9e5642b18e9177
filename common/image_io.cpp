#include "gridrt/common/image_io.h"

#include "gridrt/common/safe_io.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string_view>
#include <system_error>

#include <unistd.h>

#ifdef GRIDRT_WITH_OIIO
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#endif

namespace gridrt {
namespace fs = std::filesystem;

namespace {

std::string lower_extension(const std::string& path) {
  std::string ext = fs::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return char(std::tolower(c)); });
  return ext;
}

void check_size(const std::string& path, uint32_t width, uint32_t height, size_t have, size_t per_pixel) {
  if (width == 0 || height == 0)
    throw Error("cannot write image '" + path + "': zero size (" + std::to_string(width) + " x " +
                std::to_string(height) + ")");
  if (have != size_t(width) * height * per_pixel)
    throw Error("cannot write image '" + path + "': " + std::to_string(have / per_pixel) +
                " pixels given for " + std::to_string(width) + " x " + std::to_string(height));
}

// Binary PPM (P6, 8-bit) or PFM (PF, little-endian float, rows bottom to top as the format says).
std::string netpbm_bytes(uint32_t width, uint32_t height, bool pfm, const std::vector<uint8_t>& bytes8,
                         const std::vector<float>& floats) {
  std::string out = (pfm ? "PF\n" : "P6\n") + std::to_string(width) + " " + std::to_string(height) +
                    (pfm ? "\n-1.0\n" : "\n255\n");
  if (pfm) {
    for (uint32_t y = height; y-- > 0;)
      out.append(reinterpret_cast<const char*>(floats.data() + size_t(y) * width * 3), size_t(width) * 3 * sizeof(float));
  } else {
    out.append(reinterpret_cast<const char*>(bytes8.data()), bytes8.size());
  }
  return out;
}

#ifdef GRIDRT_WITH_OIIO
// The written file decodes to the image's size: a writer that swallowed a failed write, or one
// that writes an incomplete file without a word (OpenImageIO's JPEG 2000 writer on images of
// fewer than about 64 x 48 pixels: a 77-byte header, or nothing), is caught before the file
// replaces anything.
void check_reads_back(const std::string& path, const std::string& tmp, uint32_t width, uint32_t height, int channels) {
  auto in = OIIO::ImageInput::open(tmp);
  std::vector<float> check(size_t(width) * height * size_t(channels));
  if (!in || in->spec().width != int(width) || in->spec().height != int(height) ||
      !in->read_image(0, 0, 0, channels, OIIO::TypeDesc::FLOAT, check.data())) {
    if (in) (void)in->geterror();  // consumed: the message names the temporary file
    (void)OIIO::geterror();
    throw Error("cannot write image '" + path + "': the file OpenImageIO's encoder wrote does not decode to " +
                std::to_string(width) + " x " + std::to_string(height) +
                " pixels (a failed write, or this format's writer failing on this image: try another format)");
  }
}

// Encodes into memory where the format's writer takes an I/O proxy (PNG, JPEG, EXR, HDR, TIFF,
// ...): then no disk error can happen inside the library (OpenImageIO's PNG writer does not
// report failed writes, and libjpeg's exits the process), and the bytes go out through
// write_file_atomically, which checks every write. A format without proxy support is written
// to the temporary file by the library and read back in full before the rename.
void write_oiio(const std::string& path, uint32_t width, uint32_t height, int channels, OIIO::TypeDesc type,
                const void* data) {
  const std::string ext = lower_extension(path);
  auto out = OIIO::ImageOutput::create(ext.substr(1));
  if (!out) throw Error("cannot write image '" + path + "': " + OIIO::geterror());
  OIIO::ImageSpec spec(int(width), int(height), channels, type);
  // A fixed date: OpenEXR's and TIFF's writers stamp the time of writing otherwise, and the same
  // render would not give the same bytes twice (the other formats carry no date)
  if (ext == ".exr" || ext == ".tif" || ext == ".tiff") spec.attribute("DateTime", "1970:01:01 00:00:00");
  // Four channels are colour and alpha as they are: OpenImageIO takes them as premultiplied and
  // divided the colour by the alpha for PNG (a texel of alpha 7 and red 1 came back red 36)
  if (channels == 4) spec.attribute("oiio:UnassociatedAlpha", 1);
  if (out->supports("ioproxy")) {
    std::vector<unsigned char> buffer;
    OIIO::Filesystem::IOVecOutput proxy(buffer);
    if (!out->set_ioproxy(&proxy) || !out->open(path, spec) || !out->write_image(type, data) || !out->close())
      throw Error("cannot write image '" + path + "': " + out->geterror());
    out.reset();
    write_file_atomically(path, "image",
                          std::string_view(reinterpret_cast<const char*>(buffer.data()), buffer.size()),
                          [&](const std::string& tmp) { check_reads_back(path, tmp, width, height, channels); });
    return;
  }
  write_file_atomically(path, "image", [&](const std::string& tmp) {
    if (!out->open(tmp, spec) || !out->write_image(type, data) || !out->close())
      throw Error("cannot write image '" + path + "': " + out->geterror());
    out.reset();
    check_reads_back(path, tmp, width, height, channels);
  });
}
#endif

bool is_float_format(const std::string& ext) { return ext == ".pfm" || ext == ".exr" || ext == ".hdr"; }

#ifdef GRIDRT_WITH_OIIO
// The format's writer takes a picture's three channels: a 2 x 2 probe is encoded the way the
// picture will be (to memory, or to a file of its own in the temporary folder where the writer
// takes no I/O proxy), so that a format that cannot hold colour is refused before the render, not
// after it (Zfile, one channel only, failed only once the frame was made: an outside sweep).
void probe_writer(const std::string& path, const std::string& ext) {
  auto out = OIIO::ImageOutput::create(ext.substr(1));
  const OIIO::TypeDesc type = is_float_format(ext) ? OIIO::TypeDesc::FLOAT : OIIO::TypeDesc::UINT8;
  const OIIO::ImageSpec spec(2, 2, 3, type);
  const std::vector<float> pixels(2 * 2 * 3, 0.5f);
  const std::vector<uint8_t> bytes(2 * 2 * 3, 128);
  const void* data = type == OIIO::TypeDesc::FLOAT ? static_cast<const void*>(pixels.data()) : bytes.data();
  bool ok = false;
  std::string why;
  if (out && out->supports("ioproxy")) {
    std::vector<unsigned char> buffer;
    OIIO::Filesystem::IOVecOutput proxy(buffer);
    ok = out->set_ioproxy(&proxy) && out->open(path, spec) && out->write_image(type, data) && out->close();
    why = out->geterror();
  } else if (out) {
    std::error_code ec;
    fs::path dir = fs::temp_directory_path(ec);
    if (ec) dir = "/tmp";
    const fs::path probe = dir / ("gridrt-" + std::to_string(::getpid()) + "-probe" + ext);
    ok = out->open(probe.string(), spec) && out->write_image(type, data) && out->close();
    why = out->geterror();
    out.reset();
    fs::remove(probe, ec);
  }
  (void)OIIO::geterror();
  if (!ok)
    throw Error("cannot write image '" + path + "': OpenImageIO's '" + ext.substr(1) +
                "' writer does not take a colour picture" + (why.empty() ? std::string() : " (" + why + ")") +
                "; use .png, .exr, .ppm, ...");
}
#endif

void check_extension(const std::string& path, const std::string& ext) {
  if (ext == ".ppm" || ext == ".pfm") return;
#ifdef GRIDRT_WITH_OIIO
  if (ext.empty()) throw Error("cannot write image '" + path + "': no file extension to choose the format by");
  // OpenImageIO's pseudo-formats write no file: "term" draws on the terminal, "null" nothing
  if (ext == ".term" || ext == ".null" || ext == ".nullimage")
    throw Error("cannot write image '" + path + "': '" + ext + "' writes no image file (use .png, .exr, .ppm, ...)");
  // OpenImageIO's PNM writer writes a colour picture as P6 whatever the name: a '.pgm' or '.pbm'
  // file held colour (an outside sweep). Grey levels or one bit a pixel would be another picture
  if (ext == ".pgm" || ext == ".pbm")
    throw Error("cannot write image '" + path + "': '" + ext + "' holds " +
                (ext == ".pgm" ? "grey levels" : "one bit a pixel") + " and the picture is colour (use .ppm or .png)");
  if (!OIIO::ImageOutput::create(path))
    throw Error("cannot write image '" + path + "': OpenImageIO knows no format for '" + ext + "'");
  probe_writer(path, ext);
#else
  throw Error("cannot write image '" + path + "': unknown extension '" + ext +
              "' (this build has no OpenImageIO: use .ppm or .pfm)");
#endif
}

}  // namespace

void check_image_extension(const std::string& path) { check_extension(path, lower_extension(path)); }

bool have_image_library() {
#ifdef GRIDRT_WITH_OIIO
  return true;
#else
  return false;
#endif
}

uint8_t linear_to_srgb8(float c) {
  if (!(c > 0.0f)) return 0;  // also NaN
  if (c >= 1.0f) return 255;
  const float s = c <= 0.0031308f ? 12.92f * c : 1.055f * std::pow(c, 1.0f / 2.4f) - 0.055f;
  return uint8_t(std::lround(s * 255.0f));
}

void write_image(const std::string& path, uint32_t width, uint32_t height, const std::vector<glm::vec3>& rgb) {
  check_size(path, width, height, rgb.size(), 1);
  const std::string ext = lower_extension(path);
  check_extension(path, ext);
  std::vector<float> floats;
  std::vector<uint8_t> bytes;
  if (is_float_format(ext)) {
    floats.reserve(rgb.size() * 3);
    for (const glm::vec3& c : rgb) floats.insert(floats.end(), {c.x, c.y, c.z});
  } else {
    bytes.reserve(rgb.size() * 3);
    for (const glm::vec3& c : rgb)
      bytes.insert(bytes.end(), {linear_to_srgb8(c.x), linear_to_srgb8(c.y), linear_to_srgb8(c.z)});
  }
  if (ext == ".ppm" || ext == ".pfm")
    return write_file_atomically(path, "image", netpbm_bytes(width, height, ext == ".pfm", bytes, floats));
#ifdef GRIDRT_WITH_OIIO
  if (is_float_format(ext)) write_oiio(path, width, height, 3, OIIO::TypeDesc::FLOAT, floats.data());
  else write_oiio(path, width, height, 3, OIIO::TypeDesc::UINT8, bytes.data());
#endif
}

void write_image_rgba8(const std::string& path, uint32_t width, uint32_t height, const std::vector<uint8_t>& rgba,
                       bool alpha) {
  check_size(path, width, height, rgba.size(), 4);
  const std::string ext = lower_extension(path);
  check_extension(path, ext);
  std::vector<float> floats;
  std::vector<uint8_t> bytes;
  const size_t n = size_t(width) * height;
  // The bytes are sRGB-encoded (the shader's srgb8): a float image holds linear values, as the CPU
  // writes them (they were written as byte / 255, sRGB values read as linear: an outside sweep)
  if (is_float_format(ext)) {
    floats.reserve(n * 3);
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) {
        const float c = float(rgba[i * 4 + k]) / 255.0f;
        floats.push_back(c <= 0.04045f ? c / 12.92f : std::pow((c + 0.055f) / 1.055f, 2.4f));
      }
  } else if (ext == ".ppm" || !alpha) {
    // RGB: without `alpha`, as write_image writes every backend's picture (the shader's alpha, 255,
    // made a Vulkan PNG or TIFF a four-channel file no comparison with the CPU's passed: outside
    // sweeps)
    bytes.reserve(n * 3);
    for (size_t i = 0; i < n; ++i)
      for (int k = 0; k < 3; ++k) bytes.push_back(rgba[i * 4 + k]);
  }
  if (ext == ".ppm" || ext == ".pfm")
    return write_file_atomically(path, "image", netpbm_bytes(width, height, ext == ".pfm", bytes, floats));
#ifdef GRIDRT_WITH_OIIO
  if (is_float_format(ext)) write_oiio(path, width, height, 3, OIIO::TypeDesc::FLOAT, floats.data());
  else if (alpha) write_oiio(path, width, height, 4, OIIO::TypeDesc::UINT8, rgba.data());
  else write_oiio(path, width, height, 3, OIIO::TypeDesc::UINT8, bytes.data());
#endif
}

#ifdef GRIDRT_WITH_OIIO
namespace {
// The still-image formats read as textures, by their first bytes (TGA, which has no signature,
// by its extension), as OpenImageIO's format names. OpenImageIO otherwise tries every reader it
// has on a file its first choice refuses: a 38-byte text file named .mp4 was taken by the FFmpeg
// reader as a playlist, which opened the files it names itself (a FIFO: the load hung; /dev/zero:
// an abort), and a corrupt Maya IFF crashed its tile decoder (outside sweeps). The reader of the
// format found is made by name, so no other is tried.
std::string texture_format(const std::string& path) {
  std::string head(16, '\0');
  {
    std::ifstream f(path, std::ios::binary);
    f.read(head.data(), std::streamsize(head.size()));
    head.resize(size_t(std::max<std::streamsize>(f.gcount(), 0)));
  }
  const auto starts = [&](std::string_view magic) { return head.compare(0, magic.size(), magic) == 0; };
  if (starts("\x89PNG\r\n\x1a\n")) return "png";
  if (starts("\xff\xd8\xff")) return "jpeg";
  if (starts(std::string_view("II*\0", 4)) || starts(std::string_view("MM\0*", 4)) ||
      starts(std::string_view("II+\0", 4)) || starts(std::string_view("MM\0+", 4)))
    return "tiff";
  if (starts("BM")) return "bmp";
  if (starts("RIFF") && head.size() >= 12 && head.compare(8, 4, "WEBP") == 0) return "webp";
  // P1-P6, and PFM (PF, Pf), which gridrt writes itself
  if (head.size() >= 2 && head[0] == 'P' && ((head[1] >= '1' && head[1] <= '6') || head[1] == 'F' || head[1] == 'f'))
    return "pnm";
  // Not read: formats whose OpenImageIO readers an outside fuzz of damaged files hung (DDS: a zero
  // colour mask), crashed (SGI, PSD), or made allocate gigabytes from a few bytes of header before
  // any limit is consulted (PSD's colour-mode length, an OpenEXR attribute's size, a GIF's logical
  // screen); HDR and JPEG 2000 with them, outside the formats meshes' textures come in. A texture
  // must not hang, crash or exhaust a load
  const auto refused = [&](const char* name) {
    throw Error("cannot load texture '" + path + "': " + name +
                " textures are not read (OpenImageIO's reader of them hangs, crashes or allocates without bound on "
                "damaged files); convert it to PNG");
  };
  if (starts("DDS ")) refused("DDS");
  if (starts("\x01\xda")) refused("SGI");
  if (starts("8BPS")) refused("PSD");
  if (starts("\x76\x2f\x31\x01")) refused("OpenEXR");
  if (starts("GIF87a") || starts("GIF89a")) refused("GIF");
  if (starts("#?")) refused("Radiance HDR");
  if (starts(std::string_view("\0\0\0\x0cjP  \r\n", 10)) || starts("\xff\x4f\xff\x51")) refused("JPEG 2000");
  std::string ext = fs::path(path).extension().string();
  for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext == ".tga" || ext == ".tpic") {
    // True-colour and grey images only (types 2, 3, 10, 11, no colour map): OpenImageIO's reader
    // indexes a colour map with the pixel plus the header's first-entry index, unchecked, and read
    // heap bytes past it as texels (an outside fuzz)
    if (head.size() < 3) throw Error("cannot load texture '" + path + "': a TGA file shorter than its header");
    const unsigned cmap = static_cast<unsigned char>(head[1]), type = static_cast<unsigned char>(head[2]);
    if (cmap != 0 || (type != 2 && type != 3 && type != 10 && type != 11))
      throw Error("cannot load texture '" + path + "': a colour-mapped TGA (or one of image type " + std::to_string(type) +
                  "): only true-colour and grey TGA textures are read; convert it to PNG");
    return "targa";
  }
  throw Error("cannot load texture '" + path + "': not an image of a format read as a texture (PNG, JPEG, TGA, BMP, "
              "TIFF, WebP, PNM and PFM: told by its first bytes, TGA by its extension)");
}

// A PNM (P1-P6: magic, width, height and, but for P1 and P4, the largest value; blanks and '#'
// comments between; then the samples). Refused: a largest value outside 1..65535, and a sample
// above it or not a number (a plain PNM's "-5" read as 251, "300" under 255 clamped; a raw PNM's
// byte above a largest value below 255 scaled past white): OpenImageIO read such files as textures
// of some colour without a word (an outside sweep). The count of samples is its reader's to check.
// A PFM (PF colour, Pf grey: magic, width, height, scale, one blank, then 32-bit floats whose byte
// order the scale's sign gives) whose samples are not all finite is refused: OpenImageIO read NaN
// as 0 and infinity as white into the 8-bit texture without a word (an outside sweep). The count
// of samples is its reader's to check.
void check_pfm(const std::string& path, const std::string& data) {
  const bool colour = data[1] == 'F';
  std::istringstream head(data.substr(0, std::min<size_t>(data.size(), 256)));
  std::string magic;
  long w = 0, h = 0;
  double scale = 0.0;
  if (!(head >> magic >> w >> h >> scale) || w <= 0 || h <= 0 || !std::isfinite(scale) || scale == 0.0) return;
  const std::streamoff at = head.tellg();
  if (at < 0) return;
  const size_t from = size_t(at) + 1;  // the one blank after the scale
  const bool little = scale < 0.0;
  const uint64_t samples = uint64_t(w) * uint64_t(h) * (colour ? 3u : 1u);
  for (uint64_t i = 0; i < samples && from + 4 * i + 4 <= data.size(); ++i) {
    const auto b = [&](size_t k) { return uint32_t(static_cast<unsigned char>(data[from + 4 * i + k])); };
    const uint32_t bits = little ? (b(0) | b(1) << 8 | b(2) << 16 | b(3) << 24) : (b(3) | b(2) << 8 | b(1) << 16 | b(0) << 24);
    if ((bits & 0x7F800000u) == 0x7F800000u)
      throw Error("cannot load texture '" + path + "': its PFM holds " + ((bits & 0x007FFFFFu) ? "NaN" : "an infinity") +
                  " at sample " + std::to_string(i) + " (texels must be finite numbers)");
  }
}

void check_pnm(const std::string& path) {
  const std::string data = read_input_file(path, "texture");
  if (data.size() >= 2 && data[0] == 'P' && (data[1] == 'F' || data[1] == 'f')) return check_pfm(path, data);
  if (data.size() < 2 || data[0] != 'P' || data[1] < '1' || data[1] > '6') return;  // the reader's to refuse
  const char kind = data[1];
  const bool has_max = kind != '1' && kind != '4';
  const auto fail = [&](const std::string& why) {
    throw Error("cannot load texture '" + path + "': " + why + " (a damaged file)");
  };
  size_t k = 2;
  // The next token (digits or not), blanks and comments skipped; "" at the end
  const auto token = [&]() {
    for (;;) {
      while (k < data.size() && std::isspace(static_cast<unsigned char>(data[k]))) ++k;
      if (k < data.size() && data[k] == '#') {
        while (k < data.size() && data[k] != '\n' && data[k] != '\r') ++k;
        continue;
      }
      break;
    }
    const size_t from = k;
    while (k < data.size() && !std::isspace(static_cast<unsigned char>(data[k])) && data[k] != '#') ++k;
    return std::string_view(data).substr(from, k - from);
  };
  const auto number = [](std::string_view t) -> long {
    if (t.empty() || t.size() > 9 || !std::all_of(t.begin(), t.end(), [](char c) { return c >= '0' && c <= '9'; }))
      return -1;
    return std::stol(std::string(t));
  };
  token();  // width
  token();  // height
  long maxval = 1;
  if (has_max) {
    const std::string_view m = token();
    maxval = number(m);
    if (maxval < 1 || maxval > 65535)
      fail("its PNM header's largest value is '" + std::string(m) + "', outside 1..65535");
  }
  if (kind == '4') return;  // raw bits: every value is one
  if (kind == '1') {
    // Plain bits: each '0' or '1' is a sample, blanks and comments between
    for (; k < data.size(); ++k) {
      const char c = data[k];
      if (c == '#') {
        while (k < data.size() && data[k] != '\n' && data[k] != '\r') ++k;
      } else if (!std::isspace(static_cast<unsigned char>(c)) && c != '0' && c != '1') {
        fail(std::string("its plain PBM holds '") + c + "' where a sample is 0 or 1");
      }
    }
    return;
  }
  if (kind == '2' || kind == '3') {
    for (std::string_view t = token(); !t.empty(); t = token()) {
      const long v = number(t);
      if (v < 0 || v > maxval)
        fail("its plain PNM holds the sample '" + std::string(t) + "', not a number in 0.." + std::to_string(maxval));
    }
    return;
  }
  // Raw samples (P5, P6) after one blank: a byte each below 256, else two, most significant first
  k += 1;
  if (maxval == 255 || maxval == 65535) return;
  const size_t step = maxval < 256 ? 1 : 2;
  for (size_t i = k; i + step <= data.size(); i += step) {
    const long v = step == 1 ? long(static_cast<unsigned char>(data[i]))
                             : long(static_cast<unsigned char>(data[i])) << 8 | static_cast<unsigned char>(data[i + 1]);
    if (v > maxval)
      fail("its raw PNM holds the sample " + std::to_string(v) + " at byte " + std::to_string(i) + ", above its largest value " +
           std::to_string(maxval));
  }
}

// EXIF/TIFF orientation (1-8): the stored texel that display texel (x, y) shows, for a stored
// image of w x h (orientations 5-8 display it h x w).
void oriented_source(int orientation, uint32_t w, uint32_t h, uint32_t x, uint32_t y, uint32_t& sx, uint32_t& sy) {
  switch (orientation) {
    case 2: sx = w - 1 - x; sy = y; break;          // mirrored left-right
    case 3: sx = w - 1 - x; sy = h - 1 - y; break;  // turned 180 degrees
    case 4: sx = x; sy = h - 1 - y; break;          // mirrored top-bottom
    case 5: sx = y; sy = x; break;                  // transposed
    case 6: sx = y; sy = h - 1 - x; break;          // turned 90 degrees clockwise to display
    case 7: sx = w - 1 - y; sy = h - 1 - x; break;  // transversed
    case 8: sx = w - 1 - y; sy = x; break;          // turned 90 degrees counter-clockwise to display
    default: sx = x; sy = y; break;
  }
}

void check_jpeg_end(const std::string& path, std::string_view data) {
  // The markers walked from the start: segments skipped by their lengths, entropy-coded data
  // scanned for the next marker (FF 00 is a stuffed byte, FF D0-D7 a restart) until the
  // end-of-image marker FF D9. Bytes after it are allowed (cameras append data there); a file
  // that ends first is truncated. An embedded thumbnail lies inside an APP segment: skipped whole.
  const auto byte = [&](size_t k) { return static_cast<unsigned char>(data[k]); };
  const auto truncated = [&] {
    throw Error("cannot load texture '" + path + "': its JPEG data ends before the end-of-image marker (a truncated file)");
  };
  size_t k = 2;  // after SOI (FF D8), which OpenImageIO has read
  bool in_scan = false;
  while (k + 1 < data.size()) {
    if (byte(k) != 0xFF) {
      // entropy-coded data, or stray bytes between segments, which libjpeg skips to the next
      // marker with a warning (the file decodes whole: refusing it was a review's find)
      ++k;
      continue;
    }
    const unsigned char m = byte(k + 1);
    if (m == 0xD9) return;                                     // EOI
    if (m == 0xFF) { ++k; continue; }                          // fill byte
    if (in_scan && (m == 0x00 || (m >= 0xD0 && m <= 0xD7))) { k += 2; continue; }  // stuffed byte, restart
    if (m >= 0xD0 && m <= 0xD8) { k += 2; continue; }          // restart or SOI without a length
    if (k + 3 >= data.size()) truncated();
    const size_t length = size_t(byte(k + 2)) << 8 | byte(k + 3);
    if (length < 2) truncated();
    k += 2 + length;
    in_scan = m == 0xDA;  // SOS: its entropy-coded data follows
  }
  truncated();
}
}  // namespace
#endif

#ifdef GRIDRT_WITH_OIIO
namespace {
Texture load_texture_oiio(const std::string& path, AlphaSource alpha, bool* alpha_channel);

// Whether an error a reader reported after a read that returned success means missing or damaged
// pixels. A reader may decode what it can and report the rest while returning success: a TIFF cut
// short read its missing strips as black texels, a DDS its missing blocks (outside sweeps). Not
// JPEG in general: libjpeg's warnings arrive the same way on files that decode whole (stray bytes
// between segments); but its "premature end of data segment" (scan data cut short, an end marker
// after it) and "Premature end of JPEG file" are missing texels read as grey (an outside sweep).
bool reported_damage(const std::string& format, const std::string& late) {
  if (late.empty()) return false;
  std::string lower = late;
  for (char& c : lower) c = char(std::tolower(static_cast<unsigned char>(c)));
  return format != "jpeg" || lower.find("premature end") != std::string::npos;
}
}  // namespace
#endif

DecodedImage decode_image(const std::string& name, const unsigned char* bytes, size_t size) {
#ifdef GRIDRT_WITH_OIIO
  const auto fail = [&](const std::string& why) { throw Error(name + ": " + why); };
  const std::string_view data(reinterpret_cast<const char*>(bytes), bytes ? size : 0);
  const std::string format = data.substr(0, 8) == std::string_view("\x89PNG\r\n\x1a\n", 8) ? "png"
                             : data.substr(0, 3) == "\xff\xd8\xff"                         ? "jpeg"
                                                                                          : "";
  if (format.empty()) fail("not a PNG or JPEG (told by its first bytes)");
  try {
    OIIO::Filesystem::IOMemReader proxy(bytes, size);
    OIIO::ImageSpec config;
    config.attribute("oiio:UnassociatedAlpha", 1);
    auto in = OIIO::ImageInput::create(format);
    if (!in || !in->supports("ioproxy")) fail("this build's OpenImageIO cannot read " + format + " from memory");
    if (!in->set_ioproxy(&proxy)) fail("this build's OpenImageIO cannot read " + format + " from memory");
    OIIO::ImageSpec opened;
    if (!in->open(name, opened, config)) {
      const std::string why = in->geterror();
      fail(why.empty() ? "it does not open as the " + format + " its first bytes name" : why);
    }
    const OIIO::ImageSpec& spec = in->spec();
    const int nch = spec.nchannels;
    if (spec.width <= 0 || spec.height <= 0 || nch <= 0 || spec.depth > 1) fail("not a 2D image with channels");
    if (nch > 4) fail(std::to_string(nch) + " channels (a PNG or JPEG texture has 1 to 4)");
    const uint64_t declared = uint64_t(spec.width) * uint64_t(spec.height);
    if (declared > input_limits().max_texture_pixels)
      fail("its header declares " + std::to_string(spec.width) + " x " + std::to_string(spec.height) +
           " pixels, more than the limit of " + std::to_string(input_limits().max_texture_pixels) +
           " pixels (--max-texture-pixels)");
    DecodedImage out;
    out.width = uint32_t(spec.width);
    out.height = uint32_t(spec.height);
    out.channels = nch;
    out.bits = spec.format.size() >= 2 ? 16 : 8;
    const size_t n = size_t(declared) * size_t(nch) * size_t(out.bits / 8);
    require_host_memory(uint64_t(n), name + " (" + std::to_string(out.width) + " x " + std::to_string(out.height) +
                                          " pixels, decoded)",
                        "lower --max-texture-pixels, or use smaller textures");
    out.data.resize(n);
    const OIIO::TypeDesc type = out.bits == 16 ? OIIO::TypeDesc::UINT16 : OIIO::TypeDesc::UINT8;
    const auto damaged = [&](const std::string& why) {
      fail((why.empty() ? std::string("its pixels do not decode") : why) + " (a truncated or corrupt image)");
    };
    if (!in->read_image(0, 0, 0, nch, type, out.data.data())) damaged(in->geterror());
    const std::string late = in->geterror();
    if (reported_damage(in->format_name(), late)) damaged(late);
    in->close();
    if (format == "jpeg") check_jpeg_end(name, data);
    return out;
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    fail(std::string("its reader failed (") + e.what() + "): a damaged image");
  }
  return {};
#else
  (void)bytes;
  (void)size;
  throw Error(name + ": this build has no OpenImageIO (GRIDRT_WITH_OIIO off) to decode it");
#endif
}

Texture load_texture(const std::string& path, AlphaSource alpha, bool* alpha_channel) {
#ifdef GRIDRT_WITH_OIIO
  // A reader's own C++ exceptions (a BMP's RLE data, a length computation past its range) are the
  // texture's error, not gridrt's (they ended in exit 5, "internal error": an outside fuzz)
  try {
    return load_texture_oiio(path, alpha, alpha_channel);
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const std::exception& e) {
    throw Error("cannot load texture '" + path + "': its reader failed (" + e.what() + "): a damaged file");
  }
#else
  (void)alpha;
  (void)alpha_channel;
  if (const std::string why = why_missing(path); !why.empty()) throw Error("cannot load texture '" + path + "': " + why);
  throw Error("cannot load texture '" + path +
              "': this build has no OpenImageIO (GRIDRT_WITH_OIIO off); load the scene from a "
              ".gridscene cache written by a full build instead");
#endif
}

#ifdef GRIDRT_WITH_OIIO
namespace {
Texture load_texture_oiio(const std::string& path, AlphaSource alpha, bool* alpha_channel) {
  // Keep colour and alpha as stored (OpenImageIO premultiplies by default): a masked-out texel
  // still has its colour.
  check_input_file(path, "texture");  // a regular file (not /dev/zero, a FIFO, a directory), bounded
  OIIO::ImageSpec config;
  config.attribute("oiio:UnassociatedAlpha", 1);
  const std::string format_name = texture_format(path);
  if (format_name == "pnm") check_pnm(path);
  if (format_name == "bmp") {
    // OpenImageIO decodes an RLE BMP whole in open(), before its size can be checked (381 MB for
    // a 152-byte file: an outside fuzz): the header's size first (BITMAPINFOHEADER and later)
    std::string head(34, '\0');
    std::ifstream f(path, std::ios::binary);
    f.read(head.data(), std::streamsize(head.size()));
    if (f.gcount() >= 26) {
      const auto i32 = [&](size_t k) {
        return int32_t(uint32_t(uint8_t(head[k])) | uint32_t(uint8_t(head[k + 1])) << 8 |
                       uint32_t(uint8_t(head[k + 2])) << 16 | uint32_t(uint8_t(head[k + 3])) << 24);
      };
      const auto u16 = [&](size_t k) { return uint64_t(uint8_t(head[k])) | uint64_t(uint8_t(head[k + 1])) << 8; };
      const bool core = i32(14) == 12;  // OS/2's BITMAPCOREHEADER: 16-bit sizes
      const uint64_t bw = core ? u16(18) : uint64_t(std::abs(int64_t(i32(18))));
      const uint64_t bh = core ? u16(20) : uint64_t(std::abs(int64_t(i32(22))));
      if (bw * bh > input_limits().max_texture_pixels)
        throw Error("cannot load texture '" + path + "': its header declares " + std::to_string(bw) + " x " +
                    std::to_string(bh) + " pixels, more than the limit of " +
                    std::to_string(input_limits().max_texture_pixels) + " pixels (--max-texture-pixels)");
      // The compression (BITMAPINFOHEADER and later): OpenImageIO reads one it does not know
      // (JPEG, PNG, CMYK, any number) as uncompressed pixels, a texture of noise with exit 0 (an
      // outside sweep). Read: none, RLE8 at 8 bits, RLE4 at 4, bit fields at 16 or 32.
      if (!core && f.gcount() == std::streamsize(head.size())) {
        const uint32_t compression = uint32_t(i32(30));
        const uint64_t bpp = u16(28);
        const bool known = compression == 0 || (compression == 1 && bpp == 8) || (compression == 2 && bpp == 4) ||
                           (compression == 3 && (bpp == 16 || bpp == 32));
        if (!known) {
          static const char* names[] = {"none", "RLE8", "RLE4", "bit fields", "JPEG", "PNG", "alpha bit fields"};
          const std::string name = compression < std::size(names) ? std::string(" (") + names[compression] + ")"
                                   : compression >= 11 && compression <= 13 ? std::string(" (CMYK)")
                                                                            : std::string();
          throw Error("cannot load texture '" + path + "': BMP compression " + std::to_string(compression) + name +
                      " at " + std::to_string(bpp) + " bits a pixel is not read (none, RLE8 at 8 bits, RLE4 at 4, "
                      "bit fields at 16 or 32 are): convert it to PNG");
        }
      }
    }
  }
  auto in = OIIO::ImageInput::create(format_name);
  if (in) {
    OIIO::ImageSpec opened;
    if (!in->open(path, opened, config)) {
      const std::string why = in->geterror();
      throw Error("cannot load texture '" + path + "': " + (why.empty() ? "it does not open as the format its first bytes name" : why));
    }
  }
  if (!in) {
    std::string why = OIIO::geterror();
    if (const std::string missing = why_missing(path); !missing.empty()) why = missing;
    throw Error("cannot load texture '" + path + "': " + why);
  }
  const OIIO::ImageSpec& spec = in->spec();
  const int nch = spec.nchannels;
  if (spec.width <= 0 || spec.height <= 0 || nch <= 0 || spec.depth > 1)
    throw Error("cannot load texture '" + path + "': not a 2D image with channels");
  // The header's size, checked before anything is allocated for the pixels.
  const uint64_t declared = uint64_t(spec.width) * uint64_t(spec.height);
  if (declared > input_limits().max_texture_pixels || nch > 64)
    throw Error("cannot load texture '" + path + "': its header declares " + std::to_string(spec.width) + " x " +
                std::to_string(spec.height) + " pixels of " + std::to_string(nch) + " channels, more than the limit of " +
                std::to_string(input_limits().max_texture_pixels) + " pixels (--max-texture-pixels)");
  Texture tex;
  tex.path = path;
  tex.width = uint32_t(spec.width);
  tex.height = uint32_t(spec.height);
  const size_t n = size_t(tex.width) * tex.height;
  // Which channel is alpha: the one the file names, else the last of 2 or 4.
  int a = spec.alpha_channel;
  if (a < 0 || a >= nch) a = (nch == 2 || nch == 4) ? nch - 1 : -1;
  if (alpha_channel) *alpha_channel = a >= 0;
  if (a < 0 && alpha == AlphaSource::kFirstChannel) a = 0;
  // Only the channels used are read: the colour's (the first three, or one grey) and the alpha's,
  // each by itself. A header of 64 channels took 64 bytes a pixel (4 GiB at the pixel limit, from
  // a 66 KB file), and so did one whose alpha is its last channel (an EXR layer's "*.A" sorts last:
  // outside sweeps).
  const int colour = std::min(nch, 3);
  // Each texture is within the pixel limit, but nothing else bounds their sum (ten copies of one
  // 8192 x 8192 PNG took 3 GB, beyond --max-host-mib: an outside sweep): the read and the RGBA
  // copy must fit the host's memory before anything is allocated
  require_host_memory(uint64_t(n) * uint64_t(colour + 1 + 4), "texture '" + path + "' (" + std::to_string(tex.width) +
                          " x " + std::to_string(tex.height) + " pixels, decoded)",
                      "lower --max-texture-pixels, or use smaller textures");
  std::vector<uint8_t> px(n * size_t(colour));
  std::vector<uint8_t> alpha_px;
  auto failed = [&](const std::string& why) {
    throw Error("cannot load texture '" + path + "': " + (why.empty() ? "its pixels do not decode (truncated or corrupt)" : why));
  };
  if (!in->read_image(0, 0, 0, colour, OIIO::TypeDesc::UINT8, px.data())) failed(in->geterror());
  if (a >= colour) {
    alpha_px.resize(n);
    if (!in->read_image(0, 0, a, a + 1, OIIO::TypeDesc::UINT8, alpha_px.data())) failed(in->geterror());
  }
  // A reader may decode what it can and report the rest as an error while returning success: a
  // TIFF cut short read its missing strips as black texels, a DDS its missing blocks (outside
  // sweeps). Not JPEG: libjpeg's warnings arrive the same way on files that decode whole (stray
  // bytes between segments); its truncation is found by the end marker below.
  const std::string format = in->format_name();
  std::string late = in->geterror();
  if (reported_damage(format, late))
    failed(late + " (the reader decoded what it could and reported this: a truncated or corrupt file)");
  // Where the file says its texels are stored (EXIF/TIFF Orientation 2-8), they are laid out as
  // it is displayed, as image viewers and the tools that painted it show it (read as stored, a
  // camera's portrait photo lay on its side)
  const int orientation = spec.get_int_attribute("Orientation", 1);
  // A TIFF alpha that the reader does not call unassociated is associated (colour premultiplied by
  // alpha, ExtraSamples 1): the colour is divided by it, so that a texel's colour means the same as
  // a PNG's (a premultiplied TIFF drew its soft edges dark)
  // (only where the file names that channel alpha: ExtraSamples 0, "unspecified", is data as stored)
  const bool premultiplied = a >= 0 && a == spec.alpha_channel && format == "tiff" &&
                             spec.get_int_attribute("oiio:UnassociatedAlpha", 0) != 1;
  in->close();
  // libjpeg calls missing scan lines a warning and OpenImageIO returns them grey without an
  // error: a JPEG must end with its end-of-image marker (FF D9), trailing blanks aside
  if (format == "jpeg") check_jpeg_end(path, read_input_file(path, "texture"));
  const bool turned = orientation >= 5 && orientation <= 8;
  const uint32_t sw = tex.width, sh = tex.height;
  if (turned) std::swap(tex.width, tex.height);
  tex.rgba.resize(n * 4);
  for (uint32_t y = 0; y < tex.height; ++y)
    for (uint32_t x = 0; x < tex.width; ++x) {
      uint32_t sx = x, sy = y;
      oriented_source(orientation, sw, sh, x, y, sx, sy);
      const size_t i = size_t(sy) * sw + sx;
      const uint8_t* p = px.data() + i * size_t(colour);
      uint8_t* q = tex.rgba.data() + (size_t(y) * tex.width + x) * 4;
      if (nch >= 3) { q[0] = p[0]; q[1] = p[1]; q[2] = p[2]; }
      else { q[0] = q[1] = q[2] = p[0]; }
      q[3] = a < 0 ? 255 : a >= colour ? alpha_px[i] : p[a];
      if (premultiplied && q[3] != 0 && q[3] != 255)
        for (int c = 0; c < 3; ++c) q[c] = uint8_t(std::min(255u, (uint32_t(q[c]) * 255u + q[3] / 2u) / q[3]));
      if (q[3] < 255) tex.has_alpha = true;
    }
  return tex;
}
}  // namespace
#endif

}  // namespace gridrt
