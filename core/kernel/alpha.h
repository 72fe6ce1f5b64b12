// Alpha testing (glTF alphaMode MASK and BLEND) for ray traversal. Every
// backend's traversal calls this for triangles of meshes flagged
// kMeshHasAlphaTest, so cut-outs and stochastic transparency look the same
// everywhere.
#pragma once

#include "core/kernel/geometry.h"
#include "core/kernel/rng.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// Decides whether a candidate hit on an alpha-tested triangle is opaque.
// MASK: alpha >= cutoff. BLEND: stochastic transparency, opaque with
// probability alpha, keyed by (path, instance, primitive).
TANDEM_HD bool alpha_test_opaque(const KernelData& kd, uint32_t instance, uint32_t prim, float u,
                                 float v, uint32_t alpha_key) {
  const KInstance& inst = kd.instances[instance];
  const KMesh& mesh = kd.meshes[inst.mesh];
  const KTriangle tri = kd.triangles[mesh.triangle_offset + prim];
  const KMaterial& m = kd.materials[tri.material];
  if (m.alpha_mode == kAlphaOpaque) return true;
  float alpha = m.base_color.w;
  if (m.base_color_tex.texture >= 0) {
    Vec2 uv[2];
    interpolate_uvs(kd, mesh, tri, u, v, uv);
    alpha *=
        sample_texture(kd, uint32_t(m.base_color_tex.texture), material_uv(m.base_color_tex, uv)).w;
  }
  if (m.alpha_mode == kAlphaMask) return alpha >= m.alpha_cutoff;
  const float r = u32_to_unit_float(hash_combine(hash_combine(alpha_key, instance), prim));
  return r < alpha;
}

TANDEM_KERNEL_END
}  // namespace tandem
