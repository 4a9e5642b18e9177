#include "gridrt/common/embree/embree_tracer.h"
#include "gridrt/common/parallel.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include <embree3/rtcore.h>

// alpha.h calls min/max unqualified (GLSL built-ins); compat.h does not bring GLM's into
// gridrt::shared yet, so do it here before including it.
namespace gridrt::shared {
using glm::floor;
using glm::max;
using glm::min;
}  // namespace gridrt::shared
#include "gridrt/common/shared/alpha.h"
#include "gridrt/common/shared/grid.h"
#include "gridrt/common/shared/transform.h"

namespace gridrt {

namespace {

constexpr float kInf = std::numeric_limits<float>::infinity();

// What the alpha filter of one geometry needs.
struct GeometryData {
  const Scene* scene = nullptr;
  const Mesh* mesh = nullptr;
};

// The intersection context with the launch reference of the ray being traced.
struct Context {
  RTCIntersectContext rtc;
  uint32_t launch_ref;
  glm::vec3 org;                                     // the ray's origin (the surface rule)
  const Scene* scene;                                // for the hit triangle's vertices
  const std::vector<std::vector<glm::vec3>>* world;  // per instance, world-space vertices
};

// The tracers' rules for a ray launched from a surface, on a hit Embree found: the launch
// triangle is not hit (self-hit), nor a face whose plane passes within 8 ulps of the origin
// (shared::origin_on_plane, the surface rule, on the same world-space vertices in the same order
// as the grid's triangle records).
void self_filter(const RTCFilterFunctionNArguments* args) {
  const Context* ctx = reinterpret_cast<const Context*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const uint32_t geom = RTCHitN_geomID(args->hit, args->N, i), prim = RTCHitN_primID(args->hit, args->N, i);
    const uint32_t ref = (geom << 16) | prim;
    if (ref == ctx->launch_ref) {
      args->valid[i] = 0;
      continue;
    }
    const glm::uvec3 t = ctx->scene->meshes[ctx->scene->instances[geom].mesh].triangles[prim];
    const std::vector<glm::vec3>& w = (*ctx->world)[geom];
    if (shared::origin_on_plane(ctx->org, w[t[0]], w[t[1]], w[t[2]])) args->valid[i] = 0;
  }
}

// hits_along: the context of a ray whose every hit is recorded and then refused (so Embree goes on).
struct CollectContext {
  RTCIntersectContext rtc;
  uint32_t launch_ref;
  std::vector<uint32_t>* refs;
};

void collect_filter(const RTCFilterFunctionNArguments* args) {
  const CollectContext* ctx = reinterpret_cast<const CollectContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const uint32_t ref = (RTCHitN_geomID(args->hit, args->N, i) << 16) | RTCHitN_primID(args->hit, args->N, i);
    if (ref != ctx->launch_ref) ctx->refs->push_back(ref);
    args->valid[i] = 0;
  }
}

// Alpha keying: no surface where the mask's texel under the hit's uv is below the cutoff.
void alpha_filter(const RTCFilterFunctionNArguments* args) {
  const GeometryData* g = static_cast<const GeometryData*>(args->geometryUserPtr);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] != -1) continue;
    const uint32_t prim = RTCHitN_primID(args->hit, args->N, i);
    const Material& mat = g->scene->materials[g->mesh->materials[prim]];
    if (!mat.alpha_keyed()) continue;
    const Texture& tex = g->scene->textures[mat.alpha_texture];
    if (tex.width == 0 || tex.height == 0) continue;
    glm::vec2 uv(0.0f);
    if (!g->mesh->uvs.empty()) {
      const glm::uvec3 t = g->mesh->triangles[prim];
      uv = shared::interpolate_uv(g->mesh->uvs[t[0]], g->mesh->uvs[t[1]], g->mesh->uvs[t[2]],
                                  RTCHitN_u(args->hit, args->N, i), RTCHitN_v(args->hit, args->N, i));
    }
    const glm::uvec2 xy = shared::alpha_texel_coords(uv, tex.width, tex.height);
    if (tex.texel(xy.x, xy.y).a < shared::kAlphaCutoff) args->valid[i] = 0;
  }
}

bool finite3(const glm::vec3& v) { return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z); }

void error_callback(void* user, RTCError code, const char* message) {
  auto* last = static_cast<std::string*>(user);
  *last = "Embree error " + std::to_string(int(code)) + ": " + (message ? message : "");
}

}  // namespace

struct EmbreeTracer::Impl {
  unsigned threads = 0;
  RTCDevice device = nullptr;
  RTCScene rtc_scene = nullptr;
  const Scene* scene = nullptr;
  std::string last_error;
  mutable std::atomic<uint64_t> rejected{0};  // rays outside the domain, never handed to Embree
  std::vector<RTCGeometry> geometries;        // per instance
  std::vector<GeometryData> data;             // per instance (stable addresses)
  std::vector<std::vector<glm::vec3>> world;  // per instance, world-space vertices

  ~Impl() { release(); }

  void release() {
    for (RTCGeometry g : geometries)
      if (g) rtcReleaseGeometry(g);  // (a build that failed made only some)
    geometries.clear();
    if (rtc_scene) rtcReleaseScene(rtc_scene);
    rtc_scene = nullptr;
  }

  void check() {
    if (!last_error.empty()) {
      const std::string e = last_error;
      last_error.clear();
      throw Error(e);
    }
  }

  // World-space vertices of instance i at `time`, written into its Embree vertex buffer.
  void transform(uint32_t i, float time) {
    const Instance& inst = scene->instances[i];
    const Mesh& mesh = scene->meshes[inst.mesh];
    const shared::Affine m = shared::to_affine(inst.transform_at(time));
    std::vector<glm::vec3>& w = world[i];
    w.resize(mesh.positions.size());
    for (size_t v = 0; v < w.size(); ++v) w[v] = shared::transform_point(m, mesh.positions[v]);
    float* buf = static_cast<float*>(rtcGetGeometryBufferData(geometries[i], RTC_BUFFER_TYPE_VERTEX, 0));
    for (size_t v = 0; v < w.size(); ++v) {
      buf[3 * v + 0] = w[v].x;
      buf[3 * v + 1] = w[v].y;
      buf[3 * v + 2] = w[v].z;
    }
  }

  Hit trace_one(const Ray& ray) const {
    Hit hit{};
    hit.t = kInf;
    hit.instance = shared::kNoInstance;
    // Reject rays outside the domain (shared::ray_domain, the grid's rule; it also keeps every
    // component far below Embree 3's validity limit of about 1.8e18, whose assertion aborts).
    if (shared::ray_domain(ray.org, ray.dir, ray.tmin, ray.tmax) != shared::kDomainOk || !finite3(ray.org)) {
      hit.flags = shared::kHitRejected;
      rejected.fetch_add(1, std::memory_order_relaxed);
      return hit;
    }
    if (!(shared::origin_tmin(ray.org, ray.dir, ray.tmin) < ray.tmax)) return hit;
    // Strict interval: Embree accepts tnear <= t <= tfar.
    RTCRayHit rh{};
    rh.ray.org_x = ray.org.x, rh.ray.org_y = ray.org.y, rh.ray.org_z = ray.org.z;
    rh.ray.dir_x = ray.dir.x, rh.ray.dir_y = ray.dir.y, rh.ray.dir_z = ray.dir.z;
    rh.ray.tnear = std::nextafter(shared::origin_tmin(ray.org, ray.dir, ray.tmin), kInf);
    rh.ray.tfar = std::isinf(ray.tmax) ? kInf : std::nextafter(ray.tmax, -kInf);
    if (!(rh.ray.tnear <= rh.ray.tfar)) return hit;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.time = 0.0f;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    Context ctx;
    rtcInitIntersectContext(&ctx.rtc);
    ctx.launch_ref = ray.launch_ref;
    ctx.org = ray.org;
    ctx.scene = scene;
    ctx.world = &world;
    if (ray.launch_ref != shared::kNoRef) ctx.rtc.filter = self_filter;
    rtcIntersect1(rtc_scene, &ctx.rtc, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return hit;
    hit.t = rh.ray.tfar;
    hit.instance = rh.hit.geomID;
    hit.triangle = rh.hit.primID;
    hit.u = rh.hit.u;
    hit.v = rh.hit.v;
    // Back face from the world-space triangle the grid also sees.
    const Mesh& mesh = scene->meshes[scene->instances[hit.instance].mesh];
    const glm::uvec3 t = mesh.triangles[hit.triangle];
    const std::vector<glm::vec3>& w = world[hit.instance];
    const glm::vec3 n = shared::sh_cross(w[t[1]] - w[t[0]], w[t[2]] - w[t[0]]);
    if (shared::sh_dot(n, ray.dir) > 0.0f) hit.flags |= shared::kHitBackFace;
    return hit;
  }
};

EmbreeTracer::EmbreeTracer(unsigned threads) : impl_(std::make_unique<Impl>()) {
  impl_->threads = thread_count_or_hardware(threads);
  const std::string config = "threads=" + std::to_string(impl_->threads);
  impl_->device = rtcNewDevice(config.c_str());
  if (!impl_->device) throw Error("Embree: cannot create a device (" + std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  rtcSetDeviceErrorFunction(impl_->device, error_callback, &impl_->last_error);
}

EmbreeTracer::~EmbreeTracer() {
  impl_->release();
  rtcReleaseDevice(impl_->device);
}

void EmbreeTracer::build_scene(const Scene& scene, float time) {
  Impl& d = *impl_;
  d.release();
  d.scene = &scene;
  try {
    scene.require_extent(time, "embree");
    d.rtc_scene = rtcNewScene(d.device);
    rtcSetSceneFlags(d.rtc_scene, RTCSceneFlags(RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION |
                                                (scene.has_dynamic() ? RTC_SCENE_FLAG_DYNAMIC : 0)));
    const size_t n = scene.instances.size();
    d.geometries.assign(n, nullptr);
    d.data.assign(n, GeometryData{});
    d.world.assign(n, {});
    for (uint32_t i = 0; i < n; ++i) {
      const Instance& inst = scene.instances[i];
      const Mesh& mesh = scene.meshes[inst.mesh];
      RTCGeometry g = rtcNewGeometry(d.device, RTC_GEOMETRY_TYPE_TRIANGLE);
      d.geometries[i] = g;
      rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, 3 * sizeof(float),
                              std::max<size_t>(mesh.positions.size(), 1));
      auto* idx = static_cast<uint32_t*>(rtcSetNewGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3,
                                                                  3 * sizeof(uint32_t), mesh.triangles.size()));
      d.check();
      for (size_t t = 0; t < mesh.triangles.size(); ++t)
        for (int k = 0; k < 3; ++k) idx[3 * t + k] = mesh.triangles[t][k];
      d.transform(i, time);
      d.data[i] = GeometryData{&scene, &mesh};
      bool alpha = false;
      for (uint32_t m : mesh.materials) alpha = alpha || scene.materials[m].alpha_keyed();
      if (alpha) {
        rtcSetGeometryUserData(g, &d.data[i]);
        rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
      }
      if (inst.dynamic) rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
      rtcCommitGeometry(g);
      rtcAttachGeometryByID(d.rtc_scene, g, i);
      d.check();
    }
    rtcCommitScene(d.rtc_scene);
    d.check();
  } catch (...) {
    d.release();  // as before any build (Tracer::build)
    throw;
  }
  d.scene = &scene;
}

void EmbreeTracer::update_to(float time) {
  Impl& d = *impl_;
  for (uint32_t i = 0; i < d.scene->instances.size(); ++i) {
    if (!d.scene->instances[i].dynamic) continue;
    d.transform(i, time);
    rtcUpdateGeometryBuffer(d.geometries[i], RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(d.geometries[i]);
  }
  rtcCommitScene(d.rtc_scene);
  d.check();
}

std::vector<uint32_t> EmbreeTracer::hits_along(const Ray& ray) const {
  const Impl& d = *impl_;
  if (!d.rtc_scene) throw Error("EmbreeTracer::hits_along before build");
  std::vector<uint32_t> refs;
  if (shared::ray_domain(ray.org, ray.dir, ray.tmin, ray.tmax) != shared::kDomainOk || !(ray.tmin < ray.tmax))
    return refs;
  RTCRayHit rh{};
  rh.ray.org_x = ray.org.x, rh.ray.org_y = ray.org.y, rh.ray.org_z = ray.org.z;
  rh.ray.dir_x = ray.dir.x, rh.ray.dir_y = ray.dir.y, rh.ray.dir_z = ray.dir.z;
  rh.ray.tnear = shared::origin_tmin(ray.org, ray.dir, ray.tmin);
  rh.ray.tfar = ray.tmax;
  rh.ray.mask = 0xFFFFFFFFu;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  CollectContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.launch_ref = ray.launch_ref;
  ctx.refs = &refs;
  ctx.rtc.filter = collect_filter;
  rtcIntersect1(d.rtc_scene, &ctx.rtc, &rh);
  std::sort(refs.begin(), refs.end());
  refs.erase(std::unique(refs.begin(), refs.end()), refs.end());
  return refs;
}

uint64_t EmbreeTracer::rejected_rays() const { return impl_->rejected.load(); }

Hit EmbreeTracer::trace_one(const Ray& ray) const {
  if (!impl_->rtc_scene) throw Error("EmbreeTracer::trace before build");
  return impl_->trace_one(ray);
}

void EmbreeTracer::trace_closest(std::span<const Ray> rays, std::span<Hit> hits) {
  constexpr size_t kBlock = 1024;
  const size_t blocks = (rays.size() + kBlock - 1) / kBlock;
  std::atomic<size_t> next{0};
  auto work = [&] {
    for (size_t b; (b = next.fetch_add(1)) < blocks;) {
      const size_t end = std::min(rays.size(), (b + 1) * kBlock);
      for (size_t r = b * kBlock; r < end; ++r) hits[r] = impl_->trace_one(rays[r]);
    }
  };
  run_on_threads(unsigned(std::max<size_t>(1, std::min<size_t>(impl_->threads, blocks))), work);
}

}  // namespace gridrt
