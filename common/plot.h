// plot.h: the tool's figures: a canvas with text set by OpenImageIO (ImageBufAlgo::render_text,
// FreeType, the DejaVu fonts of Debian's fonts-dejavu-core), a perceptual colour map (viridis), a
// colour bar, a legend of swatches, and axes with ticks for x/y plots. Used by `render --view`,
// `stats --slices`, `sweep` and `portal render`'s figures of the tutorial.
//
// Colours are display values (sRGB-encoded, [0, 1]); a canvas is written as 8-bit as it is.
// Without OpenImageIO (GRIDRT_WITH_OIIO off) drawing works but text and writing throw Error.
#pragma once

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include <glm/glm.hpp>

namespace gridrt::plot {

// Viridis (matplotlib's perceptually uniform map, as a 256-entry table) at t in [0, 1] (clamped;
// NaN: 0).
glm::vec3 viridis(float t);

// A few fixed colours for categories (legends), chosen to stay apart from viridis and each other.
namespace colors {
inline constexpr glm::vec3 white{1.0f}, black{0.0f}, grey{0.55f}, light_grey{0.85f}, dark_grey{0.25f};
inline constexpr glm::vec3 red{0.86f, 0.15f, 0.15f}, orange{1.0f, 0.6f, 0.1f}, blue{0.15f, 0.35f, 0.85f};
inline constexpr glm::vec3 green{0.2f, 0.7f, 0.3f}, magenta{0.85f, 0.2f, 0.75f};
}  // namespace colors

enum class Align { left, center, right };

// Whether this build can set text and write figures (has OpenImageIO and a DejaVu font).
bool available();

class Canvas {
 public:
  Canvas(uint32_t width, uint32_t height, glm::vec3 background = colors::white);
  uint32_t width() const { return w_; }
  uint32_t height() const { return h_; }
  glm::vec3 at(int x, int y) const { return px_[size_t(y) * w_ + size_t(x)]; }

  void set(int x, int y, glm::vec3 c);
  void rect(int x0, int y0, int x1, int y1, glm::vec3 c);     // filled, [x0, x1) x [y0, y1)
  void frame(int x0, int y0, int x1, int y1, glm::vec3 c);    // outline of the same box
  void line(int x0, int y0, int x1, int y1, glm::vec3 c, int thickness = 1);
  void marker(int cx, int cy, int radius, glm::vec3 c);       // a filled square
  // An image of w x h colours (row 0 at the top), each pixel drawn as scale x scale.
  void image(int x, int y, uint32_t w, uint32_t h, const std::vector<glm::vec3>& rgb, int scale = 1);
  // Text with its baseline at y; `size` in pixels. Returns the width it took.
  int text(int x, int y, const std::string& s, glm::vec3 c = colors::black, int size = 14, Align align = Align::left,
           bool bold = false);
  // Text turned a quarter left (for a y axis' label), centred on (x, y).
  void text_vertical(int x, int y, const std::string& s, glm::vec3 c = colors::black, int size = 14);
  static int text_width(const std::string& s, int size = 14, bool bold = false);

  // Writes the canvas as an 8-bit image (.png and whatever OpenImageIO writes); a temporary file
  // renamed over `path`.
  void write(const std::string& path) const;

 private:
  uint32_t w_, h_;
  std::vector<glm::vec3> px_;
};

// A vertical colour bar at (x, y), w x h, from lo (bottom) to hi (top), with `ticks` labelled
// values and a label above. `integer`: tick labels without decimals.
struct ColorBar {
  float lo = 0.0f, hi = 1.0f;
  std::string label;
  bool integer = true;
};
void draw_color_bar(Canvas& c, int x, int y, int w, int h, const ColorBar& bar, int ticks = 5);

// Swatches and their names, one a line, from (x, y) down. Returns the height it took.
using LegendEntry = std::pair<glm::vec3, std::string>;
int draw_legend(Canvas& c, int x, int y, const std::vector<LegendEntry>& entries, int size = 13);

// A figure of one image: a title (and a subtitle) above, the image (scaled), and at its right a
// colour bar or a legend (or both: the legend below the bar). The canvas is sized to fit.
struct ImageFigure {
  std::string title, subtitle;
  uint32_t width = 0, height = 0;
  std::vector<glm::vec3> rgb;  // display colours, row 0 at the top
  int scale = 1;
  bool has_bar = false;
  ColorBar bar;
  std::vector<LegendEntry> legend;
};
Canvas draw_image_figure(const ImageFigure& f);

// Axes of an x/y plot in the box [left, right] x [top, bottom] of a canvas, over the data ranges:
// a frame, grid lines and labelled ticks at "nice" values, axis labels.
class Axes {
 public:
  Axes(Canvas& c, int left, int top, int right, int bottom, double x0, double x1, double y0, double y1);
  void draw(const std::string& xlabel, const std::string& ylabel, int ticks = 5);
  int x(double v) const;
  int y(double v) const;

 private:
  Canvas& c_;
  int l_, t_, r_, b_;
  double x0_, x1_, y0_, y1_;
};

// Tick values: "nice" steps (1, 2, 5 times a power of ten) covering [lo, hi], about n of them.
std::vector<double> nice_ticks(double lo, double hi, int n);
// A tick's label: as few decimals as the step needs.
std::string tick_label(double v, double step);

}  // namespace gridrt::plot
