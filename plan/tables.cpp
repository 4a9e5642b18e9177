// tables.cpp: the grid's tables (instances, per-triangle materials and uvs, materials and their
// alpha masks), packed once for every backend.
#include "gridrt/plan/plan.h"

#include <cstdint>
#include <map>

namespace gridrt::plan {

void append_rgba8(const Texture& tex, std::vector<uint32_t>& texels) {
  for (size_t p = 0; p < size_t(tex.width) * tex.height; ++p)
    texels.push_back(uint32_t(tex.rgba[4 * p]) | uint32_t(tex.rgba[4 * p + 1]) << 8 |
                     uint32_t(tex.rgba[4 * p + 2]) << 16 | uint32_t(tex.rgba[4 * p + 3]) << 24);
}

GridTables pack_tables(const Scene& scene) {
  GridTables t;
  t.static_instances = scene.static_instance_count();
  uint32_t offset = 0;
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Instance& inst = scene.instances[i];
    const Mesh& mesh = scene.meshes[inst.mesh];
    shared::GridInstance gi{offset, mesh.triangle_count(), inst.dynamic ? shared::kInstanceDynamic : 0u, 0u};
    for (uint32_t m : mesh.materials)
      if (scene.materials[m].alpha_keyed()) gi.flags |= shared::kInstanceAlphaKeyed;
    t.instances.push_back(gi);
    if (i < t.static_instances) t.static_triangles = offset + mesh.triangle_count();
    offset += mesh.triangle_count();
  }
  t.triangles.assign(offset, shared::GridTriangle{});
  t.uvs.assign(offset, shared::GridTriangleUv{});
  for (uint32_t i = 0; i < scene.instances.size(); ++i) {
    const Mesh& mesh = scene.meshes[scene.instances[i].mesh];
    for (uint32_t k = 0; k < mesh.triangle_count(); ++k) {
      const uint32_t r = t.instances[i].tri_offset + k;
      t.triangles[r].material = mesh.materials.empty() ? 0u : mesh.materials[k];
      if (!mesh.uvs.empty()) {
        const glm::uvec3 idx = mesh.triangles[k];
        t.uvs[r] = {mesh.uvs[idx.x], mesh.uvs[idx.y], mesh.uvs[idx.z]};
      }
    }
  }
  // Each mask once, however many materials key with it (16 materials of one 4096^2 mask were 16
  // copies: 2.3 GB)
  std::map<int32_t, uint32_t> mask_offsets;
  for (const Material& mat : scene.materials) {
    shared::GridMaterial gm{};
    if (mat.alpha_keyed()) {
      const Texture& tex = scene.textures[size_t(mat.alpha_texture)];
      auto [it, added] = mask_offsets.emplace(mat.alpha_texture, uint32_t(t.texels.size()));
      if (added) {
        if (t.texels.size() + uint64_t(tex.width) * tex.height > UINT32_MAX)
          throw Error("the scene's alpha masks hold more than 2^32 texels (the grid's texel offsets are 32 bits): "
                      "use smaller masks");
        append_rgba8(tex, t.texels);
      }
      gm.alpha_offset = it->second;
      gm.alpha_width = tex.width;
      gm.alpha_height = tex.height;
    }
    t.materials.push_back(gm);
  }
  return t;
}

}  // namespace gridrt::plan
