// What `tandem render --denoise / --aov DIR` and `tandem bench
// --denoise-quality` share: the feature pass of a Scene on an Embree
// backend of its own (whatever backends rendered the image), the feature
// buffers as EXR files, and the image metrics.
#pragma once

#include <filesystem>
#include <vector>

#include "core/image/image.h"
#include "core/kernel/features.h"
#include "core/world/kernel_scene.h"

namespace tandem {

// Features of `scene` at `settings` (a copy is compiled; `scene` keeps its
// dirty flags), with no motion.
std::vector<PixelFeatures> render_scene_features(const Scene& scene,
                                                 const RenderSettings& settings);

// Checks before rendering that `dir` is a directory or can be made one;
// throws InputError naming it.
void check_aov_directory(const std::filesystem::path& dir);
// albedo.exr, normal.exr (xyz, -1..1), depth.exr (linear depth in every
// channel), motion.exr (x, y in pixels, 0) and ids.exr (instance,
// primitive, material; -1 for the environment), each written atomically.
void write_feature_aovs(const std::filesystem::path& dir,
                        const std::vector<PixelFeatures>& features, uint32_t width,
                        uint32_t height);

// One offline image of `spp` samples per pixel through the filter (no
// history): the variance estimate is scaled by 1 / spp, so a converged
// image keeps its detail and a noisy one is smoothed.
ImageRGB denoise_offline_image(const std::vector<PixelFeatures>& features, const ImageRGB& image,
                               uint32_t spp);

// (relative_mse() is in core/image/image.h.)
// Mean SSIM of the luminance of the tone-mapped (x / (1 + x)) images, 8x8
// windows with stride 4.
double ssim_luminance(const ImageRGB& image, const ImageRGB& reference);

}  // namespace tandem
