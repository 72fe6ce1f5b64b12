// Constants: the camera, the integrator's settings and the scene's bounds.
#include <cmath>
#include <string>

#include "core/util/errors.h"
#include "core/world/kernel_conversions.h"
#include "core/world/kernel_scene.h"

namespace tandem {

void SceneCompiler::compile_constants(const Scene& scene, const RenderSettings& s,
                                      KernelScene& out) {
  const Camera& c = scene.camera();
  // Every camera ray starts at the camera: one the tracers cannot take
  // (an API edit, an animation, a camera framing a scene beyond range) is
  // refused here, whatever brought it.
  const std::string problem = camera_problem(c);
  if (!problem.empty()) {
    throw InputError(scene.source_name() + ": the camera cannot be rendered: " + problem);
  }
  KCamera& k = out.constants.camera;
  k.type = c.type == CameraType::kOrthographic ? kCameraOrthographic : kCameraPerspective;
  k.position = to_vec3(c.position);
  k.forward = normalize(to_vec3(c.forward));
  k.right = normalize(cross(k.forward, to_vec3(c.up)));
  k.up = cross(k.right, k.forward);
  k.tan_half_fov_y = std::tan(0.5f * c.yfov);
  k.aspect = float(s.width) / float(s.height);
  k.aperture_radius = c.aperture_radius;
  k.focus_distance = c.focus_distance;
  k.ortho_half_height = c.ortho_half_height;
  k.width = s.width;
  k.height = s.height;
  KIntegratorParams& ip = out.constants.integrator;
  ip.max_depth = s.max_depth;
  ip.rr_start_depth = s.rr_start_depth;
  ip.radiance_clamp = s.radiance_clamp;
  ip.seed = s.seed;
  // O(edits since the last call): the compiler caches its bounds.
  const SceneBounds b = scene_bounds(scene);
  out.constants.scene_center = to_vec3(b.center());
  out.constants.scene_radius = b.radius();
  // From the mesh flags the traversals test, so the two always agree.
  uint32_t flags = 0;
  for (const KMesh& m : out.meshes)
    if (m.flags & kMeshHasAlphaTest) flags |= kSceneHasAlphaTest;
  out.constants.scene_flags = flags;
}

}  // namespace tandem
