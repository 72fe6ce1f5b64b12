// The environment: its constants and, for a map, the texels and the
// sampling CDFs.
#include "core/kernel/environment.h"
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"
#include "core/world/light_tables.h"

namespace tandem {

void SceneCompiler::compile_environment(const Scene& scene, KernelScene& out, SceneDelta& delta) {
  const Environment& e = scene.environment();
  KEnvironment& k = out.constants.environment;
  k = {};
  k.color = to_vec3(e.color * e.intensity);
  set_environment_rotation(k, e.rotation);
  out.env_texels.clear();
  out.env_marginal_cdf.clear();
  out.env_conditional_cdf.clear();
  out.env_marginal_guide.clear();
  out.env_conditional_guide.clear();
  if (!e.texels.empty() && e.width > 0 && e.height > 0) {
    k.has_map = 1;
    k.width = e.width;
    k.height = e.height;
    out.env_texels.resize(e.texels.size());
    for (size_t i = 0; i < e.texels.size(); ++i)
      out.env_texels[i] = make_vec4(to_vec3(e.texels[i]), 0.0f);
    build_environment_tables(out);
  }
  delta.env_texels.reallocated = delta.env_marginal_cdf.reallocated =
      delta.env_conditional_cdf.reallocated = delta.env_marginal_guide.reallocated =
          delta.env_conditional_guide.reallocated = true;
  delta.constants = true;
}

}  // namespace tandem
