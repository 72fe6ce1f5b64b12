// Helpers shared by the accstruc tests: compiled scenes with both our BVH and
// Embree built, random rays of the three kinds the renderer traces, and
// ray-by-ray comparison of two tracers.
#pragma once

#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "accstruc/accel_structure.h"
#include "backends/cpu/cpu_backend.h"
#include "core/kernel/bvh_traverse.h"
#include "core/kernel/camera.h"
#include "core/kernel/geometry.h"
#include "core/kernel/rng.h"
#include "core/kernel/sampling.h"
#include "core/world/kernel_scene.h"
#include "scenes/scene_loader.h"
#include "tests/world_compile_util.h"

namespace tandem::accstruc_test {

// Settings for tests: no disk cache (tests must not write to ~/.cache).
inline AccelSettings test_settings() {
  AccelSettings s;
  s.cache.enabled = false;
  return s;
}

// A scene compiled into kernel arrays, with our BVH and Embree on it.
struct TracedScene {
  Scene scene;
  KernelScene ks;
  SceneCompiler compiler;
  RenderSettings settings;
  AccelStructure accel;
  CpuBackend embree{CpuTraversal::kEmbree};
  SceneBounds bounds;

  explicit TracedScene(Scene s, AccelSettings a = test_settings())
      : scene(std::move(s)), accel(std::move(a)) {
    bounds = scene.bounds();
    if (!scene.has_camera()) scene.set_camera(frame_bounds_camera(bounds, 0.7f, 1.0f));
    settings.width = 256;
    settings.height = 256;
    SceneDelta delta = compile_taking_changes(compiler, scene, settings, ks);
    delta.merge(accel.update(ks, delta).delta);
    embree.sync(ks, delta);
  }
  // Applies the scene's edits to both structures; returns what our side did.
  AccelUpdate recompile(SceneDelta* delta_out = nullptr) {
    SceneDelta delta = compile_taking_changes(compiler, scene, settings, ks);
    const AccelUpdate up = accel.update(ks, delta);
    delta.merge(up.delta);
    embree.sync(ks, delta);
    if (delta_out) *delta_out = delta;
    return up;
  }
  KernelData kd() const { return ks.view(); }
};

class TestRandom {
 public:
  explicit TestRandom(uint32_t seed) : key_(hash_u32(seed * 0x9e3779b9u + 17u)) {}
  float uniform() { return u32_to_unit_float(hash_combine(key_, counter_++)); }
  uint32_t bits() { return hash_combine(key_ ^ 0x5bd1e995u, counter_++); }

 private:
  uint32_t key_;
  uint32_t counter_ = 0;
};

// The BVH built from scratch on a copy of `from`'s kernel arrays: what a
// refit or a partial update must agree with.
struct FreshBuild {
  KernelScene ks;
  AccelStructure accel{test_settings()};
  explicit FreshBuild(const KernelScene& from) : ks(from) {
    SceneDelta full;
    full.full = true;
    accel.update(ks, full);
  }
};

struct RaySample {
  Ray ray;
  uint32_t alpha_key;
};

// A uniformly chosen triangle of a uniformly chosen non-empty instance.
inline bool random_surface_point(const KernelData& kd, TestRandom& rng, SurfacePoint* sp) {
  if (kd.instances_count == 0) return false;
  for (int attempt = 0; attempt < 64; ++attempt) {
    const uint32_t inst = rng.bits() % kd.instances_count;
    const KMesh& mesh = kd.meshes[kd.instances[inst].mesh];
    if (mesh.triangle_count == 0) continue;
    const uint32_t prim = rng.bits() % mesh.triangle_count;
    // Draws named in turn: the order of a call's arguments is unspecified
    // (g++ and clang differ), and the rays must not depend on the compiler.
    const float u1 = rng.uniform(), u0 = rng.uniform();
    const Vec2 b = sample_triangle_barycentrics(u0, u1);
    *sp = make_light_point(kd, inst, prim, b.x, b.y);
    if (is_finite(sp->position) && sp->area_world > 0.0f) return true;
  }
  return false;
}

// Half from the scene camera over the whole film, half from random points
// inside the scene bounds in uniformly random directions.
inline std::vector<RaySample> primary_rays(const TracedScene& s, uint32_t count, uint32_t seed) {
  TestRandom rng(seed);
  std::vector<RaySample> rays;
  const KCamera& cam = s.ks.constants.camera;
  // Bounds grown by 5% of the diagonal, so that flat scenes do not put
  // every origin on a surface (where a hit at t ~ 0 is ill-defined).
  const Vec3 blo = {s.bounds.lo.x, s.bounds.lo.y, s.bounds.lo.z};
  const Vec3 bhi = {s.bounds.hi.x, s.bounds.hi.y, s.bounds.hi.z};
  const float margin = 0.05f * length(bhi - blo);
  const Vec3 lo = blo - make_vec3(margin), hi = bhi + make_vec3(margin);
  for (uint32_t i = 0; i < count; ++i) {
    Ray r;
    if (i % 2 == 0) {
      const float lens_v = rng.uniform(), lens_u = rng.uniform();
      const float y = rng.uniform() * float(cam.height), x = rng.uniform() * float(cam.width);
      r = generate_camera_ray(cam, x, y, lens_u, lens_v);
    } else {
      r.origin = {lo.x + (hi.x - lo.x) * rng.uniform(), lo.y + (hi.y - lo.y) * rng.uniform(),
                  lo.z + (hi.z - lo.z) * rng.uniform()};
      const float u1 = rng.uniform(), u0 = rng.uniform();
      r.dir = sample_uniform_sphere(u0, u1);
      r.tmin = 0.0f;
      r.tmax = kFloatMax;
    }
    rays.push_back({r, rng.bits()});
  }
  return rays;
}

// Segments from a random surface point, shortened at the far end as the
// integrator's shadow rays are: half end at another random surface point,
// half at a random point of the (grown) scene bounds, like a point light, so
// that large scenes get unoccluded segments too. Pairs whose segment grazes
// either surface (|cos| < 0.01, e.g. both points on one planar face) are
// skipped: there the far end's distance to its own surface is decided by
// rounding, for any tracer, and such segments carry no light (the cosines
// are ~0).
inline std::vector<RaySample> shadow_rays(const TracedScene& s, uint32_t count, uint32_t seed) {
  TestRandom rng(seed);
  const KernelData kd = s.kd();
  const Vec3 blo = {s.bounds.lo.x, s.bounds.lo.y, s.bounds.lo.z};
  const Vec3 bhi = {s.bounds.hi.x, s.bounds.hi.y, s.bounds.hi.z};
  const float margin = 0.05f * length(bhi - blo);
  const Vec3 lo = blo - make_vec3(margin), hi = bhi + make_vec3(margin);
  std::vector<RaySample> rays;
  SurfacePoint a, b;
  uint32_t attempts = 0;
  while (rays.size() < count && attempts++ < 20 * count) {
    if (!random_surface_point(kd, rng, &a)) break;
    if (attempts % 2 == 0) {
      if (!random_surface_point(kd, rng, &b)) break;
    } else {
      b.position = {lo.x + (hi.x - lo.x) * rng.uniform(), lo.y + (hi.y - lo.y) * rng.uniform(),
                    lo.z + (hi.z - lo.z) * rng.uniform()};
      b.geometric_normal = normalize(b.position - a.position);  // not a surface: never grazing
    }
    const Vec3 d = b.position - a.position;
    if (length_sq(d) <= 0.0f) continue;
    const Vec3 dn = normalize(d);
    if (std::fabs(dot(dn, a.geometric_normal)) < 0.01f ||
        std::fabs(dot(dn, b.geometric_normal)) < 0.01f) {
      continue;
    }
    rays.push_back({spawn_shadow_ray(a, b.position), rng.bits()});
  }
  return rays;
}

// Cosine-distributed directions about either side of random surface points,
// origin offset with offset_ray_origin (spawn_ray).
inline std::vector<RaySample> diffuse_rays(const TracedScene& s, uint32_t count, uint32_t seed) {
  TestRandom rng(seed);
  const KernelData kd = s.kd();
  std::vector<RaySample> rays;
  SurfacePoint sp;
  while (rays.size() < count) {
    if (!random_surface_point(kd, rng, &sp)) break;
    const Vec3 n = rng.uniform() < 0.5f ? sp.geometric_normal : -sp.geometric_normal;
    const float u1 = rng.uniform(), u0 = rng.uniform();
    const Vec3 local = sample_cosine_hemisphere(u0, u1);
    const Vec3 dir = normalize(to_world(make_frame(n), local));
    rays.push_back({spawn_ray(sp, dir), rng.bits()});
  }
  return rays;
}

struct Agreement {
  uint64_t rays = 0, agree = 0, hits = 0;
  uint64_t coincident = 0;  // agreeing hits on different but coincident triangles
  uint64_t wrong_prim = 0, wrong_t = 0, only_ours = 0, only_theirs = 0;
  uint64_t confirmed = 0;  // mismatches where the long-double reference sides with us
  double fraction() const { return rays ? double(agree) / double(rays) : 1.0; }
  // Agreement, or a mismatch in which the long-double reference sides with
  // us (the other tracer's rounding): for samples too small for fraction()
  // to allow a single mismatch (below 1000 rays at 99.9%).
  double fraction_ours_right() const {
    return rays ? double(agree + confirmed) / double(rays) : 1.0;
  }
  std::string summary() const {
    char buf[320];
    std::snprintf(
        buf, sizeof buf,
        "%7.3f%% of %llu agree (%llu hit, %llu on coincident triangles; mismatches: prim %llu, "
        "t %llu, only ours %llu, only Embree %llu; reference confirms ours in %llu)",
        100.0 * fraction(), (unsigned long long)rays, (unsigned long long)hits,
        (unsigned long long)coincident, (unsigned long long)wrong_prim, (unsigned long long)wrong_t,
        (unsigned long long)only_ours, (unsigned long long)only_theirs,
        (unsigned long long)confirmed);
    return buf;
  }
};

// Distance at which the given triangle of the given instance is hit, with
// the same object-space transform and test as the traversal (no interval).
inline bool triangle_hit_distance(const KernelData& kd, const Ray& ray, uint32_t instance,
                                  uint32_t prim, float* t) {
  const KInstance& inst = kd.instances[instance];
  const TriangleVertices tv = fetch_triangle(kd, inst.mesh, prim);
  const Vec3 translation = {inst.object_to_world.rows[0].w, inst.object_to_world.rows[1].w,
                            inst.object_to_world.rows[2].w};
  const Vec3 o = transform_vector(inst.world_to_object, ray.origin - translation);
  const Vec3 d = transform_vector(inst.world_to_object, ray.dir);
  TriangleHit th;
  if (!intersect_triangle_watertight(make_shear_ray(o, d), tv.p0, tv.p1, tv.p2, -kFloatMax,
                                     kFloatMax, &th)) {
    return false;
  }
  *t = th.t;
  return true;
}

// Extended-precision reference for arbitrating mismatches: intersects the
// ray with the triangle transformed to world space by object_to_world, in
// long double. Returns the smallest barycentric (negative: the ray passes
// outside) and the distance.
struct ExactHit {
  long double t, min_bary;
};
inline ExactHit exact_triangle_hit(const KernelData& kd, const Ray& ray, uint32_t instance,
                                   uint32_t prim) {
  using LD = long double;
  const KInstance& inst = kd.instances[instance];
  const TriangleVertices tv = fetch_triangle(kd, inst.mesh, prim);
  auto to_world = [&](Vec3 p, LD* out) {
    for (int i = 0; i < 3; ++i) {
      const Vec4& r = inst.object_to_world.rows[i];
      out[i] = LD(r.x) * p.x + LD(r.y) * p.y + LD(r.z) * p.z + LD(r.w);
    }
  };
  LD a[3], b[3], c[3];
  to_world(tv.p0, a);
  to_world(tv.p1, b);
  to_world(tv.p2, c);
  const LD o[3] = {ray.origin.x, ray.origin.y, ray.origin.z},
           d[3] = {ray.dir.x, ray.dir.y, ray.dir.z};
  LD e1[3], e2[3], s[3];
  for (int i = 0; i < 3; ++i) {
    e1[i] = b[i] - a[i];
    e2[i] = c[i] - a[i];
    s[i] = o[i] - a[i];
  }
  auto cross3 = [](const LD* x, const LD* y, LD* z) {
    z[0] = x[1] * y[2] - x[2] * y[1];
    z[1] = x[2] * y[0] - x[0] * y[2];
    z[2] = x[0] * y[1] - x[1] * y[0];
  };
  auto dot3 = [](const LD* x, const LD* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
  LD p[3], q[3];
  cross3(d, e2, p);
  const LD det = dot3(e1, p);
  if (det == 0) return {0, -1};
  cross3(s, e1, q);
  const LD u = dot3(s, p) / det, v = dot3(d, q) / det;
  return {dot3(e2, q) / det, std::min({u, v, LD(1) - u - v})};
}

// True when the reference says our answer is the right one: our triangle is
// really hit (or we missed), and Embree's triangle is really missed or
// farther away.
inline bool reference_confirms_ours(const KernelData& kd, const Ray& ray, const Hit& ours,
                                    const Hit& theirs) {
  const bool ours_real =
      !hit_valid(ours) || exact_triangle_hit(kd, ray, ours.instance, ours.prim).min_bary >= 0;
  if (!ours_real) return false;
  if (!hit_valid(theirs)) return true;
  const ExactHit e = exact_triangle_hit(kd, ray, theirs.instance, theirs.prim);
  if (e.min_bary < 0 || e.t <= ray.tmin || e.t >= ray.tmax) return true;
  return hit_valid(ours) && ours.t <= e.t;
}

// Hit distances agree when within 1e-4 relative, or within 1e-6 of the
// scene's size: both tracers' t carries an absolute error of a few ulps of
// the coordinates involved, which dominates for hits at distances below
// ~1% of the scene (e.g. between layered surfaces of ToyCar, 2 um apart).
struct DistanceTolerance {
  float absolute;
  bool same(float a, float b) const {
    const float diff = std::fabs(a - b);
    return diff <= 1e-4f * std::max(std::fabs(a), std::fabs(b)) || diff <= absolute;
  }
};

inline DistanceTolerance distance_tolerance(const SceneBounds& b) {
  return {1e-6f * std::max(glm::length(b.hi - b.lo), 1e-20f)};
}

// Closest hits: same (instance, prim) or both miss, and t within tolerance
// when both hit. A different triangle at the same distance counts as
// agreement only when that triangle is itself hit at that distance, i.e.
// the two are coincident (duplicated faces, shared edges): which one wins is
// a matter of rounding and traversal order.
inline Agreement compare_closest(const KernelData& kd, const DistanceTolerance& tol,
                                 const std::vector<RaySample>& rays,
                                 const std::function<Hit(const RaySample&)>& ours,
                                 const std::function<Hit(const RaySample&)>& theirs) {
  std::atomic<uint64_t> agree{0}, hits{0}, coincident{0}, wrong_prim{0}, wrong_t{0}, only_ours{0},
      only_theirs{0}, confirmed{0};
  tbb::parallel_for(size_t(0), rays.size(), [&](size_t i) {
    const Hit a = ours(rays[i]), b = theirs(rays[i]);
    const bool ha = hit_valid(a), hb = hit_valid(b);
    if (!ha && !hb) {
      ++agree;
      return;
    }
    if (ha != hb) {
      ++(ha ? only_ours : only_theirs);
      confirmed += reference_confirms_ours(kd, rays[i].ray, a, b) ? 1u : 0u;
      return;
    }
    ++hits;
    if (!tol.same(a.t, b.t)) {
      ++(a.instance != b.instance || a.prim != b.prim ? wrong_prim : wrong_t);
      if (a.instance != b.instance || a.prim != b.prim) {
        confirmed += reference_confirms_ours(kd, rays[i].ray, a, b) ? 1u : 0u;
      }
      return;
    }
    if (a.instance != b.instance || a.prim != b.prim) {
      float ta, tb;
      if (triangle_hit_distance(kd, rays[i].ray, a.instance, a.prim, &ta) &&
          triangle_hit_distance(kd, rays[i].ray, b.instance, b.prim, &tb) && tol.same(ta, tb)) {
        ++coincident;
        ++agree;
      } else {
        ++wrong_prim;
        confirmed += reference_confirms_ours(kd, rays[i].ray, a, b) ? 1u : 0u;
      }
      return;
    }
    ++agree;
  });
  Agreement r;
  r.rays = rays.size();
  r.agree = agree;
  r.hits = hits;
  r.coincident = coincident;
  r.wrong_prim = wrong_prim;
  r.wrong_t = wrong_t;
  r.only_ours = only_ours;
  r.only_theirs = only_theirs;
  r.confirmed = confirmed;
  return r;
}

inline Agreement compare_occlusion(const std::vector<RaySample>& rays,
                                   const std::function<bool(const RaySample&)>& ours,
                                   const std::function<bool(const RaySample&)>& theirs) {
  std::atomic<uint64_t> agree{0}, hits{0}, only_ours{0}, only_theirs{0};
  tbb::parallel_for(size_t(0), rays.size(), [&](size_t i) {
    const bool a = ours(rays[i]), b = theirs(rays[i]);
    if (a == b) {
      ++agree;
      hits += a ? 1u : 0u;
    } else {
      ++(a ? only_ours : only_theirs);
    }
  });
  Agreement r;
  r.rays = rays.size();
  r.agree = agree;
  r.hits = hits;
  r.only_ours = only_ours;
  r.only_theirs = only_theirs;
  return r;
}

inline const char* layout_name(uint32_t layout) {
  return layout == kBvhLayoutWide ? "wide" : "binary";
}

// Camera, diffuse and shadow rays (rays_per_kind each) through both of our
// layouts against Embree on the same scene: at least `required` of each kind
// agree, and something is hit.
inline void expect_hits_like_embree(TracedScene& s, const std::string& name, uint32_t rays_per_kind,
                                    double required) {
  const KernelData kd = s.kd();
  const DistanceTolerance tol = distance_tolerance(s.bounds);
  const auto primary = primary_rays(s, rays_per_kind, 1);
  const auto shadow = shadow_rays(s, rays_per_kind, 2);
  const auto diffuse = diffuse_rays(s, rays_per_kind, 3);
  auto embree_hit = [&](const RaySample& r) { return s.embree.intersect(r.ray, r.alpha_key); };
  auto embree_occ = [&](const RaySample& r) { return s.embree.occluded(r.ray, r.alpha_key); };
  for (uint32_t layout : {uint32_t(kBvhLayoutBinary), uint32_t(kBvhLayoutWide)}) {
    auto our_hit = [&](const RaySample& r) {
      return bvh_intersect(kd, r.ray, r.alpha_key, layout);
    };
    auto our_occ = [&](const RaySample& r) { return bvh_occluded(kd, r.ray, r.alpha_key, layout); };
    const Agreement p = compare_closest(kd, tol, primary, our_hit, embree_hit);
    const Agreement d = compare_closest(kd, tol, diffuse, our_hit, embree_hit);
    const Agreement o = compare_occlusion(shadow, our_occ, embree_occ);
    std::printf("[accstruc] %-40s %-6s primary %s\n", name.c_str(), layout_name(layout),
                p.summary().c_str());
    std::printf("[accstruc] %-40s %-6s diffuse %s\n", name.c_str(), layout_name(layout),
                d.summary().c_str());
    std::printf("[accstruc] %-40s %-6s shadow  %s\n", name.c_str(), layout_name(layout),
                o.summary().c_str());
    EXPECT_GE(p.fraction(), required) << name << " primary " << layout_name(layout);
    EXPECT_GE(d.fraction(), required) << name << " diffuse " << layout_name(layout);
    EXPECT_GE(o.fraction(), required) << name << " shadow " << layout_name(layout);
    // A comparison where nothing is hit proves nothing.
    EXPECT_GT(p.hits + d.hits + o.hits, 0u) << name;
  }
}

}  // namespace tandem::accstruc_test
