#include "scenes/scene_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <new>

#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/log.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_loader.h"

namespace tandem {

Scene load_scene(const std::string& spec, const SceneLoadOptions& options) {
  const std::string prefix = "builtin:";
  if (spec.rfind(prefix, 0) == 0) {
    if (options.camera > 0) {
      throw InputError(spec + ": camera " + std::to_string(options.camera) +
                       " was asked for, but a built-in scene has one camera (0)");
    }
    return make_builtin_scene(spec.substr(prefix.size()));
  }
  const std::filesystem::path path(spec);
  std::string ext = path.extension().string();
  for (char& c : ext)
    c = char(std::tolower(static_cast<unsigned char>(c)));
  if (ext != ".gltf" && ext != ".glb") {
    throw InputError(spec +
                     ": unsupported scene format (expected a .gltf or .glb file, or builtin:NAME)");
  }
  GltfOptions gltf;
  gltf.scene_index = options.gltf_scene;
  gltf.allow_outside_uris = options.allow_outside_uris;
  gltf.animations = options.animations;
  gltf.camera = options.camera;
  return load_gltf(path, gltf, options.gltf_summary);
}

void load_environment_map(Scene& scene, const std::string& path, float intensity) {
  // Checked from the header, before anything is decoded: a 400 KiB PNG can
  // claim 16384x8192 pixels, and each takes about
  // kEnvironmentBytesPerPixel in the end (the float map twice: the scene's
  // and the kernel's, and the sampling tables), more while it is decoded.
  ImageReadLimits limits;
  limits.max_pixels = kMaxEnvironmentPixels;
  limits.use = "an environment map";
  limits.advice = "scale it down to 8192x4096 or less";
  limits.bytes_per_pixel_in_use = kEnvironmentBytesPerPixel;
  const ImageRGB image = read_image(path, limits);
  // Within the limit, a small file can still ask for much more memory than
  // it holds: it is said before the rest is taken.
  const uint64_t need = uint64_t(image.width) * image.height * kEnvironmentBytesPerPixel;
  std::error_code ec;
  const uintmax_t file_bytes = std::filesystem::file_size(path, ec);
  if (need > (uint64_t(512) << 20) && !ec && need > 64 * uint64_t(file_bytes)) {
    char text[256];
    std::snprintf(text, sizeof text,
                  ": this %.0f KiB file is an environment map of %ux%u pixels; it takes about "
                  "%.1f GiB of memory to render",
                  double(file_bytes) / 1024.0, image.width, image.height,
                  double(need) / double(1u << 30));
    log_warning(path + text);
  }
  set_environment_map(scene, image, path, intensity);
}

void set_environment_map(Scene& scene, const ImageRGB& img, const std::string& path,
                         float intensity) {
  if (img.width < 2 || img.height < 1) throw InputError(path + ": environment map is too small");
  Environment& env = scene.edit_environment();
  env.color = glm::vec3(1.0f);
  env.intensity = intensity;
  env.width = img.width;
  env.height = img.height;
  env.source = path;
  try {
    env.texels.resize(size_t(img.width) * img.height);
  } catch (const std::bad_alloc&) {
    throw InputError(path + ": not enough memory for a " + std::to_string(img.width) + "x" +
                     std::to_string(img.height) + " environment map");
  }
  float brightest = 0.0f;
  for (size_t i = 0; i < env.texels.size(); ++i) {
    glm::vec3 c(img.rgb[3 * i], img.rgb[3 * i + 1], img.rgb[3 * i + 2]);
    // Negative or non-finite texels would poison the sampling tables.
    for (int k = 0; k < 3; ++k)
      c[k] = std::isfinite(c[k]) && c[k] > 0.0f ? c[k] : 0.0f;
    env.texels[i] = c;
    brightest = std::max({brightest, c.x, c.y, c.z});
  }
  // Samples are summed in float: a product near float's range overflows to
  // infinity and the image comes out black.
  if (double(brightest) * double(intensity) > 1e30) {
    char buf[200];
    std::snprintf(buf, sizeof buf,
                  ": the brightest texel (%g) times the intensity (%g) is %g, beyond the "
                  "largest radiance that can be rendered (1e30)",
                  double(brightest), double(intensity), double(brightest) * double(intensity));
    throw InputError(path + buf);
  }
}

// Generated at build time from data/env/sky.hdr (cmake/EmbedFile.cmake).
extern const unsigned char kDefaultEnvironmentHdr[];
extern const unsigned long kDefaultEnvironmentHdrSize;

ImageRGB default_environment_image() {
  return read_image_from_memory(kDefaultEnvironmentHdr, size_t(kDefaultEnvironmentHdrSize),
                                kDefaultEnvironmentName);
}

}  // namespace tandem
