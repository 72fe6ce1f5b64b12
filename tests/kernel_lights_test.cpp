// Tests of light sampling (core/kernel/lights.h) on small hand-built
// KernelScenes: the solid-angle pdf of emissive triangles (against analytic
// solid angle and irradiance), the punctual lights, and the light list that
// mixes them with the environment (whose own tests are in
// kernel_environment_test.cpp).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstring>
#include <optional>
#include <vector>

#include "core/kernel/integrator.h"
#include "core/kernel/lights.h"
#include "core/world/kernel_scene.h"
#include "core/world/light_tables.h"
#include "kernel_light_test_scenes.h"
#include "test_stats.h"

namespace tandem {
namespace {

using light_test::make_environment_scene;
using test_stats::MeanAccumulator;
using test_stats::sidak_alpha;
using test_stats::TestRng;

// The chi-square tests of the lights' family: two here (triangle
// directions, light selection), two in kernel_environment_test.cpp
// (environment directions), each at the family's Sidak level.
const double kAlpha = sidak_alpha(test_stats::kFamilySignificance, 4);

// ---------------------------------------------------------------------------
// Emissive triangles.

KTextureRef no_texture() {
  KTextureRef r{};
  r.texture = -1;
  r.m[0] = r.m[4] = 1.0f;  // identity transform
  return r;
}

KMaterial emissive_material(Vec3 emission, bool double_sided) {
  KMaterial m{};
  m.base_color = make_vec4(0.8f, 0.8f, 0.8f, 1.0f);
  m.emission = emission;
  m.specular_color = make_vec3(1.0f);
  m.roughness = 1.0f;
  m.ior = 1.5f;
  m.specular = 1.0f;
  m.flags = double_sided ? kMaterialDoubleSided : 0u;
  m.normal_scale = 1.0f;
  m.emission_luminance_scale = 1.0f;
  m.base_color_tex = m.metallic_roughness_tex = m.normal_tex = m.emissive_tex = m.transmission_tex =
      m.clearcoat_tex = m.clearcoat_roughness_tex = m.sheen_color_tex = m.sheen_roughness_tex =
          no_texture();
  return m;
}

// Affine transform x -> A x + t and its inverse, from a 3x3 matrix in double.
struct Affine {
  Mat34 forward, inverse;
};
Affine make_affine(const std::array<std::array<double, 3>, 3>& a, Vec3 t) {
  Affine r;
  const double det = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                     a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                     a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  double inv[3][3];
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      // Cofactor of (j, i) over det.
      const int r0 = (j + 1) % 3, r1 = (j + 2) % 3, c0 = (i + 1) % 3, c1 = (i + 2) % 3;
      inv[i][j] = (a[r0][c0] * a[r1][c1] - a[r0][c1] * a[r1][c0]) / det;
    }
  }
  const double tv[3] = {t.x, t.y, t.z};
  for (int i = 0; i < 3; ++i) {
    double it = 0.0;
    for (int j = 0; j < 3; ++j)
      it -= inv[i][j] * tv[j];
    r.forward.rows[i] = make_vec4(float(a[i][0]), float(a[i][1]), float(a[i][2]), float(tv[i]));
    r.inverse.rows[i] = make_vec4(float(inv[i][0]), float(inv[i][1]), float(inv[i][2]), float(it));
  }
  return r;
}

// Rz(40 deg) * Rx(20 deg) * diag(1.5, 0.7, 1.2): rotated and non-uniformly
// scaled, positive determinant.
Affine rotated_scaled() {
  const double cz = std::cos(0.698), sz = std::sin(0.698), cx = std::cos(0.349),
               sx = std::sin(0.349);
  const double r[3][3] = {{cz, -sz * cx, sz * sx}, {sz, cz * cx, -cz * sx}, {0.0, sx, cx}};
  const double s[3] = {1.5, 0.7, 1.2};
  std::array<std::array<double, 3>, 3> a;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j)
      a[i][j] = r[i][j] * s[j];
  }
  return make_affine(a, make_vec3(2.5f, 0.4f, 0.8f));
}

struct WorldTriangle {
  Vec3 p[3];
  uint32_t instance, prim;
  Vec3 emission;
  bool double_sided;
};

// One mesh of two emissive triangles at z = 2 whose front faces (glTF
// winding) look down -z, instanced with the identity and with
// rotated_scaled(). Every triangle becomes a light, weighted by
// triangle_light_power as the scene compiler does.
struct TriangleLightScene {
  KernelScene ks;
  std::vector<WorldTriangle> triangles;
};

TriangleLightScene make_triangle_light_scene(bool double_sided) {
  TriangleLightScene s;
  KernelScene& ks = s.ks;
  ks.positions = {make_vec3(0.0f, 0.0f, 2.0f),   make_vec3(0.0f, 1.0f, 2.0f),
                  make_vec3(1.0f, 0.0f, 2.0f),   make_vec3(-0.4f, -0.2f, 2.0f),
                  make_vec3(-1.0f, -1.2f, 2.0f), make_vec3(0.0f)};  // last: padding for SSE loads
  const Vec3 emission[2] = {make_vec3(4.0f, 4.0f, 4.0f), make_vec3(1.0f, 2.0f, 3.0f)};
  ks.materials = {emissive_material(emission[0], double_sided),
                  emissive_material(emission[1], double_sided)};
  ks.triangles = {KTriangle{0, 1, 2, 0}, KTriangle{3, 0, 4, 1}};
  KMesh mesh{};
  mesh.vertex_offset = 0;
  mesh.vertex_count = 5;
  mesh.triangle_offset = 0;
  mesh.triangle_count = 2;
  mesh.flags = kMeshHasEmission;
  ks.meshes = {mesh};
  const Affine transforms[2] = {{mat34_identity(), mat34_identity()}, rotated_scaled()};
  for (const Affine& a : transforms) {
    KInstance inst{};
    inst.object_to_world = a.forward;
    inst.world_to_object = a.inverse;
    inst.mesh = 0;
    inst.handedness = 1.0f;
    // As the scene compiler flags it: the identity instance's lights are
    // sampled from their cached constants, the other's from the triangles.
    if (&a == &transforms[0]) inst.flags = kInstanceIdentity;
    ks.instances.push_back(inst);
  }
  // As the scene compiler lists them: the mesh's two triangle lights once,
  // one light per instance of it.
  const KernelData kd = ks.view();
  std::vector<double> triangle_power;
  KMeshLights ml{0, 2, kInvalidIndex, 0.0f};
  for (uint32_t p = 0; p < 2; ++p) {
    ks.triangle_lights.push_back(cache_triangle_light(kd, 0, p));
    triangle_power.push_back(ks.triangle_lights.back().power);
    ml.power += ks.triangle_lights.back().power;
  }
  ks.mesh_lights = {ml};
  ks.triangle_light_alias = build_alias_table(triangle_power);
  std::vector<double> power;
  for (uint32_t i = 0; i < ks.instances.size(); ++i) {
    double instance_power = 0.0;
    for (uint32_t p = 0; p < 2; ++p) {
      instance_power +=
          triangle_light_power(ks.materials[p], triangle_world_area(kd, ks.instances[i], p));
      WorldTriangle w;
      const KTriangle& t = ks.triangles[p];
      for (int k = 0; k < 3; ++k) {
        w.p[k] = transform_point(ks.instances[i].object_to_world, ks.positions[(&t.v0)[k]]);
      }
      w.instance = i;
      w.prim = p;
      w.emission = emission[p];
      w.double_sided = double_sided;
      s.triangles.push_back(w);
    }
    KLight light{};
    light.type = kLightMeshInstance;
    light.instance = i;
    light.power = float(instance_power);
    ks.instance_lights.push_back(uint32_t(ks.lights.size()));
    ks.lights.push_back(light);
    power.push_back(instance_power);
  }
  ks.light_alias = build_alias_table(power);
  double total = 0.0;
  for (double p : power)
    total += p;
  ks.constants.total_light_power = float(total);
  ks.constants.environment_light_index = kInvalidIndex;
  return s;
}

// Front normal of a world triangle (glTF counter-clockwise winding).
Vec3 front_normal(const WorldTriangle& t) {
  return normalize(cross(t.p[1] - t.p[0], t.p[2] - t.p[0]));
}

// Solid angle of a triangle seen from o (van Oosterom and Strackee 1983).
double solid_angle(const WorldTriangle& t, Vec3 o) {
  double a[3][3], len[3];
  for (int k = 0; k < 3; ++k) {
    const Vec3 d = t.p[k] - o;
    a[k][0] = d.x, a[k][1] = d.y, a[k][2] = d.z;
    len[k] = std::sqrt(a[k][0] * a[k][0] + a[k][1] * a[k][1] + a[k][2] * a[k][2]);
  }
  auto dotd = [](const double* x, const double* y) {
    return x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
  };
  const double triple = a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) -
                        a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0]) +
                        a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0]);
  const double denom = len[0] * len[1] * len[2] + dotd(a[0], a[1]) * len[2] +
                       dotd(a[0], a[2]) * len[1] + dotd(a[1], a[2]) * len[0];
  return 2.0 * std::atan2(std::fabs(triple), denom);
}

// Irradiance at o (normal n) from a triangle of constant radiance 1 above
// o's horizon: Lambert's polygon formula E = 1/2 sum_edges theta_e (n . g_e),
// g_e the unit normal of the plane through o and the edge.
double unit_irradiance(const WorldTriangle& t, Vec3 o, Vec3 n) {
  double sum = 0.0;
  for (int k = 0; k < 3; ++k) {
    const Vec3 a = normalize(t.p[k] - o), b = normalize(t.p[(k + 1) % 3] - o);
    const double theta = std::acos(std::clamp(double(dot(a, b)), -1.0, 1.0));
    sum += theta * double(dot(n, normalize(cross(a, b))));
  }
  return 0.5 * std::fabs(sum);
}

struct RayHit {
  double t, u, v;
  size_t triangle;
};

// Closest intersection of the ray o + t d (t > 0) with the scene's triangles
// (Moller-Trumbore in double), counting only faces that emit towards o.
std::optional<RayHit> intersect(const std::vector<WorldTriangle>& tris, Vec3 o, Vec3 d) {
  std::optional<RayHit> best;
  for (size_t i = 0; i < tris.size(); ++i) {
    const WorldTriangle& tri = tris[i];
    const Vec3 e1 = tri.p[1] - tri.p[0], e2 = tri.p[2] - tri.p[0];
    const Vec3 pv = cross(d, e2);
    const double det = dot(e1, pv);
    if (std::fabs(det) < 1e-12) continue;
    const Vec3 tv = o - tri.p[0];
    const double u = dot(tv, pv) / det;
    const Vec3 qv = cross(tv, e1);
    const double v = dot(d, qv) / det;
    const double t = dot(e2, qv) / det;
    if (u < 0.0 || v < 0.0 || u + v > 1.0 || t <= 1e-6) continue;
    if (!tri.double_sided && dot(d, front_normal(tri)) >= 0.0f) continue;  // seen from behind
    if (!best || t < best->t) best = RayHit{t, u, v, i};
  }
  return best;
}

// What the integrator computes when a BSDF-sampled ray hits an emitter:
// triangle_light_pdf at the full surface point of the hit.
float pdf_at_hit(const KernelData& kd, const std::vector<WorldTriangle>& tris, Vec3 o, Vec3 d) {
  const auto hit = intersect(tris, o, d);
  if (!hit) return 0.0f;
  const WorldTriangle& tri = tris[hit->triangle];
  const Hit h = {float(hit->t), float(hit->u), float(hit->v), tri.instance, tri.prim};
  return triangle_light_pdf(kd, h, make_surface_point(kd, h), d, float(hit->t), o, make_vec3(0.0f));
}

const Vec3 kReference = make_vec3(0.3f, -0.2f, -0.4f);
const Vec3 kReferenceNormal = normalize(make_vec3(0.2f, -0.1f, 1.0f));

TEST(KernelTriangleLight, SceneIsInFrontOfTheReferencePoint) {
  // Preconditions of the analytic references below.
  const TriangleLightScene s = make_triangle_light_scene(false);
  for (const WorldTriangle& t : s.triangles) {
    for (const Vec3& p : t.p) {
      EXPECT_LT(dot(p - kReference, front_normal(t)), 0.0f);
      EXPECT_GT(dot(p - kReference, kReferenceNormal), 0.0f);
    }
  }
}

TEST(KernelTriangleLight, ExpectedInversePdfIsSolidAngle) {
  // E[1 / pdf] over sample_light = sum_k P(k) int p_k / (P(k) p_k) = the
  // total solid angle of the emitters, for any correct solid-angle pdf.
  // E[L cos / pdf] is the irradiance, by Lambert's formula.
  for (bool double_sided : {false, true}) {
    const TriangleLightScene s = make_triangle_light_scene(double_sided);
    const KernelData kd = s.ks.view();
    double omega = 0.0, irradiance[3] = {0, 0, 0};
    for (const WorldTriangle& t : s.triangles) {
      omega += solid_angle(t, kReference);
      const double e = unit_irradiance(t, kReference, kReferenceNormal);
      for (int k = 0; k < 3; ++k)
        irradiance[k] += e * component(t.emission, k);
    }
    TestRng rng(400);
    MeanAccumulator inv_pdf, irr[3];
    int mismatched = 0;
    for (int i = 0; i < 200000; ++i) {
      LightSample ls;
      const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
      ASSERT_TRUE(sample_light(kd, kReference, make_vec3(0.0f), us, u1, u2, &ls));
      ASSERT_FALSE(ls.is_delta);
      ASSERT_FALSE(ls.at_infinity);
      ASSERT_NEAR(length(ls.wi), 1.0f, 1e-5f);
      ASSERT_NEAR(length(ls.point - kReference), ls.distance, 1e-5f * ls.distance);
      ASSERT_NEAR(dot(ls.point - kReference, ls.wi), ls.distance, 1e-5f * ls.distance);
      // The pdf the integrator will compute for the same direction when a
      // BSDF sample hits this light (MIS needs both to agree).
      const float pdf_hit = pdf_at_hit(kd, s.triangles, kReference, ls.wi);
      if (!(fabsf(pdf_hit - ls.pdf) <= 1e-3f * ls.pdf) && mismatched++ < 10) {
        ADD_FAILURE() << "sample_light pdf " << ls.pdf << " but triangle_light_pdf at the hit "
                      << pdf_hit;
      }
      inv_pdf.add(1.0 / ls.pdf);
      const double cos_ref = std::max(0.0f, dot(ls.wi, kReferenceNormal));
      for (int k = 0; k < 3; ++k)
        irr[k].add(component(ls.radiance, k) * cos_ref / ls.pdf);
    }
    EXPECT_EQ(mismatched, 0);
    EXPECT_NEAR(inv_pdf.mean(), omega, 5.0 * inv_pdf.std_error() + 1e-5 * omega)
        << "double_sided=" << double_sided;
    for (int k = 0; k < 3; ++k) {
      EXPECT_NEAR(irr[k].mean(), irradiance[k], 5.0 * irr[k].std_error() + 1e-5 * irradiance[k])
          << "channel " << k << " double_sided=" << double_sided;
    }
  }
}

TEST(KernelTriangleLight, AnalyticReferencesMatchBruteForce) {
  // The solid angle and irradiance formulas above, checked by cosine-
  // weighted ray casting: otherwise a wrong reference could hide a bug.
  const TriangleLightScene s = make_triangle_light_scene(false);
  const Frame frame = make_frame(kReferenceNormal);
  double expected = 0.0;
  for (const WorldTriangle& t : s.triangles)
    expected += unit_irradiance(t, kReference, kReferenceNormal);
  TestRng rng(410);
  MeanAccumulator estimate, omega;
  for (int i = 0; i < 400000; ++i) {
    const float d_u2 = rng.next(), d_u1 = rng.next();
    const Vec3 d = to_world(frame, sample_cosine_hemisphere(d_u1, d_u2));
    estimate.add(intersect(s.triangles, kReference, d) ? kPi : 0.0);
    const float u_u2 = rng.next(), u_u1 = rng.next();
    const Vec3 u = sample_uniform_sphere(u_u1, u_u2);
    omega.add(intersect(s.triangles, kReference, u) ? 4.0 * kPi : 0.0);
  }
  EXPECT_NEAR(estimate.mean(), expected, 5.0 * estimate.std_error());
  double total_omega = 0.0;
  for (const WorldTriangle& t : s.triangles)
    total_omega += solid_angle(t, kReference);
  EXPECT_NEAR(omega.mean(), total_omega, 5.0 * omega.std_error());
}

TEST(KernelTriangleLight, DirectionsFollowTheReportedPdf) {
  // Chi-square over where sampled directions hit the emitters: each triangle
  // is split into k^2 congruent sub-triangles (in barycentrics). A cell's
  // expected share is the integral over it of the solid-angle pdf the
  // integrator computes at a BSDF hit, with d(omega) = |cos_l| dA / d^2.
  // Cells inside one triangle avoid the slivers that triangle edges would
  // cut from (theta, phi) cells.
  constexpr int k = 8, kSamples = 200000;
  const TriangleLightScene s = make_triangle_light_scene(false);
  const KernelData kd = s.ks.view();
  const size_t per_triangle = size_t(k) * k * 2, n_cells = s.triangles.size() * per_triangle;
  const size_t missed = n_cells, failed = n_cells + 1;  // hit no emitter / sample_light false
  auto cell_of = [&](size_t tri, double u, double v) {
    const double x = u * k, y = v * k;
    const int i = std::min(int(x), k - 1), j = std::min(int(y), k - 1);
    return tri * per_triangle + size_t(i * k + j) * 2 + ((x - i) + (y - j) > 1.0 ? 1 : 0);
  };
  std::vector<double> observed(n_cells + 2, 0.0), expected(n_cells + 2, 0.0);
  TestRng rng(420);
  for (int n = 0; n < kSamples; ++n) {
    LightSample ls;
    const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
    if (!sample_light(kd, kReference, make_vec3(0.0f), us, u1, u2, &ls)) {
      observed[failed] += 1.0;
      continue;
    }
    const auto hit = intersect(s.triangles, kReference, ls.wi);
    observed[hit ? cell_of(hit->triangle, hit->u, hit->v) : missed] += 1.0;
  }
  double total = 0.0;
  for (size_t t = 0; t < s.triangles.size(); ++t) {
    const WorldTriangle& tri = s.triangles[t];
    const Vec3 e1 = tri.p[1] - tri.p[0], e2 = tri.p[2] - tri.p[0];
    const Vec3 n = front_normal(tri);
    const double area =
        0.5 * length(cross(e1, e2)) / (double(k) * k) / 64.0;  // of one integration piece
    // Midpoint rule on 64 congruent pieces of every sub-triangle: evaluate at
    // the centroids of an 8 x 8 barycentric grid of the whole triangle.
    constexpr int kFine = k * 8;
    for (int i = 0; i < kFine; ++i) {
      for (int j = 0; i + j < kFine; ++j) {
        for (int upper = 0; upper < (i + j < kFine - 1 ? 2 : 1); ++upper) {
          const double u = (i + (upper ? 2.0 : 1.0) / 3.0) / kFine,
                       v = (j + (upper ? 2.0 : 1.0) / 3.0) / kFine;
          const Vec3 x = tri.p[0] + e1 * float(u) + e2 * float(v);
          const Vec3 to = x - kReference;
          const float d2 = length_sq(to);
          const Vec3 wi = to * (1.0f / sqrtf(d2));
          const double p =
              double(pdf_at_hit(kd, s.triangles, kReference, wi)) * fabsf(dot(wi, n)) / d2 * area;
          expected[cell_of(t, u, v)] += p * kSamples;
          total += p;
        }
      }
    }
  }
  expected[failed] = std::max(0.0, 1.0 - total) * kSamples;
  const auto r = test_stats::chi_square_test(observed, expected);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
  EXPECT_NEAR(total, 1.0, 1e-3);
  EXPECT_EQ(observed[missed], 0.0) << "sampled directions that hit no emitter";
}

// The cached constants of an identity instance's lights give the same bits
// as make_light_point and triangle_light_pdf from the triangles (the same
// scene with the identity flag cleared), from points all around the lights.
TEST(KernelTriangleLight, CachedTriangleLightsSampleTheSameBits) {
  for (bool double_sided : {false, true}) {
    const TriangleLightScene s = make_triangle_light_scene(double_sided);
    KernelScene uncached = s.ks;
    uncached.instances[0].flags &= ~kInstanceIdentity;
    const KernelData kd = s.ks.view(), kd_uncached = uncached.view();
    TestRng rng(77);
    int compared = 0;
    for (int i = 0; i < 20000; ++i) {
      const float x = rng.next(), y = rng.next(), z = rng.next();
      const Vec3 ref = make_vec3(4.0f * x - 2.0f, 4.0f * y - 2.0f, 4.0f * z);
      const float us = rng.next(), u1 = rng.next(), u2 = rng.next();
      LightSample a{}, b{};
      const bool ok_a = sample_light(kd, ref, make_vec3(0.0f), us, u1, u2, &a);
      const bool ok_b = sample_light(kd_uncached, ref, make_vec3(0.0f), us, u1, u2, &b);
      ASSERT_EQ(ok_a, ok_b) << i;
      if (!ok_a) continue;
      ++compared;
      ASSERT_EQ(0, std::memcmp(&a.radiance, &b.radiance, sizeof(Vec3))) << i;
      ASSERT_EQ(0, std::memcmp(&a.wi, &b.wi, sizeof(Vec3))) << i;
      ASSERT_EQ(0, std::memcmp(&a.point, &b.point, sizeof(Vec3))) << i;
      ASSERT_EQ(0, std::memcmp(&a.distance, &b.distance, sizeof(float))) << i;
      ASSERT_EQ(0, std::memcmp(&a.pdf, &b.pdf, sizeof(float))) << i;
    }
    EXPECT_GT(compared, 5000);
  }
}

TEST(KernelTriangleLight, SingleSidedEmitterIsDarkFromBehind) {
  const Vec3 behind = make_vec3(0.1f, 0.1f, 4.0f);  // above the downward-facing emitters
  {
    const TriangleLightScene s = make_triangle_light_scene(false);
    const KernelData kd = s.ks.view();
    TestRng rng(430);
    for (int i = 0; i < 10000; ++i) {
      LightSample ls;
      const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
      ASSERT_FALSE(sample_light(kd, behind, make_vec3(0.0f), us, u1, u2, &ls));
    }
  }
  {
    // A double-sided emitter lights both sides with the same pdf rules.
    const TriangleLightScene s = make_triangle_light_scene(true);
    const KernelData kd = s.ks.view();
    TestRng rng(431);
    for (int i = 0; i < 10000; ++i) {
      LightSample ls;
      const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
      ASSERT_TRUE(sample_light(kd, behind, make_vec3(0.0f), us, u1, u2, &ls));
      ASSERT_NEAR(pdf_at_hit(kd, s.triangles, behind, ls.wi), ls.pdf, 1e-3f * ls.pdf);
    }
  }
}

TEST(KernelTriangleLight, EnvironmentAndTrianglesShareOneLightList) {
  // The environment light's pdf in a mixed list (selection pmf x env_pdf)
  // must be what environment_light_pdf reports for MIS.
  TriangleLightScene s = make_triangle_light_scene(false);
  const KernelScene env = make_environment_scene(1.3f);
  s.ks.env_texels = env.env_texels;
  s.ks.env_marginal_cdf = env.env_marginal_cdf;
  s.ks.env_conditional_cdf = env.env_conditional_cdf;
  s.ks.env_marginal_guide = env.env_marginal_guide;
  s.ks.env_conditional_guide = env.env_conditional_guide;
  s.ks.constants.environment = env.constants.environment;
  std::vector<double> power;
  for (const KLight& l : s.ks.lights)
    power.push_back(l.power);
  KLight env_light{};
  env_light.type = kLightEnvironment;
  s.ks.constants.environment_light_index = uint32_t(s.ks.lights.size());
  s.ks.lights.push_back(env_light);
  power.push_back(3.0);
  s.ks.light_alias = build_alias_table(power);
  double total = 0.0;
  for (double p : power)
    total += p;
  s.ks.constants.total_light_power = float(total);
  const KernelData kd = s.ks.view();
  TestRng rng(440);
  int env_count = 0;
  constexpr int kSamples = 100000;
  for (int i = 0; i < kSamples; ++i) {
    LightSample ls;
    const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
    if (!sample_light(kd, kReference, make_vec3(0.0f), us, u1, u2, &ls)) continue;
    if (ls.at_infinity) {
      ++env_count;
      ASSERT_NEAR(environment_light_pdf(kd, ls.wi), ls.pdf, 1e-3f * ls.pdf);
    } else {
      ASSERT_NEAR(pdf_at_hit(kd, s.triangles, kReference, ls.wi), ls.pdf, 1e-3f * ls.pdf);
    }
  }
  const double p_env = 3.0 / total;
  EXPECT_NEAR(env_count, p_env * kSamples, 5.0 * std::sqrt(kSamples * p_env * (1.0 - p_env)));
}

// ---------------------------------------------------------------------------
// Punctual lights.

KernelScene make_punctual_scene(const std::vector<KLight>& lights,
                                const std::vector<double>& weights) {
  KernelScene ks;
  ks.lights = lights;
  ks.light_alias = build_alias_table(weights);
  double total = 0.0;
  for (double w : weights)
    total += w;
  ks.constants.total_light_power = float(total);
  ks.constants.environment_light_index = kInvalidIndex;
  return ks;
}

KLight point_light(Vec3 position, Vec3 intensity) {
  KLight l{};
  l.type = kLightPoint;
  l.position = position;
  l.intensity = intensity;
  return l;
}

KLight spot_light(Vec3 position, Vec3 direction, float inner, float outer, Vec3 intensity) {
  KLight l = point_light(position, intensity);
  l.type = kLightSpot;
  l.direction = normalize(direction);
  l.cos_inner = cosf(inner);
  l.cos_outer = cosf(outer);
  return l;
}

TEST(KernelPunctualLight, PointLightFallsOffWithInverseSquare) {
  const Vec3 pos = make_vec3(1.0f, 2.0f, 3.0f), intensity = make_vec3(10.0f, 20.0f, 5.0f);
  const KernelScene ks = make_punctual_scene({point_light(pos, intensity)}, {1.0});
  const KernelData kd = ks.view();
  for (const Vec3 ref :
       {make_vec3(0.0f), make_vec3(1.0f, 2.0f, 0.5f), make_vec3(-3.0f, 5.0f, 3.0f)}) {
    LightSample ls;
    ASSERT_TRUE(sample_light(kd, ref, make_vec3(0.0f), 0.3f, 0.5f, 0.5f, &ls));
    const float d2 = length_sq(pos - ref);
    EXPECT_TRUE(ls.is_delta);
    EXPECT_FALSE(ls.at_infinity);
    EXPECT_FLOAT_EQ(ls.pdf, 1.0f);
    EXPECT_NEAR(ls.radiance.x, intensity.x / d2, 1e-5f * intensity.x / d2);
    EXPECT_NEAR(ls.radiance.y, intensity.y / d2, 1e-5f * intensity.y / d2);
    EXPECT_NEAR(ls.distance, sqrtf(d2), 1e-5f);
    const Vec3 wi = normalize(pos - ref);
    EXPECT_NEAR(dot(ls.wi, wi), 1.0f, 1e-6f);
    EXPECT_NEAR(length(ls.point - pos), 0.0f, 1e-6f);
  }
  LightSample ls;
  EXPECT_FALSE(sample_light(kd, pos, make_vec3(0.0f), 0.3f, 0.5f, 0.5f, &ls))
      << "shading point at the light";
}

// The integrator's smooth mirrors and glass sample only delta lights: an
// emissive triangle gives no sample there, a point light the same sample.
TEST(KernelLights, DeltaOnlySkipsAreaLightsAndKeepsPunctualOnes) {
  const TriangleLightScene s = make_triangle_light_scene(false);
  const KernelData area = s.ks.view();
  LightSample ls;
  ASSERT_TRUE(sample_light(area, kReference, make_vec3(0.0f), 0.3f, 0.4f, 0.5f, &ls));
  EXPECT_FALSE(sample_light(area, kReference, make_vec3(0.0f), 0.3f, 0.4f, 0.5f, &ls, true));

  const Vec3 pos = make_vec3(1.0f, 2.0f, 3.0f);
  const KernelScene ks = make_punctual_scene({point_light(pos, make_vec3(4.0f))}, {1.0});
  const KernelData punctual = ks.view();
  LightSample a, b;
  ASSERT_TRUE(sample_light(punctual, make_vec3(0.0f), make_vec3(0.0f), 0.3f, 0.5f, 0.5f, &a));
  ASSERT_TRUE(sample_light(punctual, make_vec3(0.0f), make_vec3(0.0f), 0.3f, 0.5f, 0.5f, &b, true));
  EXPECT_EQ(a.pdf, b.pdf);
  EXPECT_EQ(a.radiance.x, b.radiance.x);
  EXPECT_TRUE(b.is_delta);
}

TEST(KernelPunctualLight, SpotLightConeFalloff) {
  // Cone along -y from (0, 5, 0); inner 20 deg, outer 30 deg. glTF's smooth
  // falloff: t = (cos - cos_outer) / (cos_inner - cos_outer), intensity * t^2.
  const Vec3 pos = make_vec3(0.0f, 5.0f, 0.0f), intensity = make_vec3(100.0f);
  const float inner = 20.0f * kPi / 180.0f, outer = 30.0f * kPi / 180.0f;
  const KernelScene ks =
      make_punctual_scene({spot_light(pos, make_vec3(0, -1, 0), inner, outer, intensity)}, {1.0});
  const KernelData kd = ks.view();
  for (float deg : {0.0f, 10.0f, 19.0f, 21.0f, 25.0f, 29.0f, 31.0f, 60.0f, 120.0f}) {
    const float a = deg * kPi / 180.0f;
    const Vec3 ref = pos + make_vec3(sinf(a), -cosf(a), 0.0f) * 4.0f;  // 4 units from the light
    LightSample ls;
    const bool ok = sample_light(kd, ref, make_vec3(0.0f), 0.5f, 0.5f, 0.5f, &ls);
    if (deg > 30.0f) {
      EXPECT_FALSE(ok) << deg << " deg is outside the cone";
      continue;
    }
    ASSERT_TRUE(ok) << deg;
    EXPECT_TRUE(ls.is_delta);
    float falloff = 1.0f;
    if (deg > 20.0f) {
      const float t = (cosf(a) - cosf(outer)) / (cosf(inner) - cosf(outer));
      falloff = t * t;
    }
    EXPECT_NEAR(ls.radiance.x, 100.0f * falloff / 16.0f, 1e-3f * (100.0f / 16.0f)) << deg << " deg";
    EXPECT_NEAR(dot(ls.wi, normalize(pos - ref)), 1.0f, 1e-6f);
  }
}

TEST(KernelPunctualLight, DirectionalLight) {
  KLight l{};
  l.type = kLightDirectional;
  l.direction = normalize(make_vec3(1.0f, -2.0f, 0.5f));
  l.intensity = make_vec3(3.0f, 2.0f, 1.0f);
  const KernelScene ks = make_punctual_scene({l}, {1.0});
  const KernelData kd = ks.view();
  for (const Vec3 ref : {make_vec3(0.0f), make_vec3(100.0f, -50.0f, 3.0f)}) {
    LightSample ls;
    ASSERT_TRUE(sample_light(kd, ref, make_vec3(0.0f), 0.9f, 0.1f, 0.2f, &ls));
    EXPECT_TRUE(ls.is_delta);
    EXPECT_TRUE(ls.at_infinity);
    EXPECT_FLOAT_EQ(ls.pdf, 1.0f);
    EXPECT_NEAR(dot(ls.wi, -l.direction), 1.0f, 1e-6f);
    EXPECT_FLOAT_EQ(ls.radiance.x, 3.0f);  // no distance falloff
    EXPECT_FLOAT_EQ(ls.radiance.z, 1.0f);
  }
}

TEST(KernelPunctualLight, SelectionFollowsPowerAndReportsItsPmf) {
  const std::vector<double> weights = {1.0, 0.0, 2.5, 6.0};
  const KernelScene ks = make_punctual_scene({point_light(make_vec3(0, 3, 0), make_vec3(1.0f)),
                                              point_light(make_vec3(1, 3, 0), make_vec3(1.0f)),
                                              point_light(make_vec3(2, 3, 0), make_vec3(1.0f)),
                                              point_light(make_vec3(3, 3, 0), make_vec3(1.0f))},
                                             weights);
  const KernelData kd = ks.view();
  constexpr int kSamples = 100000;
  std::vector<double> observed(4, 0.0), expected(4, 0.0);
  for (int i = 0; i < 4; ++i)
    expected[size_t(i)] = weights[size_t(i)] / 9.5 * kSamples;
  TestRng rng(450);
  for (int i = 0; i < kSamples; ++i) {
    LightSample ls;
    const float u2 = rng.next(), u1 = rng.next(), us = rng.next();
    ASSERT_TRUE(sample_light(kd, make_vec3(0.0f), make_vec3(0.0f), us, u1, u2, &ls));
    const int index = int(std::lround(ls.point.x));
    ASSERT_NEAR(ls.pdf, weights[size_t(index)] / 9.5, 1e-6);
    observed[size_t(index)] += 1.0;
  }
  const auto r = test_stats::chi_square_test(observed, expected);
  EXPECT_TRUE(r.passed(kAlpha)) << r.summary();
  LightSample ls;
  EXPECT_FALSE(
      sample_light(KernelScene{}.view(), make_vec3(0.0f), make_vec3(0.0f), 0.5f, 0.5f, 0.5f, &ls))
      << "no lights";
}

}  // namespace
}  // namespace tandem
