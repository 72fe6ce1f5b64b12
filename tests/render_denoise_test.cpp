// The denoiser's parts: the feature pass (motion vectors against
// independent camera math), temporal reprojection (rejection where a moving
// object uncovers the background, no ghost trail) and the a-trous filter
// (identity on a constant image, no blur across depth or normal edges), and
// the whole pipeline on a rendered scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <glm/gtc/matrix_transform.hpp>
#include <random>
#include <string>

#include "accstruc/accel_structure.h"
#include "backends/cpu/cpu_backend.h"
#include "backends/cpu_loops/cpu_features.h"
#include "core/render/offline_render.h"
#include "core/render/temporal_denoiser.h"
#include "core/world/motion_history.h"
#include "scenes/builtin_scenes.h"
#include "sync/scene_sync.h"

namespace tandem {
namespace {

constexpr uint32_t kW = 48, kH = 32;

PixelFeatures plane_pixel(uint32_t instance, float depth, Vec3 normal, Vec3 albedo) {
  PixelFeatures f{};
  f.albedo = albedo;
  f.depth = depth;
  f.prev_depth = depth;
  f.normal = normal;
  f.instance = instance;
  f.prim = 0;
  f.material = 0;
  return f;
}

// A pixel whose primary ray left the scene: no instance, primitive or
// material, white albedo (what the feature pass writes for the sky).
PixelFeatures sky_pixel() {
  PixelFeatures f = plane_pixel(kInvalidIndex, 0.0f, make_vec3(0.0f), make_vec3(1.0f));
  f.prim = f.material = kInvalidIndex;
  return f;
}

ImageRGB image_from(const std::vector<Vec3>& v, uint32_t w, uint32_t h) {
  ImageRGB img(w, h);
  for (size_t i = 0; i < v.size(); ++i) {
    img.rgb[3 * i] = v[i].x;
    img.rgb[3 * i + 1] = v[i].y;
    img.rgb[3 * i + 2] = v[i].z;
  }
  return img;
}

TEST(Denoise, ConstantImagePassesThroughUnchanged) {
  // Two surfaces and some sky; a constant radiance must come out exactly
  // (up to float rounding), on the first frame and with history.
  std::vector<PixelFeatures> features(kW * kH);
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      PixelFeatures& f = features[y * kW + x];
      if (y < 6) {
        f = sky_pixel();
      } else {
        f = x < kW / 2
                ? plane_pixel(0, 2.0f + 0.01f * float(y), make_vec3(0, 0, 1), make_vec3(0.5f))
                : plane_pixel(1, 5.0f, make_vec3(0.6f, 0, 0.8f), make_vec3(0.5f));
      }
    }
  }
  ImageRGB radiance(kW, kH);
  for (float& v : radiance.rgb)
    v = 0.37f;
  TemporalDenoiser denoiser;
  for (int frame = 0; frame < 3; ++frame) {
    const ImageRGB out = denoiser.process(features, radiance);
    for (size_t i = 0; i < out.rgb.size(); ++i)
      ASSERT_NEAR(out.rgb[i], 0.37f, 1e-5f) << "frame " << frame << " value " << i;
  }
}

// Left and right halves differ in depth (or normal) and in brightness; both
// are noisy. The filter must smooth each half but not mix them.
void check_no_blur_across_edge(bool depth_edge) {
  std::vector<PixelFeatures> features(kW * kH);
  std::vector<Vec3> radiance(kW * kH);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> noise(-0.5f, 0.5f);
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      const bool left = x < kW / 2;
      const float depth = depth_edge ? (left ? 2.0f : 6.0f) : 3.0f;
      const Vec3 n = depth_edge || left ? make_vec3(0, 0, 1) : make_vec3(0.8f, 0, 0.6f);
      features[y * kW + x] = plane_pixel(0, depth, n, make_vec3(1.0f));
      const float base = left ? 0.2f : 1.0f;
      radiance[y * kW + x] = make_vec3(base * (1.0f + noise(rng)));
    }
  }
  TemporalDenoiser denoiser;
  const ImageRGB out = denoiser.process(features, image_from(radiance, kW, kH));
  double in_var = 0.0, out_var = 0.0;
  for (uint32_t y = 2; y + 2 < kH; ++y) {
    // The columns at the edge keep their own side's level.
    EXPECT_NEAR(out.pixel(kW / 2 - 1, y)[0], 0.2f, 0.06f) << "row " << y;
    EXPECT_NEAR(out.pixel(kW / 2, y)[0], 1.0f, 0.3f) << "row " << y;
    for (uint32_t x = 2; x < kW / 2 - 2; ++x) {
      in_var += sqr(radiance[y * kW + x].x - 0.2f);
      out_var += sqr(out.pixel(x, y)[0] - 0.2f);
    }
  }
  // ... and the filter did filter: the noise inside a half went down.
  EXPECT_LT(out_var, 0.25 * in_var);
}

TEST(Denoise, NoBlurAcrossDepthEdge) {
  check_no_blur_across_edge(true);
}
TEST(Denoise, NoBlurAcrossNormalEdge) {
  check_no_blur_across_edge(false);
}

// A background plane (instance 0) and a square (instance 1) in front of it
// that moves `speed` pixels to the right per frame.
struct MovingSquare {
  uint32_t size = 10, speed = 3, y0 = 10;
  uint32_t x0(int frame) const { return 4 + uint32_t(frame) * speed; }
  bool inside(int frame, uint32_t x, uint32_t y) const {
    return x >= x0(frame) && x < x0(frame) + size && y >= y0 && y < y0 + size;
  }
  std::vector<PixelFeatures> features(int frame) const {
    std::vector<PixelFeatures> f(kW * kH);
    for (uint32_t y = 0; y < kH; ++y) {
      for (uint32_t x = 0; x < kW; ++x) {
        if (inside(frame, x, y)) {
          f[y * kW + x] = plane_pixel(1, 2.0f, make_vec3(0, 0, 1), make_vec3(0.8f));
          if (frame > 0) f[y * kW + x].motion = make_vec2(-float(speed), 0.0f);
        } else {
          f[y * kW + x] = plane_pixel(0, 10.0f, make_vec3(0, 0, 1), make_vec3(0.5f));
        }
      }
    }
    return f;
  }
  ImageRGB radiance(int frame) const {
    ImageRGB img(kW, kH);
    for (uint32_t y = 0; y < kH; ++y)
      for (uint32_t x = 0; x < kW; ++x)
        for (int c = 0; c < 3; ++c)
          img.pixel(x, y)[c] = inside(frame, x, y) ? 1.0f : 0.05f;
    return img;
  }
};

TEST(Denoise, HistoryRejectedWhereMovingObjectUncoversBackground) {
  const MovingSquare sq;
  TemporalDenoiser denoiser;
  denoiser.process(sq.features(0), sq.radiance(0));
  denoiser.process(sq.features(1), sq.radiance(1));
  const std::vector<Vec4>& m = denoiser.moments();
  int uncovered = 0;
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x < kW; ++x) {
      const float len = m[y * kW + x].z;
      if (sq.inside(0, x, y) && !sq.inside(1, x, y)) {
        EXPECT_EQ(len, 1.0f) << "uncovered background at " << x << "," << y << " kept history";
        ++uncovered;
      } else {
        // The square followed by its motion vector, the rest static.
        EXPECT_EQ(len, 2.0f) << "pixel " << x << "," << y << " lost its history";
      }
    }
  }
  EXPECT_EQ(uncovered, int(sq.size * sq.speed));
}

TEST(Denoise, HistoryRejectedAcrossAMaterialEdgeWithinOneInstance) {
  // A ceiling (material 0) with a light (material 1, albedo 0) in it, one
  // instance; the view pans 2.5 pixels per frame, so the bilinear taps of
  // the ceiling next to the light straddle the edge. They must not take the
  // light's history.
  const float shift = 2.5f;
  auto features = [&](int frame) {
    std::vector<PixelFeatures> f(kW * kH);
    for (uint32_t y = 0; y < kH; ++y) {
      for (uint32_t x = 0; x < kW; ++x) {
        const float wx = float(x) + 0.5f + float(frame) * shift;  // world column
        const bool light = wx >= 20.0f && wx < 30.0f && y >= 10 && y < 20;
        PixelFeatures& p = f[y * kW + x];
        p = plane_pixel(0, 3.0f, make_vec3(0, 0, 1), light ? make_vec3(0.0f) : make_vec3(0.7f));
        p.material = light ? 1u : 0u;
        if (frame > 0) p.motion = make_vec2(shift, 0.0f);
      }
    }
    return f;
  };
  auto radiance = [&](const std::vector<PixelFeatures>& f) {
    ImageRGB img(kW, kH);
    for (size_t i = 0; i < f.size(); ++i)
      for (int c = 0; c < 3; ++c)
        img.rgb[3 * i + size_t(c)] = f[i].material == 1 ? 50.0f : 0.35f;
    return img;
  };
  TemporalDenoiser denoiser;
  ImageRGB out;
  for (int frame = 0; frame < 3; ++frame) {
    const std::vector<PixelFeatures> f = features(frame);
    out = denoiser.process(f, radiance(f));
  }
  const std::vector<PixelFeatures> f = features(2);
  for (uint32_t y = 0; y < kH; ++y) {
    for (uint32_t x = 0; x + 3 < kW; ++x) {
      const size_t i = y * kW + x;
      if (f[i].material != 0) continue;
      EXPECT_NEAR(out.rgb[3 * i], 0.35f, 0.02f) << "ceiling pixel " << x << "," << y;
    }
  }
}

TEST(Denoise, NoGhostTrailBehindMovingObject) {
  const MovingSquare sq;
  TemporalDenoiser denoiser;
  ImageRGB out;
  const int frames = 8;
  for (int f = 0; f < frames; ++f)
    out = denoiser.process(sq.features(f), sq.radiance(f));
  // Exact radiance in: every pixel must come out at its own surface's
  // level. Count pixels off by more than 5%: the trail a ghost would leave.
  const ImageRGB truth = sq.radiance(frames - 1);
  int ghost = 0;
  for (size_t i = 0; i < out.rgb.size(); ++i)
    if (std::fabs(out.rgb[i] - truth.rgb[i]) > 0.05f * truth.rgb[i]) ++ghost;
  EXPECT_EQ(ghost, 0) << "pixels (channels) off by more than 5% behind the moving square";
}

// --- on a rendered scene ----------------------------------------------------

struct Compiled {
  SceneSync sync{SceneSyncSettings::arrays_only()};
  const KernelScene& ks = sync.kernel_scene();
  CpuBackend backend{CpuTraversal::kEmbree};
  void compile(Scene& scene, const RenderSettings& settings) {
    backend.sync(ks, sync.update(scene, settings).changes);
  }
};

// glm's own projection of world point p by `cam` to film pixels.
glm::vec2 glm_project(const Camera& cam, const glm::vec3& p, uint32_t w, uint32_t h) {
  const glm::mat4 view = glm::lookAt(cam.position, cam.position + cam.forward, cam.up);
  const glm::mat4 proj = glm::perspective(cam.yfov, float(w) / float(h), 0.1f, 100.0f);
  const glm::vec4 clip = proj * view * glm::vec4(p, 1.0f);
  const glm::vec2 ndc(clip.x / clip.w, clip.y / clip.w);
  return {(ndc.x + 1.0f) * 0.5f * float(w), (1.0f - ndc.y) * 0.5f * float(h)};
}
glm::vec3 glm_unproject(const Camera& cam, const glm::vec2& film, uint32_t w, uint32_t h) {
  const glm::mat4 view = glm::lookAt(cam.position, cam.position + cam.forward, cam.up);
  const glm::mat4 proj = glm::perspective(cam.yfov, float(w) / float(h), 0.1f, 100.0f);
  const glm::vec3 win(film.x, float(h) - film.y, 0.5f);
  return glm::unProject(win, view, proj, glm::vec4(0, 0, float(w), float(h)));
}

TEST(Denoise, MotionVectorsUnderCameraRotationMatchCameraMath) {
  Scene scene = make_cornell_box();
  RenderSettings settings;
  settings.width = 64;
  settings.height = 48;
  Compiled c;
  MotionHistory motion;
  std::vector<PixelFeatures> before(64 * 48), after(64 * 48);
  c.compile(scene, settings);
  ASSERT_TRUE(c.backend.render_features(motion.advance(c.ks.view()), before.data(), {}));
  const Camera a = scene.camera();
  // Yaw by 3 degrees and pitch by 1 about the camera's own position.
  Camera b = a;
  const glm::mat4 r =
      glm::rotate(glm::rotate(glm::mat4(1.0f), 0.052f, a.up), 0.017f, glm::cross(a.forward, a.up));
  b.forward = glm::normalize(glm::vec3(r * glm::vec4(a.forward, 0.0f)));
  b.up = glm::normalize(glm::vec3(r * glm::vec4(a.up, 0.0f)));
  scene.edit_camera() = b;
  c.compile(scene, settings);
  ASSERT_TRUE(c.backend.render_features(motion.advance(c.ks.view()), after.data(), {}));
  double worst = 0.0;
  int hits = 0, same_surface = 0;
  for (uint32_t y = 0; y < 48; ++y) {
    for (uint32_t x = 0; x < 64; ++x) {
      const PixelFeatures& f = after[y * 64 + x];
      const glm::vec2 centre(float(x) + 0.5f, float(y) + 0.5f);
      const glm::vec2 expected = glm_project(a, glm_unproject(b, centre, 64, 48), 64, 48);
      const glm::vec2 got = centre + glm::vec2(f.motion.x, f.motion.y);
      worst = std::max(worst, double(glm::length(got - expected)));
      if (!features_hit(f)) continue;
      ++hits;
      // Where it was, the previous frame saw the same surface at the same depth.
      const int px = int(std::floor(got.x)), py = int(std::floor(got.y));
      if (px < 0 || py < 0 || px >= 64 || py >= 48) continue;
      const PixelFeatures& g = before[size_t(py) * 64 + size_t(px)];
      if (g.instance == f.instance && std::fabs(g.depth - f.prev_depth) < 0.05f * f.prev_depth)
        ++same_surface;
    }
  }
  EXPECT_LT(worst, 2e-3) << "pixels from the motion vectors vs glm's projection";
  EXPECT_GT(hits, 64 * 48 / 2);
  EXPECT_GT(same_surface, hits * 9 / 10);
}

TEST(Denoise, FeaturesAreTheSameOnEveryCpuBackendAndStaticWithoutMotion) {
  Scene scene = make_cornell_spheres();
  RenderSettings settings;
  settings.width = 40;
  settings.height = 30;
  SceneSync sync;
  const SceneDelta delta = sync.update(scene, settings).changes;
  const KernelScene& ks = sync.kernel_scene();
  CpuBackend cpu{CpuTraversal::kEmbree};
  CpuBackend host{CpuTraversal::kTandemBvh};
  cpu.sync(ks, delta);
  host.sync(ks, delta);
  MotionHistory motion;
  const FeaturePass pass = motion.advance(ks.view());
  std::vector<PixelFeatures> f(40 * 30), g(40 * 30);
  ASSERT_TRUE(cpu.render_features(pass, f.data(), {}));
  ASSERT_TRUE(host.render_features(pass, g.data(), {}));
  int hits = 0, same = 0;
  for (size_t i = 0; i < f.size(); ++i) {
    const PixelFeatures& p = f[i];
    EXPECT_NEAR(p.motion.x, 0.0f, 1e-4f);
    EXPECT_NEAR(p.motion.y, 0.0f, 1e-4f);
    if (!features_hit(p)) continue;
    ++hits;
    EXPECT_GT(p.depth, 0.0f);
    EXPECT_NEAR(dot(p.normal, p.normal), 1.0f, 1e-3f);
    EXPECT_NEAR(p.prev_depth, p.depth, 1e-3f * p.depth);
    // Embree and Tandem's BVH find the same triangle (up to the odd ray
    // through a shared edge) and then run the same feature code.
    if (g[i].instance == p.instance && g[i].prim == p.prim) {
      ++same;
      EXPECT_NEAR(g[i].depth, p.depth, 1e-4f * p.depth);
      EXPECT_EQ(g[i].material, p.material);
      EXPECT_EQ(g[i].albedo.x, p.albedo.x);
    }
  }
  EXPECT_GT(hits, 600);
  EXPECT_GE(same, hits - 4);
}

double rel_mse(const ImageRGB& img, const ImageRGB& ref) {
  double sum = 0.0;
  for (size_t i = 0; i < img.rgb.size(); ++i)
    sum += sqr(img.rgb[i] - ref.rgb[i]) / (sqr(ref.rgb[i]) + 1e-2);
  return sum / double(img.rgb.size());
}

TEST(Denoise, AccumulatedAndFilteredOneSampleFramesBeatRawOneSample) {
  Scene scene = make_cornell_box();
  RenderSettings settings;
  settings.width = 64;
  settings.height = 64;
  settings.max_depth = 4;
  Compiled c;
  c.compile(scene, settings);
  OfflineRenderOptions ref_options;
  ref_options.spp = 128;
  const ImageRGB ref = render_offline(c.backend, 64, 64, ref_options).image;
  MotionHistory motion;
  TemporalDenoiser denoiser;
  std::vector<PixelFeatures> f(64 * 64);
  ImageRGB raw, denoised;
  for (uint32_t frame = 0; frame < 8; ++frame) {
    settings.seed = 1000 + frame;  // a new sample per frame
    c.compile(scene, settings);
    OfflineRenderOptions one;
    one.spp = 1;
    raw = render_offline(c.backend, 64, 64, one).image;
    ASSERT_TRUE(c.backend.render_features(motion.advance(c.ks.view()), f.data(), {}));
    denoised = denoiser.process(f, raw);
  }
  const double e_raw = rel_mse(raw, ref), e_den = rel_mse(denoised, ref);
  EXPECT_LT(e_den, 0.25 * e_raw) << "raw " << e_raw << " denoised " << e_den;
}

// Frame `frame` of a synthetic sequence for the filter-loop tests: sky at
// the top, a slanted plane of two materials with a checker albedo, and a
// square moving 5 pixels per frame across it (disocclusions: short-history
// runs next to long ones), with noisy radiance and 2% fireflies.
void make_square_frame(int frame, uint32_t w, uint32_t h, std::mt19937& rng,
                       std::vector<PixelFeatures>& f, std::vector<Vec3>& radiance) {
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  f.assign(size_t(w) * h, PixelFeatures{});
  radiance.assign(size_t(w) * h, Vec3{});
  const uint32_t sq_x = 20 + 5 * uint32_t(frame);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      PixelFeatures& p = f[y * w + x];
      if (y < 6) {
        p = sky_pixel();
      } else if (x >= sq_x && x < sq_x + 24 && y >= 20 && y < 44) {
        p = plane_pixel(1, 2.0f, normalize(make_vec3(0.1f, 0.0f, 1.0f)), make_vec3(0.8f));
        if (frame > 0) p.motion = make_vec2(-5.0f, 0.0f);
      } else {
        const float z = 6.0f + 0.02f * float(y);
        p = plane_pixel(0, z, normalize(make_vec3(0.0f, 0.3f, 1.0f)),
                        make_vec3(0.3f + 0.4f * float((x / 3 + y / 3) % 2), 0.5f, 0.4f));
        p.prev_depth = z;
        p.material = x < w / 3 ? 2u : 0u;
      }
      const float spike_u = u(rng), scale_u = u(rng);
      radiance[y * w + x] = p.albedo * (2.0f * scale_u) * (spike_u < 0.02f ? 20.0f : 1.0f);
    }
  }
}

// The buffers of one filter run over a sequence (double-buffered history).
struct FilterRun {
  std::vector<PixelFeatures> features[2];
  std::vector<Vec4> color[2], moments[2], a, b;
  std::vector<Vec3> output;
  std::vector<Vec2> slope;
  std::vector<SvgfGuide> guide;
  std::vector<uint32_t> material;
  explicit FilterRun(size_t n) : a(n), b(n), output(n), slope(n), guide(n), material(n) {
    for (int k = 0; k < 2; ++k) {
      features[k].assign(n, PixelFeatures{});
      color[k].assign(n, Vec4{});
      moments[k].assign(n, Vec4{});
    }
  }
  SvgfFrame frame(int cur, bool has_history, const std::vector<Vec3>& radiance) {
    const int prev = 1 - cur;
    return SvgfFrame{features[cur].data(),
                     radiance.data(),
                     has_history ? features[prev].data() : nullptr,
                     color[prev].data(),
                     moments[prev].data(),
                     color[cur].data(),
                     moments[cur].data(),
                     output.data(),
                     a.data(),
                     b.data(),
                     slope.data(),
                     guide.data(),
                     material.data()};
  }
};

// The device driver's sequence (backends/cuda/svgf_kernels.cu): each stage
// one pass of the per-pixel functions over the records, always checking
// bounds. The CPU driver's planes must give the same image.
void run_filter_on_records(const SvgfParams& p, const SvgfFrame& fr) {
  const SvgfTemporalBuffers tb{fr.features,     fr.radiance,  fr.prev_features, fr.prev_color,
                               fr.prev_moments, fr.scratch_a, fr.moments_out,   fr.depth_slope,
                               fr.guide,        fr.material};
  for (uint32_t y = 0; y < p.height; ++y)
    for (uint32_t x = 0; x < p.width; ++x)
      svgf_temporal_pixel(p, tb, x, y);
  const SvgfVarianceBuffers vb{fr.guide,     fr.material,    fr.depth_slope,
                               fr.scratch_a, fr.moments_out, fr.scratch_b};
  for (uint32_t y = 0; y < p.height; ++y)
    for (uint32_t x = 0; x < p.width; ++x)
      svgf_variance_pixel(p, vb, x, y);
  const Vec4* in = fr.scratch_b;
  for (uint32_t it = 0; it < p.iterations; ++it) {
    Vec4* out = it == 0 ? fr.history_color_out : (in == fr.scratch_a ? fr.scratch_b : fr.scratch_a);
    const SvgfAtrousBuffers ab{fr.guide, fr.material, fr.depth_slope, in};
    for (uint32_t y = 0; y < p.height; ++y)
      for (uint32_t x = 0; x < p.width; ++x)
        out[size_t(y) * p.width + x] = svgf_atrous_pixel<true>(p, ab, 1u << it, x, y);
    in = out;
  }
  for (size_t i = 0; i < size_t(p.width) * p.height; ++i)
    fr.output[i] = svgf_modulate_pixel(fr.features[i], in[i]);
}

// Largest and mean per-channel difference of `b` from the reference `a`
// over n pixels, relative to the reference pixel's L1 norm (plus 1e-3, so
// that black pixels compare absolutely).
struct RelativeDifference {
  double worst = 0.0, mean = 0.0;
};
template <class V>
RelativeDifference relative_difference(const std::vector<V>& a, const std::vector<V>& b) {
  RelativeDifference r;
  double sum = 0.0;
  for (size_t i = 0; i < a.size(); ++i) {
    const double scale = std::fabs(a[i].x) + std::fabs(a[i].y) + std::fabs(a[i].z) + 1e-3;
    for (float d : {a[i].x - b[i].x, a[i].y - b[i].y, a[i].z - b[i].z}) {
      const double rel = std::fabs(d) / scale;
      r.worst = std::max(r.worst, rel);
      sum += rel;
    }
  }
  r.mean = a.empty() ? 0.0 : sum / double(3 * a.size());
  return r;
}

// The CPU driver runs the spatial stages over structure-of-arrays planes
// (vectorised, unchecked interior loops); the device over the records. Both
// run the same per-pixel functions, so the images, the colour history and
// the history lengths must agree within float rounding, frame after frame
// (first frame: spatial variance everywhere; later: disocclusions).
TEST(Denoise, CpuPlanesGiveTheImageOfTheRecordsPath) {
  const uint32_t w = 96, h = 64;
  const size_t n = size_t(w) * h;
  for (uint32_t radius : {1u, 2u}) {
    SCOPED_TRACE("kernel radius " + std::to_string(radius));
    SvgfParams params = svgf_default_params(w, h);
    params.kernel_radius = radius;
    FilterRun planes(n), records(n);
    std::mt19937 rng(5);
    for (int frame = 0; frame < 5; ++frame) {
      SCOPED_TRACE("frame " + std::to_string(frame));
      const int cur = frame & 1;
      std::vector<PixelFeatures> f;
      std::vector<Vec3> radiance;
      make_square_frame(frame, w, h, rng, f, radiance);
      planes.features[cur] = f;
      records.features[cur] = f;
      svgf_run_cpu(params, planes.frame(cur, frame > 0, radiance), SvgfCpuIsa::kBaseline);
      run_filter_on_records(params, records.frame(cur, frame > 0, radiance));
      for (size_t i = 0; i < n; ++i)
        EXPECT_EQ(planes.moments[cur][i].z, records.moments[cur][i].z) << "pixel " << i;
      EXPECT_LT(relative_difference(records.output, planes.output).worst, 1e-4)
          << "largest relative difference of the image";
      EXPECT_LT(relative_difference(records.color[cur], planes.color[cur]).worst, 1e-4)
          << "largest relative difference of the colour history";
    }
  }
}

// A caller that keeps the CPU driver's compact guide from frame to frame
// (TemporalDenoiser) has the reprojection read it instead of last frame's
// feature records: the same values, so the same image, bit for bit, over a
// sequence (a guide from the wrong frame would reject or accept other taps).
TEST(Denoise, KeptCompactGuideGivesTheImageOfTheFeatureRecords) {
  const uint32_t w = 96, h = 64;
  const size_t n = size_t(w) * h;
  const SvgfParams params = svgf_default_params(w, h);
  FilterRun kept(n), records(n);
  SvgfCpuGuide guides[2];
  std::mt19937 rng(7);
  for (int frame = 0; frame < 5; ++frame) {
    SCOPED_TRACE("frame " + std::to_string(frame));
    const int cur = frame & 1;
    std::vector<PixelFeatures> f;
    std::vector<Vec3> radiance;
    make_square_frame(frame, w, h, rng, f, radiance);
    kept.features[cur] = f;
    records.features[cur] = f;
    SvgfFrame with_guide = kept.frame(cur, frame > 0, radiance);
    with_guide.guide_out = &guides[cur];
    if (frame > 0) with_guide.prev_guide = &guides[1 - cur];
    svgf_run_cpu(params, with_guide);
    svgf_run_cpu(params, records.frame(cur, frame > 0, radiance));
    for (size_t i = 0; i < n; ++i) {
      ASSERT_EQ(kept.moments[cur][i].z, records.moments[cur][i].z) << "pixel " << i;
      ASSERT_EQ(kept.output[i].x, records.output[i].x) << "pixel " << i;
      ASSERT_EQ(kept.output[i].y, records.output[i].y) << "pixel " << i;
      ASSERT_EQ(kept.output[i].z, records.output[i].z) << "pixel " << i;
    }
  }
}

// The CPU driver's planes are svgf_cpu_plane_stride apart: at least the
// pixel count, and one cache line further modulo 4 KiB each, so that a
// loop over a dozen planes at one index does not map them all to one L1
// set (at 640x360, 1280x720, 1920x1080 n floats are a multiple of 4 KiB).
TEST(Denoise, CpuPlanesStartOneCacheLineApartModulo4KiB) {
  for (size_t n : {size_t(1), size_t(96 * 64), size_t(640 * 360), size_t(1280 * 720),
                   size_t(1920 * 1080), size_t(1000003)}) {
    const size_t stride = svgf_cpu_plane_stride(n);
    EXPECT_GE(stride, n);
    EXPECT_LE(stride, n + 1024 + 16);
    EXPECT_EQ(stride * sizeof(float) % 4096, 64u) << n << " pixels";
  }
  SvgfCpuGuide guide;
  guide.resize(640 * 360);
  const auto offset = [](const void* p) { return reinterpret_cast<uintptr_t>(p) % 4096; };
  EXPECT_NE(offset(guide.normal_x()), offset(guide.normal_y()));
  EXPECT_NE(offset(guide.material()), offset(guide.instance()));
}

// The filter's row loops run as AVX2 + FMA clones where the CPU has them,
// and as the baseline x86-64 (SSE2) build elsewhere: the two must give the
// same image within float rounding, on a first frame (the spatial variance
// of every pixel) and on frames with reprojected history, with a moving
// square (disocclusions: short-history runs next to long ones), sky and
// noisy, textured radiance; at both kernel radii.
TEST(Denoise, Avx2AndBaselineLoopsGiveTheSameImage) {
  if (!svgf_cpu_avx2_supported()) GTEST_SKIP() << "this CPU has no AVX2 + FMA";
  EXPECT_EQ(svgf_cpu_isa(SvgfCpuIsa::kBaseline), SvgfCpuIsa::kBaseline);
  const uint32_t w = 96, h = 64;
  const size_t n = size_t(w) * h;
  for (uint32_t radius : {1u, 2u}) {
    SCOPED_TRACE("kernel radius " + std::to_string(radius));
    SvgfParams params = svgf_default_params(w, h);
    params.kernel_radius = radius;
    FilterRun runs[2] = {FilterRun(n), FilterRun(n)};
    std::mt19937 rng(11);
    for (int frame = 0; frame < 5; ++frame) {
      const int cur = frame & 1;
      std::vector<PixelFeatures> f;
      std::vector<Vec3> radiance;
      make_square_frame(frame, w, h, rng, f, radiance);
      for (int isa = 0; isa < 2; ++isa) {
        FilterRun& r = runs[isa];
        r.features[cur] = f;
        svgf_run_cpu(params, r.frame(cur, frame > 0, radiance),
                     isa == 0 ? SvgfCpuIsa::kBaseline : SvgfCpuIsa::kAvx2);
      }
      SCOPED_TRACE("frame " + std::to_string(frame));
      // The history (reprojection, firefly clamp) is the same too.
      for (size_t i = 0; i < n; ++i)
        EXPECT_EQ(runs[0].moments[cur][i].z, runs[1].moments[cur][i].z) << "pixel " << i;
      const RelativeDifference d = relative_difference(runs[0].output, runs[1].output);
      EXPECT_LT(d.worst, 1e-3) << "largest relative difference";
      EXPECT_LT(d.mean, 1e-5) << "mean relative difference";
    }
  }
}

// The viewer reads input between the parts of the feature pass: a stop
// after the first band leaves the rest unwritten, and a stop that never
// says so changes nothing.
TEST(Denoise, TheFeaturePassStopsBetweenBandsOfRows) {
  Scene scene = make_cornell_box();
  RenderSettings settings;
  settings.width = 40;
  settings.height = 64;
  Compiled c;
  c.compile(scene, settings);
  MotionHistory still;
  const FeaturePass pass = still.advance(c.ks.view());
  std::vector<PixelFeatures> whole(40 * 64), asked(40 * 64);
  ASSERT_TRUE(c.backend.render_features(pass, whole.data(), {}));
  int calls = 0;
  ASSERT_TRUE(c.backend.render_features(pass, asked.data(), [&] { return ++calls < 0; }));
  EXPECT_EQ(calls, int(kFeatureBands) - 1) << "asked between every two bands";
  EXPECT_EQ(std::memcmp(whole.data(), asked.data(), whole.size() * sizeof(PixelFeatures)), 0);

  std::vector<PixelFeatures> stopped(40 * 64);
  std::memset(stopped.data(), 0xab, stopped.size() * sizeof(PixelFeatures));
  const std::vector<PixelFeatures> untouched = stopped;
  ASSERT_TRUE(c.backend.render_features(pass, stopped.data(), [] { return true; }));
  const size_t band = size_t(std::max(64u / kFeatureBands, 8u)) * 40;
  EXPECT_EQ(std::memcmp(stopped.data(), whole.data(), band * sizeof(PixelFeatures)), 0);
  EXPECT_EQ(std::memcmp(stopped.data() + band, untouched.data() + band,
                        (stopped.size() - band) * sizeof(PixelFeatures)),
            0)
      << "rows after the stop were written";
}

// A filter stopped at any of the points where it asks leaves the output
// alone and drops the history, so the next frame is filtered as a fresh
// denoiser would; a stop that never says so changes nothing.
TEST(Denoise, AStoppedFilterIsFollowedByAFreshHistory) {
  const uint32_t w = 96, h = 64;
  std::mt19937 rng(11);
  std::vector<PixelFeatures> f[3];
  ImageRGB r[3];
  for (int k = 0; k < 3; ++k) {
    std::vector<Vec3> radiance;
    make_square_frame(k, w, h, rng, f[k], radiance);
    r[k] = image_from(radiance, w, h);
  }
  auto primed = [&] {
    TemporalDenoiser d;
    d.process(f[0], r[0]);
    d.process(f[1], r[1]);
    return d;
  };
  TemporalDenoiser plain = primed(), asked = primed();
  const ImageRGB want = plain.process(f[2], r[2]);
  int calls = 0;
  ImageRGB got;
  ASSERT_TRUE(asked.process(f[2], r[2], got, [&] { return ++calls < 0; }));
  EXPECT_EQ(got.rgb, want.rgb);
  // Bands of the split, temporal and variance stages, the points between
  // the stages and iterations.
  EXPECT_GE(calls, 3 * 3 + 2 + int(svgf_default_params(w, h).iterations) - 1);

  TemporalDenoiser fresh;
  fresh.process(f[0], r[0]);  // a history of its own, then a cut
  fresh.reset();
  const ImageRGB after_cut = fresh.process(f[2], r[2]);
  for (int stop_at = 1; stop_at <= calls; ++stop_at) {
    SCOPED_TRACE("stopped at call " + std::to_string(stop_at));
    TemporalDenoiser d = primed();
    int n = 0;
    ImageRGB out;
    EXPECT_FALSE(d.process(f[2], r[2], out, [&] { return ++n == stop_at; }));
    EXPECT_EQ(out.width, 0u) << "the output was written";
    EXPECT_FALSE(d.has_history());
    EXPECT_EQ(d.process(f[2], r[2]).rgb, after_cut.rgb);
  }

  // A new size (the viewer's still resolution after motion) asks between
  // the groups of buffers it sizes too.
  std::vector<PixelFeatures> small_f;
  std::vector<Vec3> small_radiance;
  make_square_frame(0, 48, 32, rng, small_f, small_radiance);
  const ImageRGB small_r = image_from(small_radiance, 48, 32);
  TemporalDenoiser at_small;
  const ImageRGB small_want = at_small.process(small_f, small_r);
  for (int stop_at = 1; stop_at <= 6; ++stop_at) {
    SCOPED_TRACE("new size, stopped at call " + std::to_string(stop_at));
    TemporalDenoiser d = primed();
    int n = 0;
    ImageRGB out;
    EXPECT_FALSE(d.process(small_f, small_r, out, [&] { return ++n == stop_at; }));
    EXPECT_EQ(d.process(small_f, small_r).rgb, small_want.rgb);
    EXPECT_EQ(d.process(f[2], r[2]).rgb, after_cut.rgb) << "back at the first size";
  }
}

}  // namespace
}  // namespace tandem
