// image_io.h: textures in (through OpenImageIO) and rendered images out.
//
// Input: load_texture decodes any format OpenImageIO reads into a gridrt::Texture (RGBA8, row 0 =
// the first row of the file). Without OpenImageIO (GRIDRT_WITH_OIIO off, e.g. the GPU machine)
// it throws: such builds load scenes from the binary cache (scene_io.h, `.gridscene`).
//
// Output: write_image picks the format by extension. `.ppm` (8-bit, sRGB-encoded) and `.pfm`
// (32-bit float, linear) are written by hand in every build; with OpenImageIO also `.exr`/`.hdr`
// (linear float) and everything else it writes (`.png`, `.jpg`, `.tif`, ...: sRGB-encoded 8-bit).
// An image is written to a temporary file in the same folder and renamed over `path`, so a
// reader never sees a half-written image.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "gridrt/common/scene.h"

namespace gridrt {

// Which channel becomes the texel alpha.
enum class AlphaSource {
  kImage,         // the image's alpha channel; 255 when it has none
  kFirstChannel,  // the alpha channel if there is one, else the first channel (MTL map_d)
};

// Decode an image file into RGBA8. Throws Error naming the file when it cannot be read.
// `alpha_channel`, if given, is set to whether the file has an alpha channel (then both
// AlphaSource values give the same texture).
Texture load_texture(const std::string& path, AlphaSource alpha = AlphaSource::kImage,
                     bool* alpha_channel = nullptr);

// An encoded PNG or JPEG in memory (a glTF's image), decoded with load_texture's checks: the
// format by its first bytes, the header's size against the pixel limit before the pixels are
// allocated, truncated or corrupt data refused (a JPEG must reach its end-of-image marker, a
// PNG's checksums must hold). The pixels as stored: no orientation applied, alpha unassociated as
// PNG stores it, `bits` 8 or 16 (16-bit samples in the host's byte order), `channels` 1 to 4 a
// pixel. `name` names the image in messages. Throws Error; without OpenImageIO it always does.
struct DecodedImage {
  uint32_t width = 0, height = 0;
  int channels = 0, bits = 0;
  std::vector<uint8_t> data;
};
DecodedImage decode_image(const std::string& name, const unsigned char* bytes, size_t size);

// Linear radiance -> sRGB-encoded 8-bit (NaN -> 0, clamped to [0, 1] first).
uint8_t linear_to_srgb8(float linear);

// Write width x height linear RGB pixels, row 0 at the top. Throws Error for a zero size, a size
// that does not match rgb.size(), an unknown extension or a failed write.
void write_image(const std::string& path, uint32_t width, uint32_t height,
                 const std::vector<glm::vec3>& rgb);

// Write width x height RGBA8 pixels, sRGB-encoded bytes: 8-bit formats get them as they are
// (with `alpha`, their alpha channel where the format has one: a texture for inspection; without,
// RGB, as write_image writes a rendered frame), float formats (.pfm, .exr, .hdr) the linear values
// they encode, RGB.
void write_image_rgba8(const std::string& path, uint32_t width, uint32_t height,
                       const std::vector<uint8_t>& rgba, bool alpha = true);

// Whether this build reads textures (has OpenImageIO).
bool have_image_library();

// Error unless write_image can write this file's format (check before long work).
void check_image_extension(const std::string& path);

}  // namespace gridrt
