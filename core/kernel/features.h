// Features of a pixel's primary hit (the G-buffer a denoiser steers by):
// albedo, shading normal, linear depth, instance and primitive id, and the
// screen-space motion back to where the same surface point was in the
// previous frame.
//
// Written once for every backend: the CPU backends run compute_pixel_features
// with their Tracer under TBB (backends/cpu_loops/cpu_features.h), the CUDA backend
// in a small kernel. The camera ray goes through the pixel centre with the
// lens centre (no jitter), so a pixel's features do not depend on the sample
// index and stay the same from frame to frame for a static view.
//
// Motion uses the previous frame's camera and instance transforms (captured
// on the host by MotionHistory, core/world/motion_history.h): the hit point
// is taken into its instance's object space with the current transform and
// back out with the previous one, then projected by the previous camera.
#pragma once

#include "core/kernel/geometry.h"
#include "core/kernel/integrator.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// One pixel's features. 64 bytes; an array of them is the feature buffer.
struct PixelFeatures {
  Vec3 albedo;  // base colour at the hit (1 for the environment): radiance is demodulated by it
  float depth;  // linear depth along the camera's forward axis; 0 for a miss
  Vec3 normal;  // shading normal facing the viewer; 0 for a miss
  float prev_depth;   // depth of the same point as seen by the previous camera (0: miss)
  Vec2 motion;        // previous pixel position minus this one, in pixels (x right, y down)
  uint32_t instance;  // kInvalidIndex for a miss
  uint32_t prim;      // kInvalidIndex for a miss
  uint32_t material;  // kInvalidIndex for a miss
  uint32_t pad[3];
};
static_assert(sizeof(PixelFeatures) == 64, "GPU layout");

// What the feature pass needs beyond the scene: the previous frame's camera
// and instance transforms (object to world). An instance at or beyond
// prev_instance_count (a new one) is taken not to have moved.
struct FeaturePass {
  KCamera prev_camera;
  const Mat34* prev_object_to_world;
  uint32_t prev_instance_count;
  uint32_t pad;
};

TANDEM_HD bool features_hit(const PixelFeatures& f) {
  return f.instance != kInvalidIndex;
}

// Continuous film position (pixels, (0, 0) the top-left corner) of world
// point q under `cam`: the inverse of generate_camera_ray for the lens
// centre. Returns false when q is behind the camera. *depth_out receives
// the linear depth along cam.forward.
TANDEM_HD bool project_to_film(const KCamera& cam, Vec3 q, float* film_x, float* film_y,
                               float* depth_out) {
  const Vec3 d = q - cam.position;
  const float z = dot(d, cam.forward);
  *depth_out = z;
  float ndc_x, ndc_y;
  if (cam.type == kCameraOrthographic) {
    const float hh = cam.ortho_half_height;
    ndc_x = dot(d, cam.right) / (hh * cam.aspect);
    ndc_y = dot(d, cam.up) / hh;
  } else {
    if (!(z > 0.0f)) return false;
    ndc_x = dot(d, cam.right) / (z * cam.tan_half_fov_y * cam.aspect);
    ndc_y = dot(d, cam.up) / (z * cam.tan_half_fov_y);
  }
  *film_x = (ndc_x + 1.0f) * 0.5f * float(cam.width);
  *film_y = (1.0f - ndc_y) * 0.5f * float(cam.height);
  return true;
}

// The same for a direction (a point at infinity, e.g. the environment):
// only the camera's orientation matters.
TANDEM_HD bool project_direction_to_film(const KCamera& cam, Vec3 dir, float* film_x,
                                         float* film_y) {
  KCamera at_origin = cam;
  at_origin.position = make_vec3(0.0f);
  at_origin.type = kCameraPerspective;  // an orthographic view sees no parallax either way
  float z;
  return project_to_film(at_origin, dir, film_x, film_y, &z);
}

// Features of pixel (x, y) under the scene's current camera.
template <class Tracer>
TANDEM_HD PixelFeatures compute_pixel_features(const KernelData& kd, const Tracer& tracer,
                                               const FeaturePass& pass, uint32_t x, uint32_t y) {
  const KCamera& cam = kd.constants.camera;
  const float px = float(x) + 0.5f, py = float(y) + 0.5f;
  // Lens sample (0.5, 0.5) maps to the lens centre.
  const Ray ray = generate_camera_ray(cam, px, py, 0.5f, 0.5f);
  PixelFeatures f;
  f.pad[0] = f.pad[1] = f.pad[2] = 0u;
  f.motion = make_vec2(0.0f, 0.0f);
  // The alpha key of sample 0's camera ray, so cut-out foliage hides or shows
  // the same surface the first sample sees.
  PathRng rng = make_path_rng(y * cam.width + x, 0u, kd.constants.integrator.seed);
  const Hit hit = tracer.intersect(ray, rng_bits(rng, bounce_dimension(0u, kBounceAlpha)));
  if (!hit_valid(hit)) {
    f.albedo = make_vec3(1.0f);
    f.depth = 0.0f;
    f.prev_depth = 0.0f;
    f.normal = make_vec3(0.0f);
    f.instance = f.prim = f.material = kInvalidIndex;
    float qx, qy;
    if (project_direction_to_film(pass.prev_camera, ray.dir, &qx, &qy)) {
      f.motion = make_vec2(qx - px, qy - py);
    }
    return f;
  }
  const SurfacePoint sp = make_surface_point(kd, hit);
  const KMaterial& m = kd.materials[sp.material];
  f.albedo = xyz(material_base_color(kd, m, sp.uv));
  f.normal = dot(sp.shading_normal, ray.dir) <= 0.0f ? sp.shading_normal : -sp.shading_normal;
  f.depth = dot(sp.position - cam.position, cam.forward);
  f.instance = hit.instance;
  f.prim = hit.prim;
  f.material = sp.material;
  // Where this point was a frame ago: through the instance's previous pose.
  Vec3 prev_world = sp.position;
  if (hit.instance < pass.prev_instance_count && pass.prev_object_to_world) {
    const Vec3 p_obj = transform_point(kd.instances[hit.instance].world_to_object, sp.position);
    prev_world = transform_point(pass.prev_object_to_world[hit.instance], p_obj);
  }
  float qx, qy, qz;
  if (project_to_film(pass.prev_camera, prev_world, &qx, &qy, &qz)) {
    f.motion = make_vec2(qx - px, qy - py);
    f.prev_depth = qz;
  } else {
    // Behind the previous camera: nothing to reproject from.
    f.motion = make_vec2(-1e6f, -1e6f);
    f.prev_depth = 0.0f;
  }
  return f;
}

TANDEM_KERNEL_END
}  // namespace tandem
