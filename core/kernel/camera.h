// Primary ray generation: pinhole / thin-lens perspective and orthographic
// cameras. Pixel (0, 0) is the top-left of the image; the jitter inside the
// pixel is uniform, i.e. a box reconstruction filter.
#pragma once

#include "core/kernel/sampling.h"
#include "core/kernel/types.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

TANDEM_HD Ray generate_camera_ray(const KCamera& cam, float film_x, float film_y, float lens_u,
                                  float lens_v) {
  // film_x, film_y in pixels (continuous).
  const float ndc_x = 2.0f * film_x / float(cam.width) - 1.0f;
  const float ndc_y = 1.0f - 2.0f * film_y / float(cam.height);
  Ray ray;
  ray.tmin = 0.0f;
  ray.tmax = kFloatMax;
  if (cam.type == kCameraOrthographic) {
    const float hh = cam.ortho_half_height;
    ray.origin = cam.position + cam.right * (ndc_x * hh * cam.aspect) + cam.up * (ndc_y * hh);
    ray.dir = cam.forward;
    return ray;
  }
  const Vec3 dir = normalize(cam.forward + cam.right * (ndc_x * cam.tan_half_fov_y * cam.aspect) +
                             cam.up * (ndc_y * cam.tan_half_fov_y));
  if (cam.aperture_radius <= 0.0f) {
    ray.origin = cam.position;
    ray.dir = dir;
    return ray;
  }
  // Thin lens: all rays through a pixel converge on the focal plane.
  const float t_focus = cam.focus_distance / dot(dir, cam.forward);
  const Vec3 focus = cam.position + dir * t_focus;
  const Vec2 lens = sample_disk_concentric(lens_u, lens_v);
  ray.origin = cam.position + (cam.right * lens.x + cam.up * lens.y) * cam.aperture_radius;
  ray.dir = normalize(focus - ray.origin);
  return ray;
}

TANDEM_KERNEL_END
}  // namespace tandem
