#include "app/render_denoise.h"

#include <cmath>
#include <system_error>

#include "backends/cpu/cpu_backend.h"
#include "core/render/temporal_denoiser.h"
#include "core/util/errors.h"
#include "core/world/motion_history.h"
#include "sync/scene_sync.h"

namespace tandem {

std::vector<PixelFeatures> render_scene_features(const Scene& scene,
                                                 const RenderSettings& settings) {
  Scene copy = scene;
  SceneSync scene_sync(SceneSyncSettings::arrays_only());  // Embree builds its own
  const SceneSyncUpdate& up = scene_sync.update(copy, settings);
  CpuBackend backend{CpuTraversal::kEmbree};
  backend.sync(scene_sync.kernel_scene(), up.changes);
  MotionHistory motion;
  std::vector<PixelFeatures> features(size_t(settings.width) * settings.height);
  backend.render_features(motion.advance(scene_sync.view()), features.data(), {});
  return features;
}

void check_aov_directory(const std::filesystem::path& dir) {
  std::error_code ec;
  if (std::filesystem::exists(dir, ec)) {
    if (!std::filesystem::is_directory(dir, ec))
      throw InputError(dir.string() + ": --aov needs a directory, and this is a file");
    return;
  }
  if (!std::filesystem::create_directories(dir, ec) || ec)
    throw InputError(dir.string() + ": cannot create the --aov directory: " + ec.message());
}

void write_feature_aovs(const std::filesystem::path& dir, const std::vector<PixelFeatures>& f,
                        uint32_t width, uint32_t height) {
  ImageRGB albedo(width, height), normal(width, height), depth(width, height),
      motion(width, height), ids(width, height);
  auto id = [](uint32_t v) { return v == kInvalidIndex ? -1.0f : float(v); };
  for (size_t i = 0; i < f.size(); ++i) {
    const PixelFeatures& p = f[i];
    float* a = &albedo.rgb[3 * i];
    a[0] = p.albedo.x, a[1] = p.albedo.y, a[2] = p.albedo.z;
    float* n = &normal.rgb[3 * i];
    n[0] = p.normal.x, n[1] = p.normal.y, n[2] = p.normal.z;
    for (int c = 0; c < 3; ++c)
      depth.rgb[3 * i + c] = p.depth;
    motion.rgb[3 * i] = p.motion.x, motion.rgb[3 * i + 1] = p.motion.y;
    float* d = &ids.rgb[3 * i];
    d[0] = id(p.instance), d[1] = id(p.prim), d[2] = id(p.material);
  }
  write_image(dir / "albedo.exr", albedo);
  write_image(dir / "normal.exr", normal);
  write_image(dir / "depth.exr", depth);
  write_image(dir / "motion.exr", motion);
  write_image(dir / "ids.exr", ids);
}

ImageRGB denoise_offline_image(const std::vector<PixelFeatures>& features, const ImageRGB& image,
                               uint32_t spp) {
  SvgfParams params = svgf_default_params(image.width, image.height);
  params.variance_scale = 1.0f / float(spp);
  TemporalDenoiser denoiser(params);
  return denoiser.process(features, image);
}

double ssim_luminance(const ImageRGB& image, const ImageRGB& ref) {
  const uint32_t w = image.width, h = image.height;
  auto lum = [](const ImageRGB& img, uint32_t x, uint32_t y) {
    const float* p = img.pixel(x, y);
    const double l = 0.2126 * p[0] + 0.7152 * p[1] + 0.0722 * p[2];
    return l / (1.0 + l);
  };
  const double c1 = 1e-4, c2 = 9e-4;  // (0.01 L)^2, (0.03 L)^2 with L = 1
  double total = 0.0;
  int windows = 0;
  for (uint32_t y0 = 0; y0 + 8 <= h; y0 += 4) {
    for (uint32_t x0 = 0; x0 + 8 <= w; x0 += 4) {
      double ma = 0, mb = 0, va = 0, vb = 0, cov = 0;
      for (uint32_t y = y0; y < y0 + 8; ++y)
        for (uint32_t x = x0; x < x0 + 8; ++x)
          ma += lum(image, x, y), mb += lum(ref, x, y);
      ma /= 64.0, mb /= 64.0;
      for (uint32_t y = y0; y < y0 + 8; ++y) {
        for (uint32_t x = x0; x < x0 + 8; ++x) {
          const double a = lum(image, x, y) - ma, b = lum(ref, x, y) - mb;
          va += a * a, vb += b * b, cov += a * b;
        }
      }
      va /= 63.0, vb /= 63.0, cov /= 63.0;
      total += ((2 * ma * mb + c1) * (2 * cov + c2)) / ((ma * ma + mb * mb + c1) * (va + vb + c2));
      ++windows;
    }
  }
  return windows ? total / windows : 1.0;
}

}  // namespace tandem
