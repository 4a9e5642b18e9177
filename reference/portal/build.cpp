// build.cpp: maximal divs, flux density, the per-face choice, packing (build.h).
#include "gridrt/reference/portal/build.h"
#include "gridrt/common/parallel.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <random>
#include <thread>

#include "gridrt/common/progress.h"
#include "gridrt/common/safe_io.h"
#include "gridrt/common/util.h"

namespace gridrt::portal {

namespace {

using Clock = std::chrono::steady_clock;

unsigned thread_count(unsigned requested) { return thread_count_or_hardware(requested); }

glm::ivec3 axis_unit(uint32_t a) {
  glm::ivec3 u(0);
  u[int(a)] = 1;
  return u;
}

}  // namespace

glm::ivec2 face_extent(const Box& b, uint32_t face) {
  const uint32_t a = face / 2;
  const glm::ivec3 s = b.size();
  return {s[int(shared::portal_tangent0(a))], s[int(shared::portal_tangent1(a))]};
}

// ---- Maximal divs ----------------------------------------------------------------------------

std::vector<Box> maximal_divs(const World& world, unsigned threads, size_t max_boxes) {
  const int X = int(world.dims.x), Y = int(world.dims.y), Z = int(world.dims.z);
  // Media present.
  std::vector<uint32_t> media;
  for (int z = 0; z < Z; ++z)
    for (int y = 0; y < Y; ++y)
      for (int x = 0; x < X; ++x) {
        const uint32_t m = world.medium({x, y, z});
        if (m != World::kOpaque && std::find(media.begin(), media.end(), m) == media.end()) media.push_back(m);
      }
  std::sort(media.begin(), media.end());
  std::vector<Box> all;
  for (const uint32_t m : media) {
    // Per-layer summed-area tables of "voxel is of medium m": sat[z][(y+1)*(X+1) + x+1].
    const size_t S = size_t(X + 1) * (Y + 1);
    std::vector<int32_t> sat(S * Z, 0);
    std::vector<uint8_t> in(size_t(X) * Y * Z);
    for (int z = 0; z < Z; ++z)
      for (int y = 0; y < Y; ++y)
        for (int x = 0; x < X; ++x) {
          const uint8_t v = world.medium({x, y, z}) == m;
          in[x + size_t(X) * (y + size_t(Y) * z)] = v;
          int32_t* s = &sat[S * z];
          s[(y + 1) * (X + 1) + x + 1] = v + s[y * (X + 1) + x + 1] + s[(y + 1) * (X + 1) + x] - s[y * (X + 1) + x];
        }
    auto full = [&](int z, int x0, int x1, int y0, int y1) {  // layer z entirely of medium m over the rectangle
      if (z < 0 || z >= Z) return false;
      const int32_t* s = &sat[S * z];
      const int32_t c = s[y1 * (X + 1) + x1] - s[y0 * (X + 1) + x1] - s[y1 * (X + 1) + x0] + s[y0 * (X + 1) + x0];
      return c == (x1 - x0) * (y1 - y0);
    };
    std::vector<std::vector<Box>> found(Z);
    std::atomic<size_t> total{all.size()};
    std::atomic<bool> too_many{false};
    parallel_for(size_t(Z), thread_count(threads), [&](size_t zi) {
      const int z0 = int(zi);
      if (too_many.load(std::memory_order_relaxed)) return;
      std::vector<uint8_t> mask(size_t(X) * Y, 1);
      std::vector<int> h(X + 1), rowcount(X + 1);
      std::vector<std::pair<int, int>> stack;  // (start, height)
      for (int z1 = z0; z1 < Z; ++z1) {
        if (max_boxes && total.load(std::memory_order_relaxed) > max_boxes) {
          too_many = true;
          return;
        }
        bool any = false;
        for (int y = 0; y < Y; ++y)
          for (int x = 0; x < X; ++x) {
            uint8_t& mk = mask[x + size_t(X) * y];
            mk = mk && in[x + size_t(X) * (y + size_t(Y) * z1)];
            any = any || mk;
          }
        if (!any) break;
        // Maximal rectangles of the mask: rows y, heights h[x] = run of mask cells ending at row y.
        std::fill(h.begin(), h.end(), 0);
        for (int y = 0; y < Y; ++y) {
          for (int x = 0; x < X; ++x) h[x] = mask[x + size_t(X) * y] ? h[x] + 1 : 0;
          h[X] = 0;
          // Prefix counts of mask cells in row y + 1: a rectangle ending at row y is maximal downwards
          // iff row y + 1 is not all mask over its span.
          rowcount[0] = 0;
          for (int x = 0; x < X; ++x) rowcount[x + 1] = rowcount[x] + (y + 1 < Y ? mask[x + size_t(X) * (y + 1)] : 0);
          stack.clear();
          for (int x = 0; x <= X; ++x) {
            int start = x;
            while (!stack.empty() && stack.back().second > h[x]) {
              const auto [s, ht] = stack.back();
              stack.pop_back();
              start = s;
              // Rectangle columns [s, x), rows [y - ht + 1, y].
              const bool down_blocked = y + 1 >= Y || rowcount[x] - rowcount[s] < x - s;
              if (down_blocked && !full(z0 - 1, s, x, y - ht + 1, y + 1) && !full(z1 + 1, s, x, y - ht + 1, y + 1)) {
                found[zi].push_back(Box{{s, y - ht + 1, z0}, {x, y + 1, z1 + 1}, m});
                total.fetch_add(1, std::memory_order_relaxed);
              }
            }
            if (h[x] > 0 && (stack.empty() || stack.back().second < h[x])) stack.push_back({start, h[x]});
          }
        }
      }
    });
    if (too_many)
      throw Error("portal build: world '" + world.name + "' has more than " + std::to_string(max_boxes) +
                  " maximal divs, the limit of the exact choice (use the bounded choice)");
    for (auto& f : found) all.insert(all.end(), f.begin(), f.end());
  }
  std::sort(all.begin(), all.end(), [](const Box& a, const Box& b) {
    if (a.medium != b.medium) return a.medium < b.medium;
    for (int i = 2; i >= 0; --i)
      if (a.lo[i] != b.lo[i]) return a.lo[i] < b.lo[i];
    for (int i = 2; i >= 0; --i)
      if (a.hi[i] != b.hi[i]) return a.hi[i] < b.hi[i];
    return false;
  });
  return all;
}

// ---- Flux density ----------------------------------------------------------------------------

float FluxDensity::x_face(int p, int j, int k) const {
  if (p < 1 || p > range || j < 0 || j >= range || k < 0 || k >= range) return 0.0f;
  return plane_x[(size_t(p - 1) * range + j) * range + k];
}
float FluxDensity::z_face(int i, int j, int q) const {
  if (q < 1 || q > range || i < 0 || i >= range || j < 0 || j >= range) return 0.0f;
  return plane_z[(size_t(i) * range + j) * range + (q - 1)];
}

double FluxDensity::length_sum(int i0, int i1, int j0, int j1, int k0, int k1) const {
  const int R = range, R1 = R + 1;
  auto sat = [&](int i, int j, int k) { return length_sat[(size_t(i) * R1 + j) * R1 + k]; };
  auto box = [&](int a0, int a1, int b0, int b1, int c0, int c1) {  // nonnegative, clamped
    a0 = std::clamp(a0, 0, R), a1 = std::clamp(a1, 0, R), b0 = std::clamp(b0, 0, R), b1 = std::clamp(b1, 0, R);
    c0 = std::clamp(c0, 0, R), c1 = std::clamp(c1, 0, R);
    if (a0 >= a1 || b0 >= b1 || c0 >= c1) return 0.0;
    return sat(a1, b1, c1) - sat(a0, b1, c1) - sat(a1, b0, c1) - sat(a1, b1, c0) + sat(a0, b0, c1) + sat(a0, b1, c0) +
           sat(a1, b0, c0) - sat(a0, b0, c0);
  };
  // Fold a signed range [l, h) into up to two nonnegative ranges (|i| for i < 0 is -i).
  auto fold = [](int l, int h, int out[4]) {
    int n = 0;
    if (l < 0) {  // i in [l, min(h, 0)): |i| in [1 - min(h, 0), 1 - l)
      out[n++] = 1 - std::min(h, 0);
      out[n++] = 1 - l;
    }
    const int pl = std::max(l, 0);
    if (h > pl) out[n++] = pl, out[n++] = h;
    return n / 2;
  };
  int fi[4], fj[4];
  const int ni = fold(i0, i1, fi), nj = fold(j0, j1, fj);
  double s = 0.0;
  for (int a = 0; a < ni; ++a)
    for (int b = 0; b < nj; ++b) s += box(fi[2 * a], fi[2 * a + 1], fj[2 * b], fj[2 * b + 1], k0, k1);
  return s;
}

FluxDensity FluxDensity::compute(int range, uint32_t rays) {
  FluxDensity f;
  f.range = range;
  f.rays = rays;
  const int R = range;
  const size_t n3 = size_t(R) * R * R;
  const unsigned T = thread_count(0);
  const uint32_t chunks = 64;
  // The chunks in waves of at most 8 (one per thread), each wave's tables added to the sums in
  // chunk order, as all 64 at once were: the same sums, in 8 x 6 MiB of tables where the 64
  // took 400 MiB for every portal world (an outside sweep measured 530 MB for a world of 2 divs)
  const uint32_t wave = std::clamp<uint32_t>(T, 1u, 8u);
  std::vector<std::vector<double>> px(wave), pz(wave), len(wave);
  f.plane_x.assign(n3, 0.0f), f.plane_z.assign(n3, 0.0f);
  std::vector<double> L(n3, 0.0);
  for (uint32_t c0 = 0; c0 < chunks; c0 += wave) {
    const uint32_t in_wave = std::min(wave, chunks - c0);
    parallel_for(in_wave, T, [&](size_t w) {
      const uint32_t c = c0 + uint32_t(w);
      std::vector<double>& PX = px[w];
      std::vector<double>& PZ = pz[w];
      std::vector<double>& Lc = len[w];
      PX.assign(n3, 0.0), PZ.assign(n3, 0.0), Lc.assign(n3, 0.0);
      std::mt19937_64 rng(0x9E3779B97F4A7C15ull + c);
      std::uniform_real_distribution<double> U(0.0, 1.0);
      const uint32_t begin = uint32_t(uint64_t(rays) * c / chunks), end = uint32_t(uint64_t(rays) * (c + 1) / chunks);
      const double kPi = 3.14159265358979323846;
      for (uint32_t r = begin; r < end; ++r) {
        // Origin uniform on the unit square, direction cosine-distributed, folded into x, y >= 0.
        double ox = U(rng), oy = U(rng);
        const double u1 = U(rng), u2 = U(rng);
        const double sr = std::sqrt(u1), phi = 2.0 * kPi * u2;
        double dx = sr * std::cos(phi), dy = sr * std::sin(phi);
        const double dz = std::sqrt(std::max(1.0 - u1, 1e-12));
        if (dx < 0) dx = -dx, ox = 1.0 - ox;
        if (dy < 0) dy = -dy, oy = 1.0 - oy;
        // Voxel walk from voxel (0, 0, 0), t = distance (|d| = 1).
        int i = 0, j = 0, k = 0;
        double t = 0.0;
        const double tdx = dx > 0 ? 1.0 / dx : 1e300, tdy = dy > 0 ? 1.0 / dy : 1e300, tdz = 1.0 / dz;
        double nx = (1.0 - ox) * tdx, ny = (1.0 - oy) * tdy, nz = tdz;
        if (dx <= 0) nx = 1e300;
        if (dy <= 0) ny = 1e300;
        for (;;) {
          const size_t cell = (size_t(i) * R + j) * R + k;
          if (nx <= ny && nx <= nz) {
            Lc[cell] += nx - t, t = nx, nx += tdx;
            PX[(size_t(i) * R + j) * R + k] += 1.0;  // plane x = i + 1
            if (++i >= R) break;
          } else if (ny <= nz) {
            Lc[cell] += ny - t, t = ny, ny += tdy;
            PX[(size_t(j) * R + i) * R + k] += 1.0;  // plane y = j + 1: by the x <-> y symmetry, table x
            if (++j >= R) break;
          } else {
            Lc[cell] += nz - t, t = nz, nz += tdz;
            PZ[(size_t(i) * R + j) * R + k] += 1.0;      // plane z = k + 1
            if (++k >= R) break;
          }
        }
      }
    });
    for (uint32_t w = 0; w < in_wave; ++w)
      for (size_t q = 0; q < n3; ++q) {
        f.plane_x[q] += float(px[w][q]);
        f.plane_z[q] += float(pz[w][q]);
        L[q] += len[w][q];
      }
  }
  // Unfold: a folded index stands for its mirror images (plane p for planes p and 1 - p; voxel
  // index i > 0 for i and -i), and the x table holds the x and the y planes together. Divide by
  // the number of images so that each entry is the flux of one face of space.
  auto images = [](int i) { return i > 0 ? 2.0 : 1.0; };
  for (int a = 0; a < R; ++a)
    for (int bb = 0; bb < R; ++bb)
      for (int k = 0; k < R; ++k) {
        const size_t q = (size_t(a) * R + bb) * R + k;
        f.plane_x[q] = float(double(f.plane_x[q]) / (double(rays) * 2.0 * 2.0 * images(bb)));  // a: plane, bb: row
        f.plane_z[q] = float(double(f.plane_z[q]) / (double(rays) * images(a) * images(bb)));  // a, bb: column
        L[q] /= images(a) * images(bb);
      }
  const int R1 = R + 1;
  f.length_sat.assign(size_t(R1) * R1 * R1, 0.0);
  auto S = [&](int a, int b, int c) -> double& { return f.length_sat[(size_t(a) * R1 + b) * R1 + c]; };
  for (int a = 1; a <= R; ++a)
    for (int b = 1; b <= R; ++b)
      for (int c = 1; c <= R; ++c)
        S(a, b, c) = L[(size_t(a - 1) * R + b - 1) * R + c - 1] / rays + S(a - 1, b, c) + S(a, b - 1, c) + S(a, b, c - 1) -
                     S(a - 1, b - 1, c) - S(a - 1, b, c - 1) - S(a, b - 1, c - 1) + S(a - 1, b - 1, c - 1);
  return f;
}

const FluxDensity& FluxDensity::get() {
  static const FluxDensity f = compute(64, 1u << 18);
  return f;
}

// ---- The heuristic ---------------------------------------------------------------------------

namespace {

// The heuristic over any medium lookup: medium(w) for voxels inside the world, kOutsideMedium
// beyond it.
constexpr uint32_t kOutsideMedium = 0xFFFFFFFEu;
template <class MediumOf>
EntryCost integrate_impl(const MediumOf& medium_of, const FluxDensity& flux, glm::ivec3 v, uint32_t entry_face,
                         const Box& div) {
  const uint32_t e = entry_face / 2;
  const int s = (entry_face & 1u) ? -1 : 1;  // rays through the -e face move +e
  const uint32_t a0 = shared::portal_tangent0(e), a1 = shared::portal_tangent1(e);
  const uint32_t med = medium_of(v);
  // The sub-cuboid the rays enter: depth k in [0, K), tangents i in [i0, i1), j in [j0, j1) (relative to v).
  const int K = s > 0 ? div.hi[e] - v[e] : v[e] - div.lo[e] + 1;
  const int i0 = div.lo[a0] - v[a0], i1 = div.hi[a0] - v[a0];
  const int j0 = div.lo[a1] - v[a1], j1 = div.hi[a1] - v[a1];
  auto voxel = [&](int i, int j, int k) {
    glm::ivec3 w = v;
    w[e] += s * k, w[a0] += i, w[a1] += j;
    return w;
  };
  auto open = [&](glm::ivec3 w) { return medium_of(w) == med; };
  const int R = flux.range;
  EntryCost c;
  // Far face: plane at depth K.
  if (K <= R)
    for (int j = std::max(j0, -R); j < std::min(j1, R); ++j)
      for (int i = std::max(i0, -R); i < std::min(i1, R); ++i) {
        const double f = flux.z_face(std::abs(i), std::abs(j), K);
        (open(voxel(i, j, K)) ? c.p_open : c.p_wall) += f;
      }
  // Side faces, tangent a0: planes i = i1 (folded p = i1) and i = i0 (folded p = 1 - i0).
  const int kmax = std::min(K, R);
  for (int side = 0; side < 2; ++side) {
    const int p = side ? 1 - i0 : i1;
    const int beyond = side ? i0 - 1 : i1;
    if (p > R) continue;
    for (int k = 0; k < kmax; ++k)
      for (int j = std::max(j0, -R); j < std::min(j1, R); ++j) {
        const double f = flux.x_face(p, std::abs(j), k);
        (open(voxel(beyond, j, k)) ? c.p_open : c.p_wall) += f;
      }
  }
  // Side faces, tangent a1 (the table is symmetric in x and y).
  for (int side = 0; side < 2; ++side) {
    const int p = side ? 1 - j0 : j1;
    const int beyond = side ? j0 - 1 : j1;
    if (p > R) continue;
    for (int k = 0; k < kmax; ++k)
      for (int i = std::max(i0, -R); i < std::min(i1, R); ++i) {
        const double f = flux.x_face(p, std::abs(i), k);
        (open(voxel(i, beyond, k)) ? c.p_open : c.p_wall) += f;
      }
  }
  c.length = flux.length_sum(i0, i1, j0, j1, 0, K);
  c.cost = c.length > 0 ? c.p_open / c.length : 1e30;
  return c;
}

// Media of all voxels, precomputed for the build's inner loop.
struct MediumGrid {
  glm::ivec3 dims;
  std::vector<uint32_t> m;
  explicit MediumGrid(const World& w) : dims(w.dims), m(w.voxel_count()) {
    for (int z = 0; z < dims.z; ++z)
      for (int y = 0; y < dims.y; ++y)
        for (int x = 0; x < dims.x; ++x) m[w.index(x, y, z)] = w.medium({x, y, z});
  }
  uint32_t operator()(glm::ivec3 v) const {
    if (uint32_t(v.x) >= uint32_t(dims.x) || uint32_t(v.y) >= uint32_t(dims.y) || uint32_t(v.z) >= uint32_t(dims.z))
      return kOutsideMedium;
    return m[size_t(v.x) + size_t(dims.x) * (size_t(v.y) + size_t(dims.y) * size_t(v.z))];
  }
};

// The same integral, exact, in O(rows + open runs) instead of O(area): the open voxel faces of
// each face of the box as runs along one tangent axis (one list per row of the other), and the
// flux table summed along rows by 1D prefix sums (folded like the table).
struct FluxPrefix {
  int R = 0;
  std::vector<double> z;  // [(j * R + (q - 1)) * (R + 1) + n] = sum over i < n of z_face(i, j, q)
  std::vector<double> x;  // [((p - 1) * R + k) * (R + 1) + n] = sum over j < n of x_face(p, j, k)
  // `limit`: the table's range cut to this many voxels (0: the whole table).
  explicit FluxPrefix(const FluxDensity& f, int limit = 0) : R(limit > 0 ? std::min(limit, f.range) : f.range) {
    z.assign(size_t(R) * R * (R + 1), 0.0);
    x.assign(size_t(R) * R * (R + 1), 0.0);
    for (int a = 0; a < R; ++a)
      for (int b = 0; b < R; ++b) {
        double* zp = &z[(size_t(a) * R + b) * (R + 1)];
        double* xp = &x[(size_t(a) * R + b) * (R + 1)];
        for (int n = 0; n < R; ++n) {
          zp[n + 1] = zp[n] + f.z_face(n, a, b + 1);
          xp[n + 1] = xp[n] + f.x_face(a + 1, n, b);
        }
      }
  }
  // Sum of g(|i|) over signed i in [l, h), g given by its prefix row P (R + 1 entries).
  double fold(const double* P, int l, int h) const {
    auto S = [&](int n) { return P[std::clamp(n, 0, R)]; };
    double sum = 0.0;
    if (l < 0) sum += S(1 - l) - S(1 - std::min(h, 0));
    const int pl = std::max(l, 0);
    if (h > pl) sum += S(h) - S(pl);
    return sum;
  }
  const double* zrow(int j, int q) const { return &z[(size_t(j) * R + (q - 1)) * (R + 1)]; }
  const double* xrow(int p, int k) const { return &x[(size_t(p - 1) * R + k) * (R + 1)]; }
};

struct FaceRuns {
  int row_axis = 0, run_axis = 0, row_lo = 0;
  std::vector<std::vector<std::pair<int, int>>> rows;  // open runs [start, end), absolute coordinates
};
struct BoxRuns {
  FaceRuns f[6][2];  // [face][0: runs along tangent0 of the face normal, 1: along tangent1]
};

BoxRuns box_runs(const MediumGrid& media, const Box& B) {
  BoxRuns r;
  for (uint32_t f = 0; f < 6; ++f) {
    const int n = int(f / 2);
    const int beyond = (f & 1u) ? B.hi[n] : B.lo[n] - 1;
    const int tg[2] = {int(shared::portal_tangent0(uint32_t(n))), int(shared::portal_tangent1(uint32_t(n)))};
    for (int d = 0; d < 2; ++d) {
      FaceRuns& fr = r.f[f][d];
      fr.run_axis = tg[d], fr.row_axis = tg[1 - d], fr.row_lo = B.lo[fr.row_axis];
      fr.rows.resize(size_t(B.hi[fr.row_axis] - B.lo[fr.row_axis]));
      for (int row = B.lo[fr.row_axis]; row < B.hi[fr.row_axis]; ++row) {
        auto& runs = fr.rows[size_t(row - fr.row_lo)];
        int start = -1;
        for (int c = B.lo[fr.run_axis]; c <= B.hi[fr.run_axis]; ++c) {
          bool open = false;
          if (c < B.hi[fr.run_axis]) {
            glm::ivec3 w;
            w[n] = beyond, w[fr.row_axis] = row, w[fr.run_axis] = c;
            open = media(w) == B.medium;
          }
          if (open && start < 0) start = c;
          if (!open && start >= 0) runs.push_back({start, c}), start = -1;
        }
      }
    }
  }
  return r;
}

EntryCost integrate_runs(const FluxPrefix& fp, const BoxRuns& runs, glm::ivec3 v, uint32_t entry_face, const Box& B) {
  const int e = int(entry_face / 2);
  const int s = (entry_face & 1u) ? -1 : 1;
  const int a0 = int(shared::portal_tangent0(uint32_t(e))), a1 = int(shared::portal_tangent1(uint32_t(e)));
  const int K = s > 0 ? B.hi[e] - v[e] : v[e] - B.lo[e] + 1;
  const int i0 = B.lo[a0] - v[a0], i1 = B.hi[a0] - v[a0];
  const int j0 = B.lo[a1] - v[a1], j1 = B.hi[a1] - v[a1];
  const int R = fp.R;
  double total = 0.0, open = 0.0;
  // Far face (normal e, on the side the rays move to): rows along a1, runs along a0.
  if (K <= R) {
    const FaceRuns& fr = runs.f[2 * e + (s > 0 ? 1 : 0)][0];
    for (int j = std::max(j0, 1 - R); j < std::min(j1, R); ++j) {
      const double* P = fp.zrow(std::abs(j), K);
      total += fp.fold(P, i0, i1);
      for (const auto& [a, b] : fr.rows[size_t(v[a1] + j - fr.row_lo)]) open += fp.fold(P, a - v[a0], b - v[a0]);
    }
  }
  // Side faces: rows along e (depth k), runs along the other tangent.
  const int kmax = std::min(K, R);
  for (int t = 0; t < 2; ++t) {
    const int n = t ? a1 : a0, other = t ? a0 : a1;
    const int lo = t ? j0 : i0, hi = t ? j1 : i1;      // the normal's range
    const int olo = t ? i0 : j0, ohi = t ? i1 : j1;    // the run axis' range
    for (int side = 0; side < 2; ++side) {
      const int p = side ? 1 - lo : hi;
      if (p > R) continue;
      const int d = other == int(shared::portal_tangent0(uint32_t(n))) ? 0 : 1;
      const FaceRuns& fr = runs.f[2 * n + (side ? 0 : 1)][d];
      for (int k = 0; k < kmax; ++k) {
        const double* P = fp.xrow(p, k);
        total += fp.fold(P, olo, ohi);
        for (const auto& [a, b] : fr.rows[size_t(v[e] + s * k - fr.row_lo)]) open += fp.fold(P, a - v[other], b - v[other]);
      }
    }
  }
  EntryCost c;
  c.p_open = open;
  c.p_wall = total - open;
  return c;
}


// The choice's sort key of candidate `bi` (box B) for rays entering v through face f: the cost as
// float bits, then the candidate index (ties to the lower index). Shared by both choices.
uint64_t entry_key(const FluxDensity& flux, const FluxPrefix& prefix, const BoxRuns& runs, glm::ivec3 v, uint32_t f,
                   const Box& B, uint32_t bi) {
  EntryCost c = integrate_runs(prefix, runs, v, f, B);
  const int e = int(f / 2), t0 = int(shared::portal_tangent0(f / 2)), t1 = int(shared::portal_tangent1(f / 2));
  c.length = flux.length_sum(B.lo[t0] - v[t0], B.hi[t0] - v[t0], B.lo[t1] - v[t1], B.hi[t1] - v[t1], 0,
                             (f & 1u) ? v[e] - B.lo[e] + 1 : B.hi[e] - v[e]);
  c.cost = c.length > 0 ? c.p_open / c.length : 1e30;
  const float cf = float(c.cost);
  uint32_t bits;
  std::memcpy(&bits, &cf, 4);
  return (uint64_t(bits) << 32) | uint64_t(bi);
}

// Summed-area table of "voxel is of medium m" over the whole world: any box's count in O(1).
struct MediumSat {
  glm::ivec3 d;
  std::vector<int32_t> s;  // (X+1)(Y+1)(Z+1)
  MediumSat(const MediumGrid& media, uint32_t m) : d(media.dims), s(size_t(d.x + 1) * (d.y + 1) * (d.z + 1), 0) {
    const size_t sx = 1, sy = size_t(d.x + 1), sz = size_t(d.x + 1) * (d.y + 1);
    for (int z = 0; z < d.z; ++z)
      for (int y = 0; y < d.y; ++y)
        for (int x = 0; x < d.x; ++x) {
          const size_t i = (x + 1) * sx + (y + 1) * sy + (z + 1) * sz;
          const int32_t v = media({x, y, z}) == m;
          s[i] = v + s[i - sx] + s[i - sy] + s[i - sz] - s[i - sx - sy] - s[i - sx - sz] - s[i - sy - sz] +
                 s[i - sx - sy - sz];
        }
  }
  int64_t count(glm::ivec3 lo, glm::ivec3 hi) const {
    const size_t sy = size_t(d.x + 1), sz = size_t(d.x + 1) * (d.y + 1);
    auto at = [&](int x, int y, int z) { return int64_t(s[x + y * sy + z * sz]); };
    return at(hi.x, hi.y, hi.z) - at(lo.x, hi.y, hi.z) - at(hi.x, lo.y, hi.z) - at(hi.x, hi.y, lo.z) +
           at(lo.x, lo.y, hi.z) + at(lo.x, hi.y, lo.z) + at(hi.x, lo.y, lo.z) - at(lo.x, lo.y, lo.z);
  }
};

// Grow the box [lo, hi) of medium m along order[0], order[1], order[2] in turn, each as far as the
// layers beyond are entirely of m: a binary search over the layer count, one O(1) query per probe.
Box grow_greedy(const MediumSat& sat, Box B, glm::ivec3 order) {
  // Grow by the largest k whose k layers beyond are all of m (monotone in k: binary search).
  auto full = [&](glm::ivec3 lo, glm::ivec3 hi) {
    const glm::ivec3 s = hi - lo;
    return sat.count(lo, hi) == int64_t(s.x) * s.y * s.z;
  };
  for (int t = 0; t < 3; ++t) {
    const int a = order[t];
    int lo = 0, hi = B.lo[a];  // largest k in [0, B.lo[a]] with layers [B.lo[a] - k, B.lo[a]) full
    while (lo < hi) {
      const int k = (lo + hi + 1) / 2;
      glm::ivec3 l = B.lo, h = B.hi;
      h[a] = B.lo[a], l[a] = B.lo[a] - k;
      if (full(l, h)) lo = k;
      else hi = k - 1;
    }
    const int down = lo;
    lo = 0, hi = sat.d[a] - B.hi[a];
    while (lo < hi) {
      const int k = (lo + hi + 1) / 2;
      glm::ivec3 l = B.lo, h = B.hi;
      l[a] = B.hi[a], h[a] = B.hi[a] + k;
      if (full(l, h)) lo = k;
      else hi = k - 1;
    }
    B.lo[a] -= down, B.hi[a] += lo;
  }
  return B;
}

// Grow along axes b1 and b2 one layer at a time in turn (b1 down, b1 up, b2 down, b2 up), until
// no layer can be added: a squarer maximal box than the greedy ones (the box can no longer grow
// along the run's axis, blocked at its thinnest stage).
Box grow_alternating(const MediumSat& sat, Box B, int b1, int b2) {
  auto full = [&](glm::ivec3 lo, glm::ivec3 hi) {
    const glm::ivec3 s = hi - lo;
    return sat.count(lo, hi) == int64_t(s.x) * s.y * s.z;
  };
  for (bool grew = true; grew;) {
    grew = false;
    for (const int a : {b1, b2}) {
      if (B.lo[a] > 0) {
        glm::ivec3 l = B.lo, h = B.hi;
        h[a] = B.lo[a], l[a] = B.lo[a] - 1;
        if (full(l, h)) B.lo[a] -= 1, grew = true;
      }
      if (B.hi[a] < sat.d[a]) {
        glm::ivec3 l = B.lo, h = B.hi;
        l[a] = B.hi[a], h[a] = B.hi[a] + 1;
        if (full(l, h)) B.hi[a] += 1, grew = true;
      }
    }
  }
  return B;
}

bool box_less(const Box& a, const Box& b) {
  if (a.medium != b.medium) return a.medium < b.medium;
  for (int i = 2; i >= 0; --i)
    if (a.lo[i] != b.lo[i]) return a.lo[i] < b.lo[i];
  for (int i = 2; i >= 0; --i)
    if (a.hi[i] != b.hi[i]) return a.hi[i] < b.hi[i];
  return false;
}

// The runs of passable voxels of one medium along each axis: id[a][voxel] (kNone where opaque),
// and each run's first voxel.
struct AxisRuns {
  glm::ivec3 dims;
  size_t stride[3];
  std::vector<uint32_t> id[3];
  std::vector<uint32_t> start[3];
  glm::ivec3 coords(size_t i) const {
    return glm::ivec3(int(i % dims.x), int((i / dims.x) % dims.y), int(i / (size_t(dims.x) * dims.y)));
  }
};

AxisRuns axis_runs(const MediumGrid& media, glm::ivec3 dims) {
  AxisRuns R{dims, {1, size_t(dims.x), size_t(dims.x) * dims.y}, {}, {}};
  const size_t N = size_t(dims.x) * dims.y * dims.z;
  for (int a = 0; a < 3; ++a) {
    R.id[a].assign(N, kNone);
    for (size_t i = 0; i < N; ++i) {
      const uint32_t m = media.m[i];
      if (m == World::kOpaque) continue;
      const glm::ivec3 v = R.coords(i);
      if (v[a] > 0 && media.m[i - R.stride[a]] == m) {
        R.id[a][i] = R.id[a][i - R.stride[a]];
      } else {
        R.id[a][i] = uint32_t(R.start[a].size());
        R.start[a].push_back(uint32_t(i));
      }
    }
  }
  return R;
}

// K greedy boxes per run along axis a: along the run's axis, then the other two axes in either
// order (k = 0, 1), and (k = 2) the alternating box. A run whose neighbour run along the second
// axis spans the same interval grows into the same box (the second growth finds the same all-m
// range, the third then starts from the same rectangle), so only the first run of each such stack
// is grown; the others copy its box. Returns the boxes, [K * run + k].
std::vector<Box> greedy_boxes(const AxisRuns& runs, const MediumGrid& media,
                              const std::function<const MediumSat&(uint32_t)>& sat_of, int a, uint32_t K, unsigned T) {
  const glm::ivec3 dims = runs.dims;
  const int o1 = (a + 1) % 3, o2 = (a + 2) % 3;
  const int b1 = std::min(o1, o2), b2 = std::max(o1, o2);
  const std::vector<uint32_t>& run_id = runs.id[a];
  const std::vector<uint32_t>& run_start = runs.start[a];
  const size_t R = run_start.size();
  auto run_end = [&](uint32_t r) {  // one past the run's last voxel along a
    glm::ivec3 v = runs.coords(run_start[r]);
    size_t i = run_start[r];
    while (v[a] < dims[a] && run_id[i] == r) ++v[a], i += runs.stride[a];
    return v[a];
  };
  std::vector<uint32_t> end(R);
  parallel_for((R + 4095) / 4096, T, [&](size_t c) {
    for (size_t r = c * 4096; r < std::min(R, (c + 1) * 4096); ++r) end[r] = uint32_t(run_end(uint32_t(r)));
  });
  std::vector<uint32_t> root(K * R);
  std::vector<uint32_t> roots;
  for (uint32_t r = 0; r < R; ++r)
    for (uint32_t k = 0; k < K; ++k) {
      if (k == 2) {  // the alternating box: no stack argument, grown for every run
        root[K * r + k] = K * r + k;
        roots.push_back(K * r + k);
        continue;
      }
      const int second = k ? b2 : b1;
      const size_t i = run_start[r];
      const glm::ivec3 v = runs.coords(i);
      uint32_t src = K * r + k;
      if (v[second] > 0) {
        const size_t j = i - runs.stride[second];
        const uint32_t q = run_id[j];
        if (q != kNone && run_start[q] == j && end[q] == end[r] && media.m[j] == media.m[i]) src = root[K * q + k];
      }
      root[K * r + k] = src;
      if (src == K * r + k) roots.push_back(src);
    }
  std::vector<Box> grown(K * R);
  const size_t chunk = 256, n = (roots.size() + chunk - 1) / chunk;
  parallel_for(n, T, [&](size_t c) {
    for (size_t x = c * chunk; x < std::min(roots.size(), (c + 1) * chunk); ++x) {
      const uint32_t r = roots[x] / K, k = roots[x] % K;
      const glm::ivec3 v = runs.coords(run_start[r]);
      const uint32_t m = media.m[run_start[r]];
      glm::ivec3 hi = v + 1;
      hi[a] = int(end[r]);
      grown[roots[x]] = k == 2   ? grow_alternating(sat_of(m), Box{v, hi, m}, b1, b2)
                        : k == 1 ? grow_greedy(sat_of(m), Box{v, hi, m}, glm::ivec3(a, b2, b1))
                                 : grow_greedy(sat_of(m), Box{v, hi, m}, glm::ivec3(a, b1, b2));
    }
  });
  for (size_t x = 0; x < K * R; ++x) grown[x] = grown[root[x]];
  return grown;
}

// The candidates of a voxel: the maximal boxes its runs grew into, up to 3 K distinct indices.
struct Candidates {
  const AxisRuns& runs;
  uint32_t K;
  std::vector<uint32_t> run_box[3];  // [K * run + k]: index into the maximal boxes
  // Voxel i's candidates, ascending; returns their count.
  int operator()(size_t i, uint32_t out[9]) const {
    int n = 0;
    for (int a = 0; a < 3; ++a)
      for (uint32_t k = 0; k < K; ++k) {
        const uint32_t c = run_box[a][K * size_t(runs.id[a][i]) + k];
        if (std::find(out, out + n, c) == out + n) out[n++] = c;
      }
    std::sort(out, out + n);
    return n;
  }
};

// Start boxes: a cover of the passable voxels. In voxel order, a voxel takes the largest of its
// candidates already in the cover, else the largest of all its candidates, which joins the cover
// (ties: lower index). The cover is far smaller than "each voxel's largest candidate", and every
// box in it is stored, so it bounds the atlas.
void start_cover(PortalBuild& b, const MediumGrid& media, const Candidates& candidates) {
  const size_t N = b.world.voxel_count();
  b.start_box.assign(N, kNone);
  std::vector<uint8_t> in_cover(b.maximal.size(), 0);
  uint32_t c[9];
  for (size_t i = 0; i < N; ++i) {
    if (media.m[i] == World::kOpaque) continue;
    const int n = candidates(i, c);
    uint32_t best = kNone, any = c[0];
    for (int k = 0; k < n; ++k) {
      if (b.maximal[c[k]].volume() > b.maximal[any].volume()) any = c[k];
      if (in_cover[c[k]] && (best == kNone || b.maximal[c[k]].volume() > b.maximal[best].volume())) best = c[k];
    }
    if (best == kNone) best = any, in_cover[any] = 1;
    b.start_box[i] = best;
  }
}

// The representative of (u, f): the first voxel, in the world-aligned block x block square of u's
// plane (normal f / 2) that holds u, whose candidates are u's (cand[0..n)). A function of the world
// alone, so the choice stays deterministic however the rounds are scheduled.
glm::ivec3 representative(const World& w, const MediumGrid& media, const Candidates& candidates, int block,
                          glm::ivec3 u, uint32_t f, const uint32_t* cand, int n) {
  if (block == 1) return u;
  const glm::ivec3 dims(w.dims);
  const int a = int(f / 2), ta = int(shared::portal_tangent0(f / 2)), tb = int(shared::portal_tangent1(f / 2));
  glm::ivec3 r = u;
  const int a0 = u[ta] / block * block, b0 = u[tb] / block * block;
  uint32_t other[9];
  for (int jb = b0; jb < std::min(b0 + block, dims[tb]); ++jb)
    for (int ia = a0; ia < std::min(a0 + block, dims[ta]); ++ia) {
      r[ta] = ia, r[tb] = jb;
      if (r == u) return u;
      const size_t ri = w.index(glm::uvec3(r));
      if (media.m[ri] != media.m[w.index(glm::uvec3(u))]) continue;
      // Rays must be able to enter r through f as they enter u: the voxel they come from passable.
      glm::ivec3 from = r;
      from[a] += (f & 1u) ? 1 : -1;
      if (w.inside(from) && media(from) == World::kOpaque) continue;
      if (candidates(ri, other) == n && std::equal(cand, cand + n, other)) return r;
    }
  return u;
}

// The closure. Faces needed: every texel of every stored div's faces whose voxel beyond is not
// opaque (and the exterior div's, the world box entered from outside). A face's choice may store
// a new div, whose faces are then needed: rounds over the frontier of new divs, each round's faces
// evaluated in parallel. Writes b.choice (kNone where no face needed a choice) and the counts.
void close_faces(PortalBuild& b, const FluxDensity& flux, const MediumGrid& media, const FluxPrefix& prefix,
                 const Candidates& candidates, const PortalOptions& opt, unsigned T) {
  const World& w = b.world;
  const glm::ivec3 dims(w.dims);
  const size_t N = w.voxel_count();
  std::vector<std::atomic<uint32_t>> choice(N * 6);
  for (auto& c : choice) c.store(kNone, std::memory_order_relaxed);
  std::vector<std::atomic<uint8_t>> stored(b.maximal.size());
  for (auto& s : stored) s.store(0, std::memory_order_relaxed);
  std::vector<std::unique_ptr<BoxRuns>> runs(b.maximal.size());
  std::vector<std::once_flag> runs_once(b.maximal.size());
  auto runs_of = [&](uint32_t c) -> const BoxRuns& {
    std::call_once(runs_once[c], [&] { runs[c] = std::make_unique<BoxRuns>(box_runs(media, b.maximal[c])); });
    return *runs[c];
  };
  std::atomic<size_t> evaluated{0}, faces{0};
  const int block = int(std::max(1u, opt.choice_block));
  // The representative of (u, f): the first voxel, in the world-aligned block x block square of
  // u's plane (normal f / 2) that holds u, whose candidates are u's. A function of the world alone,
  // so the choice stays deterministic however the rounds are scheduled.
  std::function<uint32_t(glm::ivec3, uint32_t)> choose = [&](glm::ivec3 u, uint32_t f) -> uint32_t {
    const size_t key = w.index(glm::uvec3(u)) * 6 + f;
    uint32_t c = choice[key].load(std::memory_order_relaxed);
    if (c != kNone) return c;
    uint32_t cand[9];
    const int n = candidates(w.index(glm::uvec3(u)), cand);
    uint64_t best = ~0ull;
    const glm::ivec3 rep = n == 1 ? u : representative(w, media, candidates, block, u, f, cand, n);
    if (n == 1) {
      best = cand[0];
    } else if (rep != u) {
      best = choose(rep, f);
    } else {
      for (int k = 0; k < n; ++k) best = std::min(best, entry_key(flux, prefix, runs_of(cand[k]), u, f, b.maximal[cand[k]], cand[k]));
      evaluated.fetch_add(size_t(n), std::memory_order_relaxed);
    }
    c = uint32_t(best & 0xFFFFFFFFu);
    choice[key].store(c, std::memory_order_relaxed);
    faces.fetch_add(1, std::memory_order_relaxed);
    return c;
  };
  const uint64_t atlas_capacity = uint64_t(opt.atlas_width) * 65536;
  uint64_t area = 0;
  size_t stored_count = 1;  // the exterior div
  auto face_area = [](const Box& B) {
    const glm::ivec3 s = B.size();
    return 2 * (uint64_t(s.x) * s.y + uint64_t(s.y) * s.z + uint64_t(s.x) * s.z);
  };
  std::vector<uint32_t> frontier;
  auto admit = [&](std::vector<uint32_t>& list) {  // sort, count, check the limits
    std::sort(list.begin(), list.end());
    for (uint32_t c : list) area += face_area(b.maximal[c]);
    stored_count += list.size();
    if (stored_count > shared::kPortalMaxDivs)
      throw Error("portal build: world '" + w.name + "' needs more than " + std::to_string(shared::kPortalMaxDivs) +
                  " divs, the most 15-bit div indices address (a coarser --voxels for a voxelized scene, a smaller or simpler map for a tile or block map)");
    if (area > atlas_capacity)
      throw Error("portal build: world '" + w.name + "' needs more than " + std::to_string(area) +
                  " atlas texels, beyond an atlas " + std::to_string(opt.atlas_width) +
                  " texels wide and 65536 rows (16-bit atlas coordinates; raise the atlas width or use a smaller world)");
  };
  for (size_t i = 0; i < N; ++i)
    if (b.start_box[i] != kNone && stored[b.start_box[i]].exchange(1) == 0) frontier.push_back(b.start_box[i]);
  area = face_area(Box{{0, 0, 0}, dims, kEmpty});
  admit(frontier);
  std::mutex mutex;
  auto visit_faces = [&](const Box& B, bool exterior, std::vector<uint32_t>& found) {
    for (uint32_t f = 0; f < 6; ++f) {
      const uint32_t a = f / 2, ta = shared::portal_tangent0(a), tb = shared::portal_tangent1(a);
      const glm::ivec2 ext = face_extent(B, f);
      for (int jv = 0; jv < ext.y; ++jv)
        for (int iu = 0; iu < ext.x; ++iu) {
          glm::ivec3 u;
          u[ta] = B.lo[ta] + iu, u[tb] = B.lo[tb] + jv;
          u[a] = exterior ? ((f & 1u) ? dims[a] - 1 : 0) : ((f & 1u) ? B.hi[a] : B.lo[a] - 1);
          if (!w.inside(u) || media(u) == World::kOpaque) continue;
          const uint32_t c = choose(u, exterior ? f : f ^ 1u);
          if (stored[c].load(std::memory_order_relaxed) == 0 && stored[c].exchange(1) == 0) found.push_back(c);
        }
    }
  };
  {
    std::vector<uint32_t> found;
    visit_faces(Box{{0, 0, 0}, dims, kEmpty}, true, found);
    admit(found);
    frontier.insert(frontier.end(), found.begin(), found.end());
  }
  // Progress: the stored divs whose faces are visited, of the candidates (an upper bound: the line
  // ends with "done" below 100 %); the bounded choice was silent for minutes (an outside sweep)
  std::optional<Progress> progress;
  if (opt.progress) progress.emplace("portal build: closing the divs' faces (of the candidate divs)", b.maximal.size());
  while (!frontier.empty()) {
    std::vector<uint32_t> next;
    parallel_for(frontier.size(), T, [&](size_t k) {
      std::vector<uint32_t> found;
      visit_faces(b.maximal[frontier[k]], false, found);
      if (progress) progress->advance();
      if (!found.empty()) {
        std::lock_guard lock(mutex);
        next.insert(next.end(), found.begin(), found.end());
      }
    });
    admit(next);
    frontier = std::move(next);
  }
  b.choice.assign(N * 6, kNone);
  for (size_t i = 0; i < N * 6; ++i) b.choice[i] = choice[i].load(std::memory_order_relaxed);
  b.stats.candidates_evaluated = evaluated;
  b.stats.faces_chosen = faces;
}

// The bounded choice (build.h, DivChoice::bounded): candidates, start boxes, then the closure of
// the stored divs' face textures, round by round, each round's faces evaluated in parallel.
void choose_bounded(PortalBuild& b, const FluxDensity& flux, const MediumGrid& media, const FluxPrefix& prefix,
                    const PortalOptions& opt, unsigned T) {
  const glm::ivec3 dims(b.world.dims);
  const bool timing = std::getenv("GRIDRT_PORTAL_TIMING") != nullptr;
  const uint32_t K = opt.choice_per_run >= 3 ? 3 : 2;  // greedy boxes per run
  auto tick = Clock::now();
  auto phase = [&](const char* what) {
    if (timing) std::fprintf(stderr, "portal build (bounded): %s %.3f s\n", what, seconds_since(tick));
    tick = Clock::now();
  };
  const AxisRuns runs = axis_runs(media, dims);
  phase("runs");
  // Media present, one summed-area table each.
  std::vector<uint32_t> media_present;
  for (uint32_t i : runs.start[0])
    if (std::find(media_present.begin(), media_present.end(), media.m[i]) == media_present.end())
      media_present.push_back(media.m[i]);
  std::sort(media_present.begin(), media_present.end());
  std::vector<std::unique_ptr<MediumSat>> sats;
  for (uint32_t m : media_present) sats.push_back(std::make_unique<MediumSat>(media, m));
  auto sat_of = [&](uint32_t m) -> const MediumSat& {
    return *sats[size_t(std::lower_bound(media_present.begin(), media_present.end(), m) - media_present.begin())];
  };
  std::vector<Box> grown[3];
  for (int a = 0; a < 3; ++a) grown[a] = greedy_boxes(runs, media, sat_of, a, K, T);
  sats.clear();
  phase("greedy boxes");
  for (int a = 0; a < 3; ++a)
    for (size_t x = 0; x < grown[a].size(); ++x)
      if (x == 0 || !(grown[a][x] == grown[a][x - 1])) b.maximal.push_back(grown[a][x]);  // copies are adjacent often
  std::sort(b.maximal.begin(), b.maximal.end(), box_less);
  b.maximal.erase(std::unique(b.maximal.begin(), b.maximal.end()), b.maximal.end());
  Candidates candidates{runs, K, {}};
  for (int a = 0; a < 3; ++a) {
    candidates.run_box[a].resize(grown[a].size());
    for (size_t k = 0; k < grown[a].size(); ++k)
      candidates.run_box[a][k] =
          uint32_t(std::lower_bound(b.maximal.begin(), b.maximal.end(), grown[a][k], box_less) - b.maximal.begin());
    grown[a] = {};
  }
  b.stats.maximal = b.maximal.size();
  phase("sort");
  start_cover(b, media, candidates);
  phase("start cover");
  close_faces(b, flux, media, prefix, candidates, opt, T);
  phase("closure");
}

}  // namespace

EntryCost integrate_flux_density_fast(const World& world, glm::ivec3 v, uint32_t entry_face, const Box& div) {
  static const FluxPrefix prefix(FluxDensity::get());
  const MediumGrid media(world);
  EntryCost c = integrate_runs(prefix, box_runs(media, div), v, entry_face, div);
  const EntryCost slow = integrate_flux_density_over_cuboid(world, FluxDensity::get(), v, entry_face, div);
  c.length = slow.length;
  c.cost = c.length > 0 ? c.p_open / c.length : 1e30;
  return c;
}

EntryCost integrate_flux_density_over_cuboid(const World& world, const FluxDensity& flux, glm::ivec3 v,
                                             uint32_t entry_face, const Box& div) {
  return integrate_impl([&](glm::ivec3 w) { return world.inside(w) ? world.medium(w) : kOutsideMedium; }, flux, v,
                        entry_face, div);
}

// ---- Build -----------------------------------------------------------------------------------

Box greedy_div(const World& world, glm::ivec3 v, glm::ivec3 order) {
  const MediumGrid media(world);
  const uint32_t m = media(v);
  if (m == World::kOpaque) throw Error("greedy_div: voxel is opaque");
  return grow_greedy(MediumSat(media, m), Box{v, v + 1, m}, order);
}

DivChoice parse_div_choice(const std::string& name) {
  if (name == "bounded") return DivChoice::bounded;
  if (name == "exact") return DivChoice::exact;
  throw Error("unknown div choice '" + name + "' (bounded, exact)");
}
const char* div_choice_name(DivChoice c) { return c == DivChoice::exact ? "exact" : "bounded"; }

DivInfo read_div_info(const PackedPortal& p, uint32_t d) {
  DivInfo info;
  auto texel = [&](uint32_t k) {
    const size_t idx = size_t(d) * 8 + k;
    const size_t x = idx % p.info_width, y = idx / p.info_width;
    const uint8_t* t = &p.info[(y * p.info_width + x) * 4];
    return glm::uvec4(t[0], t[1], t[2], t[3]);
  };
  for (uint32_t f = 0; f < 6; ++f) {
    const glm::uvec4 t = texel(f);
    info.face_uv[f] = glm::uvec2(t.x | (t.z << 8), t.y | (t.w << 8));
  }
  const glm::uvec4 s = texel(6), o = texel(7);
  info.size = glm::ivec3(s.x, s.y, s.z);
  info.glass_material = s.w;
  info.lo = glm::ivec3(o.x, o.y, o.z);
  info.type = o.w & shared::kPortalTypeMask;
  info.level = o.w >> shared::kPortalLevelShift;
  return info;
}

namespace {

// 2-3 (the exact choice): every maximal div, then for every entry face of every passable voxel the
// best candidate, an atomic min of (cost bits << 32 | maximal index); the start div of a voxel:
// its largest candidate.
void choose_exact(PortalBuild& b, const FluxDensity& flux, const MediumGrid& media, const FluxPrefix& prefix,
                  const PortalOptions& opt, unsigned T) {
  const World& w = b.world;
  const size_t N = w.voxel_count();
  // 2. Maximal divs.
  if (N > kExactChoiceMaxVoxels)
    throw Error("portal build: world '" + w.name + "' has " + std::to_string(N) + " voxels; the exact div choice takes at most " +
                std::to_string(kExactChoiceMaxVoxels) + " (it grows about as resolution^5; use the bounded choice)");
  auto t = Clock::now();
  b.maximal = maximal_divs(w, T, 4 * kExactChoiceMaxVoxels);
  b.stats.maximal = b.maximal.size();
  b.stats.seconds_maximal = seconds_since(t);

  // 3. For every entry face of every passable voxel, the best candidate.
  t = Clock::now();
  std::vector<std::atomic<uint64_t>> best(N * 6);
  std::vector<std::atomic<uint64_t>> largest(N);
  std::vector<std::atomic<uint32_t>> count(N);
  for (auto& x : best) x.store(~0ull, std::memory_order_relaxed);
  for (auto& x : largest) x.store(0, std::memory_order_relaxed);
  for (auto& x : count) x.store(0, std::memory_order_relaxed);
  parallel_for(b.maximal.size(), T, [&](size_t bi) {
    const Box& B = b.maximal[bi];
    for (int z = B.lo.z; z < B.hi.z; ++z)
      for (int y = B.lo.y; y < B.hi.y; ++y)
        for (int x = B.lo.x; x < B.hi.x; ++x) {
          const size_t vi = w.index(x, y, z);
          count[vi].fetch_add(1, std::memory_order_relaxed);
          const uint64_t key = (uint64_t(B.volume()) << 32) | (0xFFFFFFFFu - uint32_t(bi));
          uint64_t cur = largest[vi].load(std::memory_order_relaxed);
          while (key > cur && !largest[vi].compare_exchange_weak(cur, key)) {}
        }
  });
  {
    // Refuse before evaluating: every entered face of a voxel in n > 1 candidates costs n evaluations.
    size_t estimate = 0;
    for (size_t i = 0; i < N; ++i) {
      const uint32_t n = count[i].load(std::memory_order_relaxed);
      if (n > 1) estimate += size_t(n) * 6;
    }
    if (estimate > kExactChoiceMaxEvaluations)
      throw Error("portal build: world '" + w.name + "': the exact div choice would evaluate up to " + std::to_string(estimate) +
                  " candidates, beyond its limit of " + std::to_string(kExactChoiceMaxEvaluations) +
                  " (minutes of work; use the bounded choice)");
  }
  std::atomic<size_t> evaluated{0};
  {
    std::optional<Progress> progress;
    if (opt.progress) progress.emplace("portal build: choosing divs", b.maximal.size());
    parallel_for(b.maximal.size(), T, [&](size_t bi) {
      const Box& B = b.maximal[bi];
      const BoxRuns runs = box_runs(media, B);
      size_t local = 0;
      for (int z = B.lo.z; z < B.hi.z; ++z)
        for (int y = B.lo.y; y < B.hi.y; ++y)
          for (int x = B.lo.x; x < B.hi.x; ++x) {
            const glm::ivec3 v(x, y, z);
            const size_t vi = w.index(x, y, z);
            const bool single = count[vi].load(std::memory_order_relaxed) == 1;
            for (uint32_t f = 0; f < 6; ++f) {
              // Rays enter through face f from the voxel beyond it: skip faces no ray crosses.
              const glm::ivec3 from = v + ((f & 1u) ? 1 : -1) * axis_unit(f / 2);
              if (w.inside(from) && w.medium(from) == World::kOpaque) continue;
              uint64_t key;
              if (single) {
                key = uint64_t(bi);
              } else {
                key = entry_key(flux, prefix, runs, v, f, B, uint32_t(bi));
                ++local;
              }
              std::atomic<uint64_t>& slot = best[vi * 6 + f];
              uint64_t cur = slot.load(std::memory_order_relaxed);
              while (key < cur && !slot.compare_exchange_weak(cur, key)) {}
            }
          }
      evaluated += local;
      if (progress) progress->advance();
    });
  }
  b.stats.candidates_evaluated = evaluated;
  b.choice.assign(N * 6, kNone);
  b.start_box.assign(N, kNone);
  for (size_t i = 0; i < N * 6; ++i) {
    const uint64_t k = best[i].load();
    if (k != ~0ull) b.choice[i] = uint32_t(k & 0xFFFFFFFFu);
  }
  for (size_t i = 0; i < N; ++i) {
    const uint64_t k = largest[i].load();
    if (k) b.start_box[i] = 0xFFFFFFFFu - uint32_t(k & 0xFFFFFFFFu);
  }
  for (uint32_t c : b.choice) b.stats.faces_chosen += c != kNone;
  b.stats.seconds_choice = seconds_since(t);
}

// 4. Stored divs: the exterior div, then every maximal div some face or voxel uses, in order.
void store_divs(PortalBuild& b) {
  const World& w = b.world;
  const glm::ivec3 dims(w.dims);
  b.div_of_maximal.assign(b.maximal.size(), kNone);
  for (uint32_t c : b.choice)
    if (c != kNone) b.div_of_maximal[c] = 0;
  for (uint32_t c : b.start_box)
    if (c != kNone) b.div_of_maximal[c] = 0;
  b.divs.push_back(Box{{0, 0, 0}, dims, kEmpty});
  for (size_t i = 0; i < b.maximal.size(); ++i)
    if (b.div_of_maximal[i] == 0) {
      b.div_of_maximal[i] = uint32_t(b.divs.size());
      b.divs.push_back(b.maximal[i]);
    }
  if (b.divs.size() > shared::kPortalMaxDivs)
    throw Error("portal build: world '" + w.name + "' needs " + std::to_string(b.divs.size()) +
                " divs, the 16-bit atlas texels address at most 32768 (a coarser --voxels for a voxelized scene, a smaller or simpler map for a tile or block map)");
}

// 5a. The atlas's layout: shelf packing, tallest faces first; each (div, face)'s texel corner.
std::vector<glm::uvec2> place_faces(PortalBuild& b, const PortalOptions& opt) {
  PackedPortal& p = b.packed;
  struct FaceRef { uint32_t div, face; glm::ivec2 ext; };
  std::vector<FaceRef> faces;
  for (uint32_t d = 0; d < b.divs.size(); ++d)
    for (uint32_t f = 0; f < 6; ++f) faces.push_back({d, f, face_extent(b.divs[d], f)});
  std::stable_sort(faces.begin(), faces.end(), [](const FaceRef& a, const FaceRef& c) { return a.ext.y > c.ext.y; });
  std::vector<glm::uvec2> face_uv(b.divs.size() * 6);
  uint32_t cx = 0, cy = 0, shelf = 0;
  for (const FaceRef& fr : faces) {
    if (uint32_t(fr.ext.x) > opt.atlas_width)
      throw Error("portal build: a div face " + std::to_string(fr.ext.x) + " texels wide does not fit the atlas width " +
                  std::to_string(opt.atlas_width));
    if (cx + fr.ext.x > opt.atlas_width) cy += shelf, cx = 0, shelf = 0;
    face_uv[fr.div * 6 + fr.face] = glm::uvec2(cx, cy);
    cx += fr.ext.x;
    shelf = std::max(shelf, uint32_t(fr.ext.y));
  }
  const uint64_t atlas_h = uint64_t(cy) + shelf;
  if (atlas_h > 65536)
    throw Error("portal build: atlas would need " + std::to_string(atlas_h) +
                " rows, beyond the 16-bit atlas coordinates (raise the atlas width)");
  p.atlas_width = opt.atlas_width, p.atlas_height = uint32_t(atlas_h);
  return face_uv;
}

// 5b. The atlas's texels: per face texel, the div the ray enters beyond it (or the wall, or outside).
void fill_atlas(PortalBuild& b, const std::vector<glm::uvec2>& face_uv, unsigned T) {
  const World& w = b.world;
  const glm::ivec3 dims(w.dims);
  PackedPortal& p = b.packed;
  auto texel_for = [&](glm::ivec3 beyond, uint32_t entry_face) -> uint16_t {
    if (!w.inside(beyond)) return uint16_t(shared::kPortalOutside);
    const uint16_t m = w.at(beyond);
    if (w.medium(beyond) == World::kOpaque) return uint16_t(shared::kPortalWallBit + m);
    const uint32_t c = b.choice[w.index(glm::uvec3(beyond)) * 6 + entry_face];
    if (c == kNone) throw Error("portal build: internal error, no div chosen for an entered face");
    return uint16_t(b.div_of_maximal[c]);
  };
  p.atlas.assign(size_t(p.atlas_width) * p.atlas_height, 0);
  parallel_for(b.divs.size(), T, [&](size_t d) {
    const Box& B = b.divs[d];
    for (uint32_t f = 0; f < 6; ++f) {
      const uint32_t a = f / 2, ta = shared::portal_tangent0(a), tb = shared::portal_tangent1(a);
      const glm::ivec2 ext = face_extent(B, f);
      const glm::uvec2 uv = face_uv[d * 6 + f];
      for (int jv = 0; jv < ext.y; ++jv)
        for (int iu = 0; iu < ext.x; ++iu) {
          glm::ivec3 vox;
          vox[ta] = B.lo[ta] + iu, vox[tb] = B.lo[tb] + jv;
          uint16_t value;
          if (d == 0) {
            // Exterior: the world's boundary voxel on face f, entered through that face from outside.
            vox[a] = (f & 1u) ? dims[a] - 1 : 0;
            value = texel_for(vox, f);
          } else {
            // Interior: the voxel beyond the face, entered through its opposite face.
            vox[a] = (f & 1u) ? B.hi[a] : B.lo[a] - 1;
            value = texel_for(vox, f ^ 1u);
          }
          p.atlas[size_t(uv.y + jv) * p.atlas_width + uv.x + iu] = value;
        }
    }
  });
}

// 5c. Div info: 8 texels a div (its faces' atlas corners, size and glass material, corner and type).
void pack_div_info(PortalBuild& b, const std::vector<glm::uvec2>& face_uv, const PortalOptions& opt) {
  PackedPortal& p = b.packed;
  const uint64_t info_texels = uint64_t(b.divs.size()) * 8;
  p.info_width = opt.info_width;
  p.info_height = uint32_t((info_texels + p.info_width - 1) / p.info_width);
  p.info.assign(size_t(p.info_width) * p.info_height * 4, 0);
  for (uint32_t d = 0; d < b.divs.size(); ++d) {
    const Box& B = b.divs[d];
    auto put = [&](uint32_t k, uint32_t r, uint32_t g, uint32_t bl, uint32_t al) {
      const size_t idx = size_t(d) * 8 + k;
      uint8_t* tx = &p.info[idx * 4];
      tx[0] = uint8_t(r), tx[1] = uint8_t(g), tx[2] = uint8_t(bl), tx[3] = uint8_t(al);
    };
    for (uint32_t f = 0; f < 6; ++f) {
      const glm::uvec2 uv = face_uv[d * 6 + f];
      put(f, uv.x & 0xFF, uv.y & 0xFF, uv.x >> 8, uv.y >> 8);
    }
    const bool glass = B.medium != kEmpty;
    put(6, B.size().x, B.size().y, B.size().z, glass ? B.medium : 0);
    put(7, B.lo.x, B.lo.y, B.lo.z, d == 0 ? shared::kPortalDivExterior : glass ? shared::kPortalDivGlass : shared::kPortalDivAir);
  }
}

// 5d. The start map: per voxel its start div, or the wall bit and the voxel's material.
void pack_start(PortalBuild& b) {
  const World& w = b.world;
  const size_t N = w.voxel_count();
  PackedPortal& p = b.packed;
  p.start.assign(N, 0);
  for (size_t i = 0; i < N; ++i) {
    if (b.start_box[i] != kNone) {
      p.start[i] = uint16_t(b.div_of_maximal[b.start_box[i]]);
    } else {
      p.start[i] = uint16_t(shared::kPortalWallBit + w.voxels[i]);
    }
  }
}

}  // namespace

PortalBuild build_portal(World world, const PortalOptions& opt) {
  world.validate();
  if (opt.info_width < 8 || opt.info_width % 8 != 0)
    throw Error("portal build: div-info texture width " + std::to_string(opt.info_width) + " must be a positive multiple of 8");
  if (opt.atlas_width < 1 || opt.atlas_width > 65536)
    throw Error("portal build: atlas width " + std::to_string(opt.atlas_width) + " outside 1 .. 65536 (16-bit atlas coordinates)");
  // The build's arrays, checked against the host's memory (--max-host-mib too) before they are
  // made: about 80-90 bytes a voxel at their peak on the Cornell box at 128^3 and 200^3 voxels
  // (316 and 782 MB resident, about 150 of them the program's), so 112 a voxel (an outside sweep:
  // `--max-host-mib 1` did not bound it)
  require_host_memory(uint64_t(world.voxel_count()) * 112u,
                      "the portal build's arrays for " + std::to_string(world.dims.x) + "x" + std::to_string(world.dims.y) +
                          "x" + std::to_string(world.dims.z) + " voxels",
                      "fewer --voxels, or a smaller map");
  const auto t_start = Clock::now();
  const unsigned T = thread_count(opt.threads);
  PortalBuild b;
  b.world = std::move(world);
  const World& w = b.world;

  b.stats.choice = opt.choice;
  // 1. The flux-density table (once per process).
  auto t = Clock::now();
  const FluxDensity& flux = FluxDensity::get();
  b.stats.seconds_flux = seconds_since(t);
  const MediumGrid media(w);
  const FluxPrefix prefix(flux);

  if (opt.choice == DivChoice::bounded) {
    // 2-3. Greedy candidates, start boxes and the closure of the needed faces (build.h).
    t = Clock::now();
    const FluxPrefix near(flux, int(opt.choice_range));
    choose_bounded(b, flux, media, near, opt, T);
    b.stats.seconds_choice = seconds_since(t);
  } else {
    choose_exact(b, flux, media, prefix, opt, T);
  }

  // 4. Stored divs.
  t = Clock::now();
  store_divs(b);

  // 5. Pack: texel values, the atlas (shelf packing, tallest faces first), div info, start map.
  PackedPortal& p = b.packed;
  p.dims = w.dims, p.origin = w.origin, p.voxel_size = w.voxel_size;
  p.div_count = uint32_t(b.divs.size());
  const std::vector<glm::uvec2> face_uv = place_faces(b, opt);
  fill_atlas(b, face_uv, T);
  pack_div_info(b, face_uv, opt);
  pack_start(b);
  p.start_depth = glm::ivec3(w.dims).z;
  p.coverage.assign(w.materials.size(), 1.0f);
  p.resolve.assign(w.materials.size(), 0);
  b.stats.seconds_pack = seconds_since(t);
  if (opt.mip_levels > 1) add_mip_levels(b, opt);
  b.stats.divs = b.divs.size();
  b.stats.atlas_texels = p.atlas.size();
  b.stats.bytes = p.bytes();
  b.stats.seconds_total = seconds_since(t_start);
  return b;
}

}  // namespace gridrt::portal
