#include "gridrt/common/plot.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "gridrt/common/image_io.h"
#include "gridrt/common/scene.h"
#ifdef GRIDRT_WITH_OIIO
#  include <OpenImageIO/imagebuf.h>
#  include <OpenImageIO/imagebufalgo.h>
#endif

namespace gridrt::plot {

namespace {

// Matplotlib's viridis (its 256-entry table, CC0): every 8th entry, index 0 to 248, and the last
// (255); linear between them (at most 1/255 off the full table in any channel).
constexpr std::array<std::array<float, 3>, 33> kViridis{{
    {0.267004f, 0.004874f, 0.329415f}, {0.277018f, 0.050344f, 0.375715f}, {0.282327f, 0.094955f, 0.417331f},
    {0.282884f, 0.135920f, 0.453427f}, {0.278826f, 0.175490f, 0.483397f}, {0.270595f, 0.214069f, 0.507052f},
    {0.258965f, 0.251537f, 0.524736f}, {0.244972f, 0.287675f, 0.537260f}, {0.229739f, 0.322361f, 0.545706f},
    {0.214298f, 0.355619f, 0.551184f}, {0.199430f, 0.387607f, 0.554642f}, {0.185556f, 0.418570f, 0.556753f},
    {0.172719f, 0.448791f, 0.557885f}, {0.160665f, 0.478540f, 0.558115f}, {0.149039f, 0.508051f, 0.557250f},
    {0.137770f, 0.537492f, 0.554906f}, {0.127568f, 0.566949f, 0.550556f}, {0.120565f, 0.596422f, 0.543611f},
    {0.120638f, 0.625828f, 0.533488f}, {0.132268f, 0.655014f, 0.519661f}, {0.157851f, 0.683765f, 0.501686f},
    {0.196571f, 0.711827f, 0.479221f}, {0.246070f, 0.738910f, 0.452024f}, {0.304148f, 0.764704f, 0.419943f},
    {0.369214f, 0.788888f, 0.382914f}, {0.440137f, 0.811138f, 0.340967f}, {0.515992f, 0.831158f, 0.294279f},
    {0.595839f, 0.848717f, 0.243329f}, {0.678489f, 0.863742f, 0.189503f}, {0.762373f, 0.876424f, 0.137064f},
    {0.845561f, 0.887322f, 0.099702f}, {0.926106f, 0.897330f, 0.104071f}, {0.993248f, 0.906157f, 0.143936f},
}};

// The DejaVu fonts of fonts-dejavu-core; empty when none is installed.
const std::string& font_path(bool bold) {
  static const std::string regular = [] {
    for (const char* p : {"/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf", "/usr/share/fonts/dejavu/DejaVuSans.ttf"})
      if (std::filesystem::exists(p)) return std::string(p);
    return std::string();
  }();
  static const std::string heavy = [] {
    for (const char* p : {"/usr/share/fonts/truetype/dejavu/DejaVuSans-Bold.ttf", "/usr/share/fonts/dejavu/DejaVuSans-Bold.ttf"})
      if (std::filesystem::exists(p)) return std::string(p);
    return regular;
  }();
  return bold ? heavy : regular;
}

void require_text() {
#ifndef GRIDRT_WITH_OIIO
  throw Error("figures need OpenImageIO (this build has none)");
#endif
  if (font_path(false).empty())
    throw Error("figures need the DejaVu fonts (Debian: fonts-dejavu-core; /usr/share/fonts/truetype/dejavu/DejaVuSans.ttf)");
}

}  // namespace

glm::vec3 viridis(float t) {
  if (!(t > 0.0f)) t = 0.0f;
  t = std::min(t, 1.0f);
  // Entry i < 32 sits at 8i/255, the last at 1.
  const float idx = t * 255.0f;
  size_t i = std::min<size_t>(size_t(idx / 8.0f), 31);
  const float a = float(i * 8), b = i == 31 ? 255.0f : float(i * 8 + 8);
  const float s = std::clamp((idx - a) / (b - a), 0.0f, 1.0f);
  const auto& p = kViridis[i];
  const auto& q = kViridis[i + 1];
  return {p[0] + s * (q[0] - p[0]), p[1] + s * (q[1] - p[1]), p[2] + s * (q[2] - p[2])};
}

bool available() {
#ifdef GRIDRT_WITH_OIIO
  return !font_path(false).empty();
#else
  return false;
#endif
}

Canvas::Canvas(uint32_t width, uint32_t height, glm::vec3 background)
    : w_(width), h_(height), px_(size_t(width) * height, background) {}

void Canvas::set(int x, int y, glm::vec3 c) {
  if (x >= 0 && y >= 0 && x < int(w_) && y < int(h_)) px_[size_t(y) * w_ + size_t(x)] = c;
}

void Canvas::rect(int x0, int y0, int x1, int y1, glm::vec3 c) {
  for (int y = std::max(y0, 0); y < std::min(y1, int(h_)); ++y)
    for (int x = std::max(x0, 0); x < std::min(x1, int(w_)); ++x) px_[size_t(y) * w_ + size_t(x)] = c;
}

void Canvas::frame(int x0, int y0, int x1, int y1, glm::vec3 c) {
  line(x0, y0, x1 - 1, y0, c);
  line(x0, y1 - 1, x1 - 1, y1 - 1, c);
  line(x0, y0, x0, y1 - 1, c);
  line(x1 - 1, y0, x1 - 1, y1 - 1, c);
}

void Canvas::line(int x0, int y0, int x1, int y1, glm::vec3 c, int thickness) {
  const int n = std::max(std::abs(x1 - x0), std::abs(y1 - y0));
  const int lo = -(thickness - 1) / 2, hi = thickness / 2;
  for (int i = 0; i <= n; ++i) {
    const double s = n ? double(i) / n : 0.0;
    const int x = int(std::lround(x0 + s * (x1 - x0))), y = int(std::lround(y0 + s * (y1 - y0)));
    for (int dy = lo; dy <= hi; ++dy)
      for (int dx = lo; dx <= hi; ++dx) set(x + dx, y + dy, c);
  }
}

void Canvas::marker(int cx, int cy, int r, glm::vec3 c) { rect(cx - r, cy - r, cx + r + 1, cy + r + 1, c); }

void Canvas::image(int x, int y, uint32_t w, uint32_t h, const std::vector<glm::vec3>& rgb, int scale) {
  for (uint32_t j = 0; j < h; ++j)
    for (uint32_t i = 0; i < w; ++i)
      rect(x + int(i) * scale, y + int(j) * scale, x + int(i + 1) * scale, y + int(j + 1) * scale,
           rgb[size_t(j) * w + i]);
}

int Canvas::text_width(const std::string& s, int size, bool bold) {
  if (s.empty()) return 0;
  require_text();
#ifdef GRIDRT_WITH_OIIO
  const OIIO::ROI r = OIIO::ImageBufAlgo::text_size(s, size, font_path(bold));
  return r.defined() ? r.width() : 0;
#else
  (void)size, (void)bold;
  return 0;
#endif
}

int Canvas::text(int x, int y, const std::string& s, glm::vec3 c, int size, Align align, bool bold) {
  if (s.empty()) return 0;
  require_text();
#ifdef GRIDRT_WITH_OIIO
  const int w = text_width(s, size, bold);
  if (align == Align::center) x -= w / 2;
  if (align == Align::right) x -= w;
  // Text wholly outside the canvas is not set (OpenImageIO asserts on it)
  if (x >= int(w_) || x + w <= 0 || y - size >= int(h_) || y + size / 2 <= 0) return w;
  OIIO::ImageBuf buf(OIIO::ImageSpec(int(w_), int(h_), 3, OIIO::TypeDesc::FLOAT), px_.data());
  const float color[3] = {c.r, c.g, c.b};
  if (!OIIO::ImageBufAlgo::render_text(buf, x, y, s, size, font_path(bold), color))
    throw Error("cannot set text '" + s + "': " + buf.geterror());
  return w;
#else
  (void)x, (void)y, (void)c, (void)size, (void)align, (void)bold;
  return 0;
#endif
}

void Canvas::text_vertical(int x, int y, const std::string& s, glm::vec3 c, int size) {
  if (s.empty()) return;
  // Set the text on a small canvas of its own, then copy it turned a quarter left.
  const int w = text_width(s, size) + 4, h = size + size / 2;
  Canvas t(uint32_t(w), uint32_t(h), glm::vec3(-1.0f));
  t.text(2, size, s, c, size);
  const glm::vec3 bg(-1.0f);
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      const glm::vec3 v = t.at(i, j);
      if (v == bg) continue;
      // coverage blend: render_text blends with the background (-1), recover it
      const glm::vec3 over = (v - bg) / (c - bg + glm::vec3(1e-6f));
      const float a = std::clamp((over.x + over.y + over.z) / 3.0f, 0.0f, 1.0f);
      const int px = x - h / 2 + j, py = y + w / 2 - i;
      if (px >= 0 && py >= 0 && px < int(w_) && py < int(h_)) {
        glm::vec3& d = px_[size_t(py) * w_ + size_t(px)];
        d = d * (1.0f - a) + c * a;
      }
    }
}

void Canvas::write(const std::string& path) const {
  require_text();
  std::vector<uint8_t> rgba(size_t(w_) * h_ * 4);
  for (size_t i = 0; i < px_.size(); ++i) {
    for (int k = 0; k < 3; ++k) rgba[i * 4 + size_t(k)] = uint8_t(std::lround(std::clamp(px_[i][k], 0.0f, 1.0f) * 255.0f));
    rgba[i * 4 + 3] = 255;
  }
  write_image_rgba8(path, w_, h_, rgba);
}

std::vector<double> nice_ticks(double lo, double hi, int n) {
  if (!(hi > lo)) return {lo};
  const double raw = (hi - lo) / std::max(n, 1);
  const double p = std::pow(10.0, std::floor(std::log10(raw)));
  double step = p;
  for (double m : {1.0, 2.0, 5.0, 10.0})
    if (m * p >= raw) {
      step = m * p;
      break;
    }
  // By index: a step below the values' ulp (a range of a few ulps far from 0) left v where it was
  std::vector<double> out;
  const double k0 = std::ceil(lo / step - 1e-9);
  for (int i = 0; i < 64; ++i) {
    const double v = (k0 + i) * step;
    if (!(v <= hi + step * 1e-9)) break;
    if (!out.empty() && v <= out.back()) continue;
    out.push_back(std::abs(v) < step * 1e-9 ? 0.0 : v);
  }
  if (out.empty()) out.push_back(lo);
  return out;
}

std::string tick_label(double v, double step) {
  int digits = 0;
  while (digits < 6 && std::abs(step * std::pow(10.0, digits) - std::round(step * std::pow(10.0, digits))) > 1e-6) ++digits;
  char b[64];
  std::snprintf(b, sizeof b, "%.*f", digits, v);
  return b;
}

void draw_color_bar(Canvas& c, int x, int y, int w, int h, const ColorBar& bar, int ticks) {
  c.text(x, y - 8, bar.label, colors::black, 13);
  for (int j = 0; j < h; ++j) c.rect(x, y + j, x + w, y + j + 1, viridis(1.0f - float(j) / float(std::max(h - 1, 1))));
  c.frame(x, y, x + w, y + h, colors::dark_grey);
  const double lo = bar.lo, hi = bar.hi > bar.lo ? bar.hi : bar.lo + 1.0;
  std::vector<double> t = nice_ticks(lo, hi, ticks);
  if (bar.integer) {
    std::vector<double> ints;
    for (double v : t)
      if (std::abs(v - std::round(v)) < 1e-9) ints.push_back(v);
    if (ints.empty()) ints = {lo, hi};
    t = ints;
  }
  const double step = t.size() > 1 ? t[1] - t[0] : 1.0;
  for (double v : t) {
    const int py = y + h - 1 - int(std::lround((v - lo) / (hi - lo) * (h - 1)));
    c.line(x + w, py, x + w + 4, py, colors::dark_grey);
    c.text(x + w + 7, py + 5, bar.integer ? tick_label(v, 1.0) : tick_label(v, step), colors::black, 12);
  }
}

int draw_legend(Canvas& c, int x, int y, const std::vector<LegendEntry>& entries, int size) {
  const int line = size + 8;
  for (size_t i = 0; i < entries.size(); ++i) {
    const int top = y + int(i) * line;
    c.rect(x, top, x + size, top + size, entries[i].first);
    c.frame(x, top, x + size, top + size, colors::dark_grey);
    c.text(x + size + 6, top + size - 2, entries[i].second, colors::black, size);
  }
  return int(entries.size()) * line;
}

Canvas draw_image_figure(const ImageFigure& f) {
  require_text();
  const int pad = 12, title_h = f.subtitle.empty() ? 30 : 48;
  const int iw = int(f.width) * f.scale, ih = int(f.height) * f.scale;
  int side = 0;
  if (f.has_bar) side = std::max(side, 20 + 8 + Canvas::text_width(tick_label(f.bar.hi, 1.0) + ".00", 12) + 8);
  if (f.has_bar) side = std::max(side, Canvas::text_width(f.bar.label, 13));
  for (const LegendEntry& e : f.legend) side = std::max(side, 13 + 6 + Canvas::text_width(e.second, 13));
  const int legend_h = int(f.legend.size()) * 21;
  // The bar's height, and the legend below it: the body holds both (the legend was placed below
  // the canvas for images about 200-280 pixels high, and OpenImageIO aborted: an outside sweep)
  const int bh = std::max(std::min(ih - 18, 260), 150);
  const int body_h = std::max(ih, (f.has_bar ? 18 + bh + 24 : 0) + legend_h + 20);
  const int width = std::max(pad + iw + (side ? pad * 2 + side : 0) + pad, Canvas::text_width(f.title, 16, true) + 2 * pad);
  Canvas c(uint32_t(width), uint32_t(title_h + body_h + pad));
  c.text(pad, 22, f.title, colors::black, 16, Align::left, true);
  if (!f.subtitle.empty()) c.text(pad, 41, f.subtitle, colors::dark_grey, 12);
  const int top = title_h;
  c.image(pad, top, f.width, f.height, f.rgb, f.scale);
  c.frame(pad - 1, top - 1, pad + iw + 1, top + ih + 1, colors::grey);
  int sy = top + 18;
  const int sx = pad + iw + 2 * pad;
  if (f.has_bar) {
    draw_color_bar(c, sx, sy, 20, bh, f.bar);
    sy += bh + 24;
  }
  if (!f.legend.empty()) draw_legend(c, sx, f.has_bar ? sy : top, f.legend);
  return c;
}

Axes::Axes(Canvas& c, int left, int top, int right, int bottom, double x0, double x1, double y0, double y1)
    : c_(c), l_(left), t_(top), r_(right), b_(bottom), x0_(x0), x1_(x1 > x0 ? x1 : x0 + 1.0), y0_(y0),
      y1_(y1 > y0 ? y1 : y0 + 1.0) {}

int Axes::x(double v) const { return int(std::lround(l_ + (r_ - l_) * (v - x0_) / (x1_ - x0_))); }
int Axes::y(double v) const { return int(std::lround(b_ - (b_ - t_) * (v - y0_) / (y1_ - y0_))); }

void Axes::draw(const std::string& xlabel, const std::string& ylabel, int ticks) {
  const std::vector<double> xt = nice_ticks(x0_, x1_, ticks), yt = nice_ticks(y0_, y1_, ticks);
  const double xs = xt.size() > 1 ? xt[1] - xt[0] : 1.0, ys = yt.size() > 1 ? yt[1] - yt[0] : 1.0;
  for (double v : xt) {
    c_.line(x(v), t_, x(v), b_, colors::light_grey);
    c_.text(x(v), b_ + 18, tick_label(v, xs), colors::black, 12, Align::center);
  }
  for (double v : yt) {
    c_.line(l_, y(v), r_, y(v), colors::light_grey);
    c_.text(l_ - 6, y(v) + 4, tick_label(v, ys), colors::black, 12, Align::right);
  }
  c_.frame(l_, t_, r_ + 1, b_ + 1, colors::black);
  c_.text((l_ + r_) / 2, b_ + 40, xlabel, colors::black, 13, Align::center);
  c_.text_vertical(l_ - 58, (t_ + b_) / 2, ylabel, colors::black, 13);
}

}  // namespace gridrt::plot
