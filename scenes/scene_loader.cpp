#include "scenes/scene_loader.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <new>

#include "core/image/image.h"
#include "core/util/errors.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_loader.h"

namespace tandem {

Scene load_scene(const std::string& spec, const SceneLoadOptions& options) {
  const std::string prefix = "builtin:";
  if (spec.rfind(prefix, 0) == 0) return make_builtin_scene(spec.substr(prefix.size()));
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
  return load_gltf(path, gltf);
}

void load_environment_map(Scene& scene, const std::string& path, float intensity) {
  ImageRGB img = read_image(path);
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

}  // namespace tandem
