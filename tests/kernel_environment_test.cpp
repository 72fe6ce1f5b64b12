// Tests of the environment light (core/kernel/environment.h) on a small
// hand-built map: importance sampling against the map's pdf and integral,
// the rotation about +y, a constant colour, and the miss shading's one map
// lookup.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/kernel/integrator.h"
#include "core/kernel/lights.h"
#include "core/world/kernel_scene.h"
#include "core/world/light_tables.h"
#include "kernel_light_test_scenes.h"
#include "sync/scene_sync.h"
#include "test_stats.h"

namespace tandem {
namespace {

using light_test::kEnvHeight;
using light_test::kEnvWidth;
using light_test::make_environment_scene;
using test_stats::MeanAccumulator;
using test_stats::sidak_alpha;
using test_stats::TestRng;

// The chi-square tests of the lights' family: two here (environment
// directions at two rotations), two in kernel_lights_test.cpp (triangle
// directions, light selection), each at the family's Sidak level.
const double kAlpha = sidak_alpha(test_stats::kFamilySignificance, 4);

// ---------------------------------------------------------------------------
// Environment map.

// Histogram frame whose pole is the map's pole (+y), so rows of the map are
// bands of the histogram. (A cyclic permutation: no mirroring.)
Vec3 world_to_grid(Vec3 d) {
  return make_vec3(d.z, d.x, d.y);
}
Vec3 grid_to_world(Vec3 g) {
  return make_vec3(g.y, g.z, g.x);
}

// Integral of env_radiance over the sphere by fine midpoint quadrature in
// (theta, phi) about +y; the map is bilinear, so 1024x2048 points are exact
// to far below the Monte Carlo noise we compare with.
Vec3 environment_integral(const KernelData& kd) {
  constexpr int kTheta = 1024, kPhi = 2048;
  double sum[3] = {0, 0, 0};
  for (int i = 0; i < kTheta; ++i) {
    const double theta = (i + 0.5) * double(kPi) / kTheta;
    double row[3] = {0, 0, 0};
    for (int j = 0; j < kPhi; ++j) {
      const double phi = (j + 0.5) * 2.0 * double(kPi) / kPhi;
      const Vec3 l = env_radiance(kd, grid_to_world(test_stats::spherical_direction(theta, phi)));
      row[0] += l.x;
      row[1] += l.y;
      row[2] += l.z;
    }
    const double w = std::sin(theta) * (double(kPi) / kTheta) * (2.0 * double(kPi) / kPhi);
    for (int k = 0; k < 3; ++k)
      sum[k] += row[k] * w;
  }
  return make_vec3(float(sum[0]), float(sum[1]), float(sum[2]));
}

class EnvironmentSampling : public ::testing::TestWithParam<float> {};

TEST_P(EnvironmentSampling, DirectionsFollowEnvPdf) {
  const KernelScene ks = make_environment_scene(GetParam());
  const KernelData kd = ks.view();
  TestRng rng(200 + uint32_t(GetParam() * 10.0f));
  const auto r = test_stats::sphere_chi_square(
      [&](Vec3* g) {
        const float u2 = rng.next(), u1 = rng.next();
        const EnvSample s = env_sample(kd, u1, u2);
        if (!(s.pdf > 0.0f)) return false;
        *g = world_to_grid(s.dir);
        return true;
      },
      [&](Vec3 g) { return env_pdf(kd, grid_to_world(g)); }, 200000, 64, 64);
  EXPECT_TRUE(r.passed(kAlpha)) << "rotation " << GetParam() << "\n" << r.summary();
  EXPECT_NEAR(r.pdf_integral, 1.0, 1e-3);
}

TEST_P(EnvironmentSampling, SampleReportsEnvPdfAndRadiance) {
  const KernelScene ks = make_environment_scene(GetParam());
  const KernelData kd = ks.view();
  TestRng rng(210);
  int mismatched = 0;
  for (int s = 0; s < 100000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const EnvSample es = env_sample(kd, u1, u2);
    ASSERT_NEAR(length(es.dir), 1.0f, 1e-5f);
    ASSERT_TRUE(es.pdf > 0.0f && std::isfinite(es.pdf));
    const float pdf = env_pdf(kd, es.dir);
    if (!(fabsf(pdf - es.pdf) <= 1e-3f * es.pdf) && mismatched++ < 10) {
      ADD_FAILURE() << "env_sample pdf " << es.pdf << " but env_pdf " << pdf << " at dir ("
                    << es.dir.x << "," << es.dir.y << "," << es.dir.z << ")";
    }
    // The sample's radiance is read at its map coordinates; the direction
    // turned back lands within a few 1e-7 of them, which the bilinear
    // filter turns into up to ~1.1e-4 relative on the steep edges of this
    // map's sun (where the sampler goes: env_texel_weight).
    const Vec3 l = env_radiance(kd, es.dir);
    ASSERT_NEAR(es.radiance.x, l.x, 3e-4f * l.x);
    ASSERT_NEAR(es.radiance.y, l.y, 3e-4f * l.y);
    ASSERT_NEAR(es.radiance.z, l.z, 3e-4f * l.z);
  }
  EXPECT_EQ(mismatched, 0);
}

TEST_P(EnvironmentSampling, EstimatorMatchesIntegralOfRadiance) {
  const KernelScene ks = make_environment_scene(GetParam());
  const KernelData kd = ks.view();
  const Vec3 reference = environment_integral(kd);
  TestRng rng(220);
  MeanAccumulator importance[3], uniform[3];
  for (int s = 0; s < 200000; ++s) {
    const float es_u2 = rng.next(), es_u1 = rng.next();
    const EnvSample es = env_sample(kd, es_u1, es_u2);
    const float d_u2 = rng.next(), d_u1 = rng.next();
    const Vec3 d = sample_uniform_sphere(d_u1, d_u2);
    const Vec3 lu = env_radiance(kd, d) * (4.0f * kPi);
    for (int k = 0; k < 3; ++k) {
      importance[k].add(es.pdf > 0.0f ? double(component(es.radiance, k)) / es.pdf : 0.0);
      uniform[k].add(component(lu, k));
    }
  }
  for (int k = 0; k < 3; ++k) {
    const double ref = component(reference, k);
    EXPECT_NEAR(importance[k].mean(), ref, 5.0 * importance[k].std_error() + 1e-4 * ref)
        << "channel " << k;
    // The same reference by plain uniform sampling: guards the quadrature.
    EXPECT_NEAR(uniform[k].mean(), ref, 5.0 * uniform[k].std_error() + 1e-4 * ref)
        << "channel " << k;
    // Importance sampling must actually help on a map with a sun.
    EXPECT_LT(importance[k].std_error(), 0.5 * uniform[k].std_error()) << "channel " << k;
  }
}

INSTANTIATE_TEST_SUITE_P(Rotations, EnvironmentSampling, ::testing::Values(0.0f, 1.3f));

// A 256x128 sky of radiance 0.5 with a sun at (100, 40): 3x3 texels, or a
// Gaussian of 6 texels' deviation with the same power (the sum of radiance
// times sin(theta) over its texels: the solid angle a texel covers).
KernelScene make_sun_scene(bool sharp) {
  constexpr uint32_t w = 256, h = 128, sx = 100, sy = 40;
  auto sin_row = [](uint32_t y) { return std::sin((double(y) + 0.5) * double(kPi) / h); };
  constexpr double kSharp = 2000.0;
  double sharp_power = 0.0, soft_power = 0.0;
  for (uint32_t y = sy - 1; y <= sy + 1; ++y)
    sharp_power += 3.0 * kSharp * sin_row(y);
  auto gauss = [&](uint32_t x, uint32_t y) {
    const double dx = double(x) - sx, dy = double(y) - sy;
    return std::exp(-(dx * dx + dy * dy) / (2.0 * 36.0));
  };
  for (uint32_t y = 0; y < h; ++y)
    for (uint32_t x = 0; x < w; ++x)
      soft_power += gauss(x, y) * sin_row(y);
  KernelScene ks;
  ks.env_texels.resize(size_t(w) * h);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      double sun = 0.0;
      if (sharp)
        sun = x + 1 >= sx && x <= sx + 1 && y + 1 >= sy && y <= sy + 1 ? kSharp : 0.0;
      else
        sun = gauss(x, y) * sharp_power / soft_power;
      ks.env_texels[size_t(y) * w + x] = make_vec4(make_vec3(float(0.5 + sun)), 0.0f);
    }
  }
  KEnvironment& env = ks.constants.environment;
  env.color = make_vec3(1.0f);
  env.has_map = 1;
  env.width = w;
  env.height = h;
  set_environment_rotation(env, 0.0f);
  build_environment_tables(ks);
  return ks;
}

// Relative variance of one light sample's estimate of the irradiance on a
// surface facing the sun's side of the sky (+y).
double irradiance_relative_variance(const KernelData& kd, uint32_t seed) {
  TestRng rng(seed);
  MeanAccumulator m;
  double sum_sq = 0.0;
  constexpr int kSamples = 400000;
  for (int s = 0; s < kSamples; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const EnvSample es = env_sample(kd, u1, u2);
    const double e =
        es.pdf > 0.0f ? double(luminance(es.radiance)) * std::max(0.0f, es.dir.y) / es.pdf : 0.0;
    m.add(e);
    sum_sq += e * e;
  }
  const double mean = m.mean();
  return (sum_sq / kSamples - mean * mean) / (mean * mean);
}

// The sampler follows what the lookup returns (env_texel_weight picks the
// texel, the lookup the point inside it), so a sharp sun is as clean as a
// soft one of the same power: 0.36 against 0.41. Weighted by each texel's
// own value the bilinear halo around the sharp one made it 176 (426
// times); by the texel's mean of the lookup alone, under twice.
TEST(KernelEnvironment, ASharpSunIsAsCleanAsASoftOneOfTheSamePower) {
  const KernelScene sharp = make_sun_scene(true), soft = make_sun_scene(false);
  const double v_sharp = irradiance_relative_variance(sharp.view(), 230);
  const double v_soft = irradiance_relative_variance(soft.view(), 231);
  EXPECT_LT(v_sharp, 1.1 * v_soft) << "sharp " << v_sharp << ", soft " << v_soft;
}

TEST(KernelEnvironment, RotationTurnsTheMapAboutY) {
  const KernelScene ks0 = make_environment_scene(0.0f), ks1 = make_environment_scene(1.3f);
  const KernelData kd0 = ks0.view(), kd1 = ks1.view();
  TestRng rng(230);
  for (int s = 0; s < 1000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec3 d = sample_uniform_sphere(u1, u2);
    const Vec3 rotated = rotate_y(d, 1.3f);
    const Vec3 a = env_radiance(kd0, d), b = env_radiance(kd1, rotated);
    ASSERT_NEAR(a.x, b.x, 1e-3f * (1.0f + a.x));
    ASSERT_NEAR(env_pdf(kd0, d), env_pdf(kd1, rotated), 1e-3f * env_pdf(kd0, d));
  }
  // Rotation keeps +y fixed and is a proper rotation.
  const Vec3 y = rotate_y(make_vec3(0, 1, 0), 0.7f);
  EXPECT_NEAR(y.y, 1.0f, 1e-6f);
  const Vec3 x = rotate_y(make_vec3(1, 0, 0), 0.7f), z = rotate_y(make_vec3(0, 0, 1), 0.7f);
  EXPECT_NEAR(dot(cross(x, y), z), 1.0f, 1e-5f);
}

// The compiled environment carries the rotation's cosine and sine, which
// the kernels turn by instead of calling rotate_y: a scene compiled with a
// rotation must look its map up (and turn its samples) exactly as
// rotate_y(d, -angle) (and rotate_y(d, angle)) would, bit for bit.
TEST(KernelEnvironment, CompiledRotationTurnsLikeRotateYBitForBit) {
  for (const float angle : {0.0f, 0.7f, -2.1f, 3.5f, 1e-3f}) {
    Scene scene;
    Environment& e = scene.edit_environment();
    e.width = 8;
    e.height = 4;
    for (uint32_t i = 0; i < e.width * e.height; ++i)
      e.texels.push_back(glm::vec3(0.1f + 0.05f * float(i), 0.2f, 0.3f));
    e.rotation = angle;
    RenderSettings settings;
    settings.width = settings.height = 8;
    SceneSync sync(SceneSyncSettings::arrays_only());
    sync.update(scene, settings);
    const KernelData kd = sync.view();
    ASSERT_EQ(kd.constants.environment.has_map, 1u);
    EXPECT_EQ(kd.constants.environment.rotation, angle);
    TestRng rng(250);
    for (int s = 0; s < 1000; ++s) {
      const float u2 = rng.next(), u1 = rng.next();
      const Vec3 d = sample_uniform_sphere(u1, u2);
      const Vec2 got = env_map_uv(kd, d), want = direction_to_equirect(rotate_y(d, -angle));
      ASSERT_EQ(std::memcmp(&got, &want, sizeof got), 0) << angle << " sample " << s;
      const KEnvironment& k = kd.constants.environment;
      const Vec3 turned = rotate_y_cs(d, k.rotation_cos, k.rotation_sin), ref = rotate_y(d, angle);
      ASSERT_EQ(std::memcmp(&turned, &ref, sizeof turned), 0) << angle << " sample " << s;
    }
  }
}

TEST(KernelEnvironment, ConstantColorIsUniform) {
  KernelScene ks;
  ks.constants.environment.color = make_vec3(0.5f, 1.0f, 2.0f);
  const KernelData kd = ks.view();
  TestRng rng(240);
  for (int s = 0; s < 1000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const EnvSample es = env_sample(kd, u1, u2);
    ASSERT_FLOAT_EQ(es.pdf, kInv4Pi);
    ASSERT_FLOAT_EQ(env_pdf(kd, es.dir), kInv4Pi);
    ASSERT_FLOAT_EQ(es.radiance.z, 2.0f);
    ASSERT_FLOAT_EQ(env_radiance(kd, es.dir).y, 1.0f);
  }
}

TEST(KernelEnvironment, MissShadesWithOneMapLookupAndTheSameBits) {
  // path_shade_miss derives the map coordinates once for the radiance and
  // the MIS pdf; it must add exactly what env_radiance and
  // environment_light_pdf give for the direction (a rotated map, so that
  // the rotation is part of what is shared).
  KernelScene ks = make_environment_scene(1.3f);
  ks.light_alias.resize(1);
  ks.light_alias[0].pdf = 0.375f;
  ks.constants.environment_light_index = 0;
  const KernelData kd = ks.view();
  TestRng rng(240);
  for (int s = 0; s < 1000; ++s) {
    const float u2 = rng.next(), u1 = rng.next();
    const Vec3 d = sample_uniform_sphere(u1, u2);
    PathState p{};
    p.ray.dir = d;
    p.throughput = make_vec3(0.5f, 0.25f, 2.0f);
    p.bsdf_pdf = 0.1f + rng.next();
    p.flags = kPathAlive;
    path_shade_miss(kd, &p);
    const float pdf = environment_light_pdf(kd, d);
    ASSERT_GT(pdf, 0.0f);
    const Vec3 want = p.throughput * env_radiance(kd, d) * mis_power_heuristic(p.bsdf_pdf, pdf);
    ASSERT_EQ(p.radiance.x, want.x);
    ASSERT_EQ(p.radiance.y, want.y);
    ASSERT_EQ(p.radiance.z, want.z);
    ASSERT_FALSE(path_alive(p));
  }
}

// ---------------------------------------------------------------------------
// The sampling tables' shortcuts: each must give the bits of what it
// replaced.

// Searches `cdf` (n + 1 entries) with and without its guide table at random
// u, at every entry and one float either side of it, and at every bucket
// edge k / n and one float either side of that.
void expect_guided_search_agrees(const std::vector<float>& cdf, TestRng& rng) {
  const uint32_t n = uint32_t(cdf.size() - 1);
  std::vector<uint32_t> guide(n + 1);
  build_cdf_guide(cdf.data(), n, guide.data());
  std::vector<float> us;
  for (int i = 0; i < 20000; ++i)
    us.push_back(rng.next());
  const auto add_with_neighbours = [&](float u) {
    us.push_back(u);
    us.push_back(std::nextafter(u, 0.0f));
    us.push_back(std::nextafter(u, 1.0f));
  };
  for (float c : cdf)
    add_with_neighbours(c);
  for (uint32_t k = 0; k <= n; ++k)
    add_with_neighbours(float(k) / float(n));
  us.push_back(0.99999994f);
  us.push_back(std::nanf(""));
  for (float u : us) {
    ASSERT_EQ(find_interval_guided(cdf.data(), guide.data(), n, u), find_interval(cdf.data(), n, u))
        << "u = " << u;
  }
}

TEST(KernelEnvironment, GuidedSearchFindsTheIntervalOfTheFullSearch) {
  TestRng rng(77);
  const uint32_t n = 97;
  // Steps of very different widths and runs of equal entries
  // (zero-probability intervals).
  std::vector<float> steps = {0.0f};
  for (uint32_t i = 1; i < n; ++i) {
    const float r = rng.next();
    steps.push_back(steps.back() + (r < 0.2f ? 0.0f : (r < 0.9f ? 1e-3f * r : 0.2f * r)));
  }
  for (float& c : steps)
    c /= steps.back() + 0.01f;
  steps.push_back(1.0f);
  expect_guided_search_agrees(steps, rng);
  // Every third entry on a bucket edge k / 300, with the floats either side
  // of it before and after: there u * n rounds up to k from below k / n
  // (seven of these edges), which the bracket's check must catch.
  const uint32_t m = 300;
  std::vector<float> edges = {0.0f};
  for (uint32_t k = 1; k < m / 3; ++k) {
    const float edge = float(k) / float(m);
    edges.insert(edges.end(), {std::nextafter(edge, 0.0f), edge, std::nextafter(edge, 1.0f)});
  }
  edges.insert(edges.end(), {0.6f, 0.8f, 1.0f});
  ASSERT_EQ(edges.size(), m + 1);
  expect_guided_search_agrees(edges, rng);
}

TEST(KernelEnvironment, TablesGiveThePdfAndRadianceOfTheDirectFormulas) {
  // env_sample reads the guide tables and env_radiance_at wraps columns
  // without a division: both must give the bits of the formulas they
  // replaced (written out here); env_pdf is the lookup's luminance (plus
  // the floor) times the texel's sin(theta), normalised.
  const KernelScene ks = make_environment_scene(0.7f);
  const KernelData kd = ks.view();
  const KEnvironment& env = kd.constants.environment;
  const auto direct_radiance = [&](Vec2 uv) {
    const float x = uv.x * float(env.width) - 0.5f, y = uv.y * float(env.height) - 0.5f;
    const float x0f = floorf(x), y0f = floorf(y);
    const float tx = x - x0f, ty = y - y0f;
    const int w = int(env.width), h = int(env.height);
    int x0 = int(x0f) % w;
    if (x0 < 0) x0 += w;
    const int x1 = (x0 + 1) % w;
    const int y0 = int(clamp_f(y0f, 0.0f, float(h - 1))),
              y1 = int(clamp_f(y0f + 1.0f, 0.0f, float(h - 1)));
    return (env_texel(kd, uint32_t(x0), uint32_t(y0)) * ((1 - tx) * (1 - ty)) +
            env_texel(kd, uint32_t(x1), uint32_t(y0)) * (tx * (1 - ty)) +
            env_texel(kd, uint32_t(x0), uint32_t(y1)) * ((1 - tx) * ty) +
            env_texel(kd, uint32_t(x1), uint32_t(y1)) * (tx * ty)) *
           env.color;
  };
  ASSERT_EQ(env.color.x, 1.0f);  // direct_radiance's luminance is then the map's
  const auto direct_pdf_uv = [&](Vec2 uv, uint32_t y) {
    return (luminance(direct_radiance(uv)) + 1e-4f) *
           std::sin((float(y) + 0.5f) * kPi / float(env.height)) * float(env.width) *
           float(env.height) / env.map_integral;
  };
  // Guide tables whose every entry is n - 1 bracket [n - 1, n], which
  // holds the answer or fails its check and widens to [0, n]: the plain
  // binary search.
  const std::vector<uint32_t> last_row(ks.env_marginal_guide.size(), env.height - 1);
  const std::vector<uint32_t> last_column(ks.env_conditional_guide.size(), env.width - 1);
  KernelData unguided = kd;
  unguided.env_marginal_guide = last_row.data();
  unguided.env_conditional_guide = last_column.data();
  TestRng rng(41);
  for (int i = 0; i < 5000; ++i) {
    const float u1 = rng.next(), u2 = rng.next();
    const EnvSample got = env_sample(kd, u1, u2), want = env_sample(unguided, u1, u2);
    ASSERT_EQ(std::memcmp(&got, &want, sizeof(EnvSample)), 0) << u1 << ", " << u2;
    const Vec3 d = sample_uniform_sphere(u1, u2);
    const Vec2 uv = env_map_uv(kd, d);
    const uint32_t py = min_u(uint32_t(uv.y * float(env.height)), env.height - 1);
    const float sin_theta = sqrtf((d.x * d.x + d.z * d.z) / (d.x * d.x + d.y * d.y + d.z * d.z));
    const float want_pdf = direct_pdf_uv(uv, py) / (2.0f * kPi * kPi * sin_theta);
    ASSERT_NEAR(env_pdf(kd, d), want_pdf, 1e-5f * want_pdf);
    // Coordinates in and around [0, 1]: the wrap's compare path and its
    // division fallback.
    const Vec2 wide = make_vec2(3.0f * rng.next() - 1.0f, rng.next());
    for (const Vec2 q : {uv, wide, make_vec2(0.0f, uv.y), make_vec2(1.0f, uv.y)}) {
      const Vec3 got_le = env_radiance_at(kd, q), want_le = direct_radiance(q);
      ASSERT_EQ(got_le.x, want_le.x);
      ASSERT_EQ(got_le.y, want_le.y);
      ASSERT_EQ(got_le.z, want_le.z);
    }
  }
}

}  // namespace
}  // namespace tandem
