// mip.cpp: mip-mapped space, the build side ("A Novel Raytracing Algorithm for GPU", "LOD? In
// raytracing?"; docs/PORTAL.md, "Mip-mapped space"): coarser voxelizations of the same space, each
// with its own divs, packed into the same textures as level 0's.
#include <cmath>
#include <cstring>
#include <map>
#include <tuple>

#include "gridrt/reference/portal/build.h"

namespace gridrt::portal {

namespace sh = gridrt::shared;

World coarse_world(const World& w, uint32_t level, std::vector<WallMaterial>& materials) {
  if (level == 0 || level >= sh::kPortalMaxLevels)
    throw Error("portal mip: level " + std::to_string(level) + " outside 1 .. " + std::to_string(sh::kPortalMaxLevels - 1));
  const int f = 1 << level;
  const glm::uvec3 cd = sh::portal_level_dims(w.dims, level);
  World c;
  c.name = w.name + " (mip level " + std::to_string(level) + ")";
  c.dims = cd;
  c.voxels.assign(size_t(cd.x) * cd.y * cd.z, kEmpty);
  c.origin = w.origin;
  c.voxel_size = w.voxel_size * float(f);
  c.has_eye = w.has_eye, c.camera = w.camera, c.lights = w.lights;
  // Coarse materials by (colour bits, coverage bits, resolve), in order of first use.
  std::map<std::tuple<uint32_t, uint32_t, uint32_t, uint32_t, bool>, uint16_t> known;
  auto bits = [](float x) {
    uint32_t u;
    std::memcpy(&u, &x, 4);
    return u;
  };
  const float per_voxel = sh::portal_level_scale(3 * level);  // 1 / 8^level, exact
  for (uint32_t z = 0; z < cd.z; ++z)
    for (uint32_t y = 0; y < cd.y; ++y)
      for (uint32_t x = 0; x < cd.x; ++x) {
        uint32_t occupied = 0, opaque = 0;
        glm::dvec3 sum(0.0);
        for (int k = 0; k < f; ++k)
          for (int j = 0; j < f; ++j)
            for (int i = 0; i < f; ++i) {
              const glm::ivec3 v(int(x) * f + i, int(y) * f + j, int(z) * f + k);
              if (!w.inside(v) || !w.solid(v)) continue;  // beyond the world: empty
              const WallMaterial& m = w.materials[w.at(v)];
              ++occupied;
              opaque += m.glass ? 0u : 1u;
              sum += glm::dvec3(m.color);
            }
        if (occupied == 0) continue;
        const glm::vec3 color(sum / double(occupied));
        const float coverage = float(occupied) * per_voxel;
        const bool resolve = opaque == uint32_t(f * f * f);
        const auto key = std::make_tuple(bits(color.x), bits(color.y), bits(color.z), bits(coverage), resolve);
        auto it = known.find(key);
        if (it == known.end()) {
          if (materials.size() > sh::kPortalMaxMaterial)
            throw Error("portal mip: world '" + w.name + "' needs more than 32767 materials with its coarse levels' (" +
                        "one per distinct colour and coverage); use fewer mip levels");
          WallMaterial m;
          m.name = "mip" + std::to_string(level) + " coverage " + std::to_string(occupied) + "/" + std::to_string(f * f * f);
          m.color = color;
          m.coverage = coverage;
          m.resolve = resolve;
          materials.push_back(m);
          it = known.emplace(key, uint16_t(materials.size() - 1)).first;
        }
        c.voxels[c.index(x, y, z)] = it->second;
      }
  return c;
}

void add_mip_levels(PortalBuild& b, const PortalOptions& opt) {
  const uint32_t levels = opt.mip_levels;
  if (levels < 1 || levels > sh::kPortalMaxLevels)
    throw Error("portal mip: " + std::to_string(levels) + " levels requested, 1 .. " + std::to_string(sh::kPortalMaxLevels) +
                " allowed");
  if (!(opt.mip_distance > 0.0f) || !std::isfinite(opt.mip_distance))
    throw Error("portal mip: the level distance must be a positive number of voxels");
  PackedPortal& p = b.packed;
  std::vector<WallMaterial> materials = b.world.materials;
  std::vector<World> coarse;
  for (uint32_t l = 1; l < levels; ++l) coarse.push_back(coarse_world(b.world, l, materials));

  // Level 0's start map, in the first dims.z slices of a texture deep enough for every level.
  uint32_t depth = 0;
  for (uint32_t l = 0; l < levels; ++l) depth += p.level_dims(l).z;
  std::vector<uint16_t> start(size_t(p.dims.x) * p.dims.y * depth, uint16_t(sh::kPortalOutside));
  std::copy(p.start.begin(), p.start.end(), start.begin());
  std::vector<uint8_t> info = p.info;  // 8 RGBA texels per div, div d at texel 8 d
  info.resize(size_t(p.div_count) * 32);
  uint32_t z0 = p.dims.z;
  for (uint32_t l = 1; l < levels; ++l) {
    World& cw = coarse[l - 1];
    cw.materials = materials;
    PortalOptions o = opt;
    o.mip_levels = 1;
    const PortalBuild lb = build_portal(std::move(cw), o);
    const PackedPortal& q = lb.packed;
    const uint32_t base = p.div_count, row0 = p.atlas_height;
    if (uint64_t(base) + q.div_count > sh::kPortalMaxDivs)
      throw Error("portal mip: level " + std::to_string(l) + " brings the divs to " + std::to_string(base + q.div_count) +
                  ", beyond the 32768 of 15-bit indices; use fewer mip levels");
    if (uint64_t(row0) + q.atlas_height > 65536)
      throw Error("portal mip: level " + std::to_string(l) + " brings the atlas to " + std::to_string(row0 + q.atlas_height) +
                  " rows, beyond the 16-bit atlas coordinates (raise the atlas width or use fewer mip levels)");
    auto remap = [&](uint16_t t) { return t < sh::kPortalWallBit ? uint16_t(t + base) : t; };
    for (uint16_t t : q.atlas) p.atlas.push_back(remap(t));
    p.atlas_height += q.atlas_height;
    for (uint32_t d = 0; d < q.div_count; ++d) {
      for (uint32_t k = 0; k < 8; ++k) {
        const size_t idx = size_t(d) * 8 + k;
        const uint8_t* t = &q.info[((idx / q.info_width) * q.info_width + idx % q.info_width) * 4];
        uint8_t tx[4] = {t[0], t[1], t[2], t[3]};
        if (k < 6) {  // face origin: v moves down by the rows of the levels before
          const uint32_t v = (uint32_t(tx[1]) | (uint32_t(tx[3]) << 8)) + row0;
          tx[1] = uint8_t(v & 0xFF), tx[3] = uint8_t(v >> 8);
        }
        if (k == 7) tx[3] = uint8_t(tx[3] | (l << sh::kPortalLevelShift));
        info.insert(info.end(), tx, tx + 4);
      }
    }
    const glm::uvec3 ld = p.level_dims(l);
    for (uint32_t z = 0; z < ld.z; ++z)
      for (uint32_t y = 0; y < ld.y; ++y)
        for (uint32_t x = 0; x < ld.x; ++x)
          start[x + size_t(p.dims.x) * (y + size_t(p.dims.y) * (z0 + z))] = remap(q.start[x + ld.x * (y + size_t(ld.y) * z)]);
    z0 += ld.z;
    p.div_count = base + q.div_count;
  }
  p.info_height = uint32_t((uint64_t(p.div_count) * 8 + p.info_width - 1) / p.info_width);
  info.resize(size_t(p.info_width) * p.info_height * 4, 0);
  p.info = std::move(info);
  p.start = std::move(start);
  p.start_depth = depth;
  p.levels = levels;
  p.mip_distance = opt.mip_distance;
  b.world.materials = materials;
  p.coverage.clear(), p.resolve.clear();
  for (const WallMaterial& m : materials) p.coverage.push_back(m.coverage), p.resolve.push_back(m.resolve ? 1 : 0);
}

}  // namespace gridrt::portal
