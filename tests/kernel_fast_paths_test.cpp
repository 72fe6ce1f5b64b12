// The integrator's shortcuts must give what the general code gives: the
// unpaired 1-D draw the same numbers as rng_1d, a single-lobe BSDF the same
// sample whatever the lobe number, and the Lambertian evaluation the
// Lambertian value and pdf; and an identity instance's shading point the
// transformed one.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>

#include "core/kernel/bsdf.h"
#include "core/kernel/lights.h"
#include "core/kernel/rng.h"
#include "core/kernel/texture.h"
#include "core/world/kernel_scene.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

bool same_bits(float a, float b) {
  return std::memcmp(&a, &b, sizeof a) == 0;
}

TEST(KernelFastPaths, UnpairedDrawIsRng1d) {
  for (uint32_t pixel : {0u, 7u, 123456u}) {
    for (uint32_t sample = 0; sample < 64; ++sample) {
      const PathRng r = make_path_rng(pixel, sample, 3);
      for (uint32_t bounce = 0; bounce < 20; ++bounce) {
        for (uint32_t which : {kBounceLightSelect, kBounceLobe, kBounceRoulette}) {
          const uint32_t dim = bounce_dimension(bounce, which);
          ASSERT_TRUE(same_bits(rng_1d_unpaired(r, dim), rng_1d(r, dim)))
              << "pixel " << pixel << " sample " << sample << " dimension " << dim;
        }
      }
    }
  }
}

BsdfParams lambertian() {
  BsdfParams p{};
  p.base_color = {0.7f, 0.5f, 0.3f};
  p.metallic = 0.0f;
  p.specular_color = {1.0f, 1.0f, 1.0f};
  p.alpha = 0.25f;
  p.transmission = 0.0f;
  p.eta = 1.5f;
  p.specular = 0.0f;
  return p;
}

TEST(KernelFastPaths, SingleLobeBsdfsAreRecognised) {
  const Vec3 wo = normalize(make_vec3(0.3f, -0.2f, 0.9f));
  BsdfParams p = lambertian();
  EXPECT_TRUE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p.metallic = 1.0f;  // a conductor: reflection only
  EXPECT_TRUE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p = lambertian();
  p.specular = 0.5f;  // plastic: diffuse and reflection
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p.transmission = 1.0f;  // glass: reflection and transmission
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
  p = lambertian();
  p.clearcoat = 0.5f;  // a coat over diffuse
  EXPECT_FALSE(bsdf_single_lobe(bsdf_lobe_probabilities(p, wo)));
}

// For a single-lobe BSDF, u_lobe = 0 (what the integrator passes) samples
// exactly what any other u_lobe samples.
TEST(KernelFastPaths, SingleLobeSampleDoesNotDependOnTheLobeNumber) {
  BsdfParams mirror = lambertian();
  mirror.metallic = 1.0f;
  mirror.alpha = 0.05f;
  for (const BsdfParams& p : {lambertian(), mirror}) {
    for (uint32_t i = 0; i < 256; ++i) {
      const PathRng r = make_path_rng(i, i, 11);
      const Vec2 d = rng_2d(r, 4);
      const Vec3 wo = sample_cosine_hemisphere(d.x, d.y);
      if (wo.z <= 1e-3f) continue;
      const BsdfLobeProbabilities prob = bsdf_lobe_probabilities(p, wo);
      ASSERT_TRUE(bsdf_single_lobe(prob));
      const Vec2 u = rng_2d(r, 6);
      const float u_lobe = rng_1d(r, 8) * 0.999f;
      BsdfSample a, b;
      const bool ok_a = bsdf_sample_lobes(p, prob, wo, 0.0f, u.x, u.y, &a);
      const bool ok_b = bsdf_sample_lobes(p, prob, wo, u_lobe, u.x, u.y, &b);
      ASSERT_EQ(ok_a, ok_b) << "sample " << i;
      if (!ok_a) continue;
      EXPECT_TRUE(same_bits(a.wi.x, b.wi.x) && same_bits(a.wi.y, b.wi.y) &&
                  same_bits(a.wi.z, b.wi.z) && same_bits(a.pdf, b.pdf) &&
                  same_bits(a.weight.x, b.weight.x))
          << "sample " << i;
    }
  }
}

TEST(KernelFastPaths, LambertianEvalIsBaseColourOverPi) {
  BsdfParams p = lambertian();
  p.transmission = 0.25f;  // still no specular layer: the diffuse share shrinks
  const Vec3 wo = normalize(make_vec3(0.3f, -0.2f, 0.9f));
  const Vec3 wi = normalize(make_vec3(-0.6f, 0.1f, 0.4f));
  const BsdfLobeProbabilities prob = bsdf_lobe_probabilities(p, wo);
  const BsdfEval e = bsdf_eval_lobes(p, prob, wo, wi);
  const float w = 0.75f * kInvPi;
  EXPECT_FLOAT_EQ(e.f.x, 0.7f * w);
  EXPECT_FLOAT_EQ(e.f.y, 0.5f * w);
  EXPECT_FLOAT_EQ(e.f.z, 0.3f * w);
  EXPECT_FLOAT_EQ(e.pdf, prob.diffuse * wi.z * kInvPi);
  EXPECT_GT(prob.transmit, 0.0f);
}

// The same bits, a zero of either sign counting as equal (the only
// difference the skipped identity products can make; adding +0 turns -0
// into +0 and leaves everything else as it is).
bool same_value(Vec3 a, Vec3 b) {
  return same_bits(a.x + 0.0f, b.x + 0.0f) && same_bits(a.y + 0.0f, b.y + 0.0f) &&
         same_bits(a.z + 0.0f, b.z + 0.0f);
}

// A mesh with every attribute the shading point reads (normals, tangents,
// UVs), placed once by the identity and once by a translation.
Scene attribute_scene() {
  Scene scene;
  Material m;
  m.name = "emissive";
  m.emissive = glm::vec3(1.0f);
  const uint32_t mat = scene.add_material(m);
  Mesh mesh;
  mesh.name = "sheet";
  for (int i = 0; i < 9; ++i) {
    const float x = float(i % 3) * 0.5f - 0.5f, y = float(i / 3) * 0.4f - 0.4f;
    mesh.positions.push_back({x, y, 0.1f * x * y - 0.25f});
    mesh.normals.push_back(glm::normalize(glm::vec3(0.2f * x, -0.1f * y, 1.0f)));
    mesh.tangents.push_back({1.0f, 0.0f, -0.2f * x, i % 2 ? 1.0f : -1.0f});
    mesh.uv0.push_back({x + 0.5f, 0.5f - y});
  }
  for (uint32_t r = 0; r < 2; ++r) {
    for (uint32_t c = 0; c < 2; ++c) {
      const uint32_t a = r * 3 + c;
      mesh.triangles.push_back({a, a + 1, a + 4});
      mesh.triangles.push_back({a, a + 4, a + 3});
    }
  }
  mesh.triangle_materials.assign(mesh.triangles.size(), mat);
  const uint32_t id = scene.add_mesh(mesh);
  scene.add_instance({"identity", id, glm::mat4(1.0f)});
  scene.add_instance({"moved", id, glm::translate(glm::mat4(1.0f), glm::vec3(0.0f, 1.0f, 0.0f))});
  return scene;
}

TEST(KernelFastPaths, IdentityInstancesShadeAsTransformedOnes) {
  Scene scene = attribute_scene();
  SceneSync sync(SceneSyncSettings::arrays_only());
  RenderSettings settings;
  settings.width = settings.height = 8;
  sync.update(scene, settings);
  const KernelScene& ks = sync.kernel_scene();
  ASSERT_EQ(ks.instances.size(), 2u);
  EXPECT_NE(ks.instances[0].flags & kInstanceIdentity, 0u);
  EXPECT_EQ(ks.instances[1].flags & kInstanceIdentity, 0u);
  // The same scene with the shortcut switched off.
  KernelScene general = ks;
  general.instances[0].flags &= ~kInstanceIdentity;
  const KernelData fast_kd = ks.view(), general_kd = general.view();
  for (uint32_t prim = 0; prim < 8; ++prim) {
    for (const Vec2 b : {Vec2{0.2f, 0.3f}, Vec2{0.0f, 0.0f}, Vec2{0.6f, 0.1f}}) {
      SCOPED_TRACE(prim);
      const Hit hit{1.0f, b.x, b.y, 0, prim};
      const SurfacePoint f = make_surface_point(fast_kd, hit);
      const SurfacePoint g = make_surface_point(general_kd, hit);
      EXPECT_TRUE(same_value(f.position, g.position));
      EXPECT_TRUE(same_value(f.geometric_normal, g.geometric_normal));
      EXPECT_TRUE(same_value(f.shading_normal, g.shading_normal));
      EXPECT_TRUE(same_value(f.tangent, g.tangent));
      EXPECT_TRUE(same_value(f.bitangent, g.bitangent));
      EXPECT_TRUE(same_bits(f.area_world, g.area_world));
      const SurfacePoint fl = make_light_point(fast_kd, 0, prim, b.x, b.y);
      const SurfacePoint gl = make_light_point(general_kd, 0, prim, b.x, b.y);
      EXPECT_TRUE(same_value(fl.position, gl.position));
      EXPECT_TRUE(same_value(fl.geometric_normal, gl.geometric_normal));
      EXPECT_TRUE(same_bits(fl.area_world, gl.area_world));
      // The moved copy is one unit up: the shortcut is not taken there.
      const SurfacePoint moved = make_surface_point(fast_kd, {1.0f, b.x, b.y, 1, prim});
      EXPECT_NEAR(moved.position.y, f.position.y + 1.0f, 1e-6f);
    }
  }
}

// wrap_coord as it was, with an integer division for every index.
int wrap_coord_by_division(int i, int n, uint32_t mode) {
  if (mode == kWrapClamp) return i < 0 ? 0 : (i >= n ? n - 1 : i);
  if (mode == kWrapMirror) {
    const int period = 2 * n;
    int m = i % period;
    if (m < 0) m += period;
    return m < n ? m : period - 1 - m;
  }
  int m = i % n;
  return m < 0 ? m + n : m;
}

TEST(KernelFastPaths, TexelWrapWithoutDivisionIsTheRemainder) {
  for (uint32_t mode : {kWrapRepeat, kWrapClamp, kWrapMirror}) {
    for (int n = 1; n <= 37; ++n) {
      // The lookups' range [-1, 2n] and well beyond it on both sides.
      for (int i = -5 * n - 3; i <= 5 * n + 3; ++i) {
        ASSERT_EQ(wrap_coord(i, n, mode), wrap_coord_by_division(i, n, mode))
            << "i " << i << " n " << n << " mode " << mode;
      }
    }
  }
}

}  // namespace
}  // namespace tandem
