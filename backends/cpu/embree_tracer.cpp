#include "backends/cpu/embree_tracer.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "core/kernel/alpha.h"
#include "core/util/log.h"

namespace tandem {

namespace {

// Our data travels with every Embree query through an extended context,
// which is how the intersection filter reaches the kernel data. Each ray's
// alpha key travels in its id, so that the rays of a packet each have their
// own.
struct TandemRayContext {
  RTCIntersectContext rtc;
  const KernelData* kd;
};

// Embree's default flags (incoherent rays), which path-tracing rays are.
TandemRayContext make_context(const KernelData* kd) {
  TandemRayContext ctx;
  rtcInitIntersectContext(&ctx.rtc);
  ctx.kd = kd;
  return ctx;
}

// The scene instance of a hit: the instance geometry's ID in a two-level
// scene, the triangle geometry's in a flat one.
uint32_t hit_instance(uint32_t inst_id, uint32_t geom_id) {
  return inst_id != RTC_INVALID_GEOMETRY_ID ? inst_id : geom_id;
}

void alpha_filter(const RTCFilterFunctionNArguments* args) {
  const auto* ctx = reinterpret_cast<const TandemRayContext*>(args->context);
  for (unsigned i = 0; i < args->N; ++i) {
    if (args->valid[i] == 0) continue;
    const uint32_t instance = hit_instance(RTCHitN_instID(args->hit, args->N, i, 0),
                                           RTCHitN_geomID(args->hit, args->N, i));
    const uint32_t prim = RTCHitN_primID(args->hit, args->N, i);
    const float u = RTCHitN_u(args->hit, args->N, i), v = RTCHitN_v(args->hit, args->N, i);
    const uint32_t alpha_key = RTCRayN_id(args->ray, args->N, i);
    if (!alpha_test_opaque(*ctx->kd, instance, prim, u, v, alpha_key)) args->valid[i] = 0;
  }
}

void embree_error(void*, RTCError code, const char* message) {
  log_warning(std::string("Embree error ") + std::to_string(int(code)) + ": " +
              (message ? message : ""));
}

RTCRay make_rtc_ray(const Ray& r, uint32_t alpha_key) {
  RTCRay ray;
  ray.org_x = r.origin.x;
  ray.org_y = r.origin.y;
  ray.org_z = r.origin.z;
  ray.tnear = r.tmin;
  ray.dir_x = r.dir.x;
  ray.dir_y = r.dir.y;
  ray.dir_z = r.dir.z;
  ray.time = 0.0f;
  ray.tfar = r.tmax;
  ray.mask = 0xffffffffu;
  ray.id = alpha_key;
  ray.flags = 0;
  return ray;
}

}  // namespace

Hit EmbreeTracer::intersect(const Ray& ray, uint32_t alpha_key) const {
  TandemRayContext ctx = make_context(kd);
  RTCRayHit rh;
  rh.ray = make_rtc_ray(ray, alpha_key);
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
  rtcIntersect1(scene, &ctx.rtc, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return make_miss();
  return {rh.ray.tfar, rh.hit.u, rh.hit.v, hit_instance(rh.hit.instID[0], rh.hit.geomID),
          rh.hit.primID};
}

bool EmbreeTracer::occluded(const Ray& ray, uint32_t alpha_key) const {
  TandemRayContext ctx = make_context(kd);
  RTCRay r = make_rtc_ray(ray, alpha_key);
  rtcOccluded1(scene, &ctx.rtc, &r);
  return r.tfar < 0.0f;  // Embree sets tfar = -inf on a hit
}

namespace {

// Lane j of a packet from rays[j] (the lanes past n are switched off).
template <class Packet, uint32_t W>
void fill_packet(Packet& p, const Ray* rays, const uint32_t* keys, uint32_t n, int* valid) {
  for (uint32_t j = 0; j < W; ++j) {
    valid[j] = j < n ? -1 : 0;
    const Ray& r = rays[j < n ? j : 0];
    p.org_x[j] = r.origin.x;
    p.org_y[j] = r.origin.y;
    p.org_z[j] = r.origin.z;
    p.tnear[j] = r.tmin;
    p.dir_x[j] = r.dir.x;
    p.dir_y[j] = r.dir.y;
    p.dir_z[j] = r.dir.z;
    p.time[j] = 0.0f;
    p.tfar[j] = r.tmax;
    p.mask[j] = 0xffffffffu;
    p.id[j] = keys[j < n ? j : 0];
    p.flags[j] = 0;
  }
}

}  // namespace

void EmbreePacketTracer::intersect_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                                          Hit* hits) const {
  TandemRayContext ctx = make_context(kd);
  alignas(64) RTCRayHit16 rh;
  alignas(64) int valid[16];
  fill_packet<RTCRay16, 16>(rh.ray, rays, alpha_keys, n, valid);
  for (uint32_t j = 0; j < 16; ++j) {
    rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
  }
  rtcIntersect16(valid, scene, &ctx.rtc, &rh);
  for (uint32_t j = 0; j < n; ++j) {
    hits[j] = rh.hit.geomID[j] == RTC_INVALID_GEOMETRY_ID
                  ? make_miss()
                  : Hit{rh.ray.tfar[j], rh.hit.u[j], rh.hit.v[j],
                        hit_instance(rh.hit.instID[0][j], rh.hit.geomID[j]), rh.hit.primID[j]};
  }
}

void EmbreePacketTracer::intersect_coherent(const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                                            Hit* hits) const {
  TandemRayContext ctx = make_context(kd);
  ctx.rtc.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
  for (uint32_t o = 0; o < n; o += 8) {
    const uint32_t m = n - o < 8 ? n - o : 8;
    alignas(32) RTCRayHit8 rh;
    alignas(32) int valid[8];
    fill_packet<RTCRay8, 8>(rh.ray, rays + o, alpha_keys + o, m, valid);
    for (uint32_t j = 0; j < 8; ++j) {
      rh.hit.geomID[j] = RTC_INVALID_GEOMETRY_ID;
      rh.hit.instID[0][j] = RTC_INVALID_GEOMETRY_ID;
    }
    rtcIntersect8(valid, scene, &ctx.rtc, &rh);
    for (uint32_t j = 0; j < m; ++j) {
      hits[o + j] =
          rh.hit.geomID[j] == RTC_INVALID_GEOMETRY_ID
              ? make_miss()
              : Hit{rh.ray.tfar[j], rh.hit.u[j], rh.hit.v[j],
                    hit_instance(rh.hit.instID[0][j], rh.hit.geomID[j]), rh.hit.primID[j]};
    }
  }
}

void EmbreePacketTracer::occluded_packet(const Ray* rays, const uint32_t* alpha_keys, uint32_t n,
                                         bool* occluded) const {
  TandemRayContext ctx = make_context(kd);
  alignas(64) RTCRay16 r;
  alignas(64) int valid[16];
  fill_packet<RTCRay16, 16>(r, rays, alpha_keys, n, valid);
  rtcOccluded16(valid, scene, &ctx.rtc, &r);
  for (uint32_t j = 0; j < n; ++j)
    occluded[j] = r.tfar[j] < 0.0f;
}

EmbreeScene::EmbreeScene() {
  device_ = rtcNewDevice(nullptr);
  if (!device_) {
    throw std::runtime_error("cannot create an Embree device (error " +
                             std::to_string(int(rtcGetDeviceError(nullptr))) + ")");
  }
  rtcSetDeviceErrorFunction(device_, embree_error, nullptr);
}

EmbreeScene::~EmbreeScene() {
  release_scenes();
  if (device_) rtcReleaseDevice(device_);
}

RTCGeometry new_mesh_geometry(RTCDevice device, const KernelScene& ks, uint32_t mesh,
                              RTCBuildQuality quality) {
  const KMesh& km = ks.meshes[mesh];
  RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, ks.positions.data(),
                             size_t(km.vertex_offset) * sizeof(Vec3), sizeof(Vec3),
                             km.vertex_count);
  rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, ks.triangles.data(),
                             size_t(km.triangle_offset) * sizeof(KTriangle), sizeof(KTriangle),
                             km.triangle_count);
  rtcSetGeometryBuildQuality(g, quality);
  return g;
}

void EmbreeScene::release_scenes() {
  if (top_) rtcReleaseScene(top_);
  top_ = nullptr;
  for (RTCScene s : blas_) {
    if (s) rtcReleaseScene(s);
  }
  blas_.clear();
}

namespace {

// Flat only without real instancing: a mesh in the top-level scene itself
// can be placed once.
bool can_flatten(const KernelScene& ks) {
  std::vector<uint8_t> used(ks.meshes.size(), 0);
  for (const KInstance& inst : ks.instances) {
    if (inst.mesh >= used.size() || used[inst.mesh]) return false;
    used[inst.mesh] = 1;
  }
  return true;
}

}  // namespace

void EmbreeScene::build_all(const KernelScene& ks) {
  release_scenes();
  flat_ = !dynamic_ && can_flatten(ks);
  if (flat_) {
    build_flat(ks);
  } else {
    build_two_level(ks);
  }
}

RTCScene EmbreeScene::build_blas(const KernelScene& ks, uint32_t mesh) {
  const KMesh& km = ks.meshes[mesh];
  RTCScene blas = rtcNewScene(device_);
  rtcSetSceneFlags(blas, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(blas, RTC_BUILD_QUALITY_HIGH);
  if (km.triangle_count > 0) attach_mesh(blas, ks, mesh, 0);
  rtcCommitScene(blas);
  return blas;
}

void EmbreeScene::attach_mesh(RTCScene scene, const KernelScene& ks, uint32_t mesh, unsigned id) {
  RTCGeometry g = new_mesh_geometry(device_, ks, mesh, RTC_BUILD_QUALITY_HIGH);
  if (ks.meshes[mesh].flags & kMeshHasAlphaTest) {
    rtcSetGeometryIntersectFilterFunction(g, alpha_filter);
    rtcSetGeometryOccludedFilterFunction(g, alpha_filter);
  }
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(scene, g, id);
  rtcReleaseGeometry(g);
}

namespace {

// An instance's transform and whether it is traced. A hidden instance
// (kInstanceHidden: zero transforms) is disabled, with the identity in
// place of its transform, which Embree would invert.
void set_instance(RTCGeometry g, const KInstance& inst) {
  static const Mat34 kIdentity = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
  const bool hidden = (inst.flags & kInstanceHidden) != 0u;
  rtcSetGeometryTransform(g, 0, RTC_FORMAT_FLOAT3X4_ROW_MAJOR,
                          hidden ? &kIdentity : &inst.object_to_world);
  if (hidden)
    rtcDisableGeometry(g);
  else
    rtcEnableGeometry(g);
}

}  // namespace

void EmbreeScene::attach_instance(const KInstance& inst, unsigned id) {
  RTCGeometry g = rtcNewGeometry(device_, RTC_GEOMETRY_TYPE_INSTANCE);
  rtcSetGeometryInstancedScene(g, blas_[inst.mesh]);
  set_instance(g, inst);
  rtcCommitGeometry(g);
  rtcAttachGeometryByID(top_, g, id);
  rtcReleaseGeometry(g);
}

void EmbreeScene::build_flat(const KernelScene& ks) {
  blas_.assign(ks.meshes.size(), nullptr);
  top_ = rtcNewScene(device_);
  rtcSetSceneFlags(top_, RTC_SCENE_FLAG_ROBUST);
  rtcSetSceneBuildQuality(top_, RTC_BUILD_QUALITY_HIGH);
  for (size_t i = 0; i < ks.instances.size(); ++i) {
    const KInstance& inst = ks.instances[i];
    if (inst.flags & kInstanceIdentity) {
      if (ks.meshes[inst.mesh].triangle_count > 0) attach_mesh(top_, ks, inst.mesh, unsigned(i));
    } else {
      blas_[inst.mesh] = build_blas(ks, inst.mesh);
      attach_instance(inst, unsigned(i));
    }
  }
  rtcCommitScene(top_);
}

void EmbreeScene::build_two_level(const KernelScene& ks) {
  blas_.resize(ks.meshes.size());
  // BLAS builds are independent; Embree parallelises inside each build too.
  for (size_t m = 0; m < ks.meshes.size(); ++m)
    blas_[m] = build_blas(ks, uint32_t(m));
  top_ = rtcNewScene(device_);
  rtcSetSceneFlags(top_, RTC_SCENE_FLAG_DYNAMIC);
  mesh_instances_.assign(ks.meshes.size(), {});
  for (size_t i = 0; i < ks.instances.size(); ++i) {
    attach_instance(ks.instances[i], unsigned(i));
    if (ks.instances[i].mesh < ks.meshes.size())
      mesh_instances_[ks.instances[i].mesh].push_back(uint32_t(i));
  }
  rtcCommitScene(top_);
}

void EmbreeScene::sync(const KernelScene& ks, const SceneDelta& delta) {
  last_instance_commits_ = 0;
  // Embree shares our vertex/index memory, so a reallocated array means the
  // BLAS must be rebuilt against the new storage.
  if (delta.full || !top_ || delta.positions.reallocated || delta.triangles.reallocated ||
      delta.meshes.reallocated || delta.instances.reallocated || !delta.meshes_rebuilt.empty()) {
    build_all(ks);
  } else if (flat_) {
    // The flat layout has no cheap update: switch to the two-level one,
    // which refits and moves instances, for good.
    if (delta.instances_changed()) {
      dynamic_ = true;
      build_all(ks);
    }
  } else {
    for (uint32_t m : delta.meshes_refit) {
      if (m >= blas_.size() || ks.meshes[m].triangle_count == 0) continue;  // no geometry
      // Deforming meshes get Embree's refit: per-geometry build quality
      // only counts in a two-level (LOW quality) scene, where REFIT keeps
      // the topology and only recomputes the boxes after the first build,
      // and only when the scene is also flagged DYNAMIC (without the flag
      // every commit is a full build: about 1 s instead of 60 ms for two
      // million triangles on 2 cores, measured 2026-12-01). Switched once
      // (the geometry's user data, unused otherwise, marks it): a change
      // of quality makes Embree build the BVH anew.
      RTCGeometry g = rtcGetGeometry(blas_[m], 0);
      static int refitting = 0;
      if (rtcGetGeometryUserData(g) != &refitting) {
        rtcSetSceneFlags(blas_[m], RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_ROBUST);
        rtcSetSceneBuildQuality(blas_[m], RTC_BUILD_QUALITY_LOW);
        rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
        rtcSetGeometryUserData(g, &refitting);
      }
      rtcUpdateGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0);
      rtcCommitGeometry(g);
      rtcCommitScene(blas_[m]);
    }
    // Committed again: the instances whose record changed (the exact list
    // when the delta has one, else its ranges), and the instances of refit
    // meshes, whose BLAS bounds changed; never the others, which a walk of
    // the bounding range or of every instance would recommit in a scene of
    // many instances where one mesh deforms.
    std::vector<uint32_t> commit;
    if (!delta.instances_moved.empty()) {
      commit = delta.instances_moved;
    } else {
      delta.instances.for_each_range([&](uint32_t b, uint32_t e) {
        for (uint32_t i = b; i < e; ++i)
          commit.push_back(i);
      });
    }
    for (uint32_t i : commit)
      set_instance(rtcGetGeometry(top_, i), ks.instances[i]);
    for (uint32_t m : delta.meshes_refit) {
      if (m < mesh_instances_.size())
        commit.insert(commit.end(), mesh_instances_[m].begin(), mesh_instances_[m].end());
    }
    std::sort(commit.begin(), commit.end());
    commit.erase(std::unique(commit.begin(), commit.end()), commit.end());
    for (uint32_t i : commit)
      rtcCommitGeometry(rtcGetGeometry(top_, i));
    last_instance_commits_ = uint32_t(commit.size());
    if (last_instance_commits_ > 0) rtcCommitScene(top_);
  }
}

}  // namespace tandem
