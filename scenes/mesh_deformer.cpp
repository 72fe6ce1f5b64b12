#include "scenes/mesh_deformer.h"

#include "core/world/kernel_scene.h"
#include "core/world/running_box.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <cmath>
#include <cstring>
#include <limits>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace tandem {

JointMatrix joint_matrix(const glm::mat4& a) {
  JointMatrix j;
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      j.m[4 * r + c] = a[c][r];  // glm is column-major
  }
  return j;
}

glm::mat4 to_mat4(const JointMatrix& j) {
  glm::mat4 a(1.0f);
  for (int r = 0; r < 3; ++r) {
    for (int c = 0; c < 4; ++c)
      a[c][r] = j.m[4 * r + c];
  }
  return a;
}

namespace {

// Vertices per task: large enough that a task is a few microseconds of
// work, small enough that two cores balance on a 10 k vertex mesh.
constexpr size_t kBlock = 4096;

// Four floats in one SSE/NEON register (GCC/Clang vector extension): a
// column of a joint matrix. Blending and transforming column-wise needs no
// horizontal sums, so each influence is four multiply-adds of registers.
typedef float v4 __attribute__((vector_size(16)));
struct alignas(16) Columns {
  v4 c[4];  // x, y, z axes and translation; lane 3 unused
};

Columns columns_of(const JointMatrix& j) {
  Columns k;
  for (int c = 0; c < 4; ++c)
    k.c[c] = v4{j.m[c], j.m[4 + c], j.m[8 + c], 0.0f};
  return k;
}

inline v4 splat(float x) {
  return v4{x, x, x, x};
}
inline v4 load3(const glm::vec3& v) {
  return v4{v.x, v.y, v.z, 0.0f};
}
inline glm::vec3 store3(v4 v) {
  return {v[0], v[1], v[2]};
}
inline v4 cross(v4 a, v4 b) {
  const v4 a_yzx = __builtin_shufflevector(a, a, 1, 2, 0, 3);
  const v4 b_yzx = __builtin_shufflevector(b, b, 1, 2, 0, 3);
  const v4 c = a * b_yzx - a_yzx * b;
  return __builtin_shufflevector(c, c, 1, 2, 0, 3);
}
inline float dot3(v4 a, v4 b) {
  const v4 p = a * b;
  return p[0] + p[1] + p[2];
}

// Unit `v`, or `fallback` when it is (nearly) zero or not finite: a zero
// tangent marks "no tangent here" and must stay zero; a collapsed normal
// keeps its input.
inline glm::vec3 normalised_or_kept(const glm::vec3& v, const glm::vec3& fallback) {
  const float len2 = glm::dot(v, v);
  if (!(len2 > 1e-30f) || !std::isfinite(len2)) return fallback;
  return v * (1.0f / std::sqrt(len2));
}
// 1 / sqrt(x): the hardware estimate and one Newton step (relative error
// about 1e-7, a unit vector to float precision) costs a fraction of a
// square root and a division, which were a third of the skinning time.
inline float inverse_sqrt(float x) {
#if defined(__SSE__)
  float r = _mm_cvtss_f32(_mm_rsqrt_ss(_mm_set_ss(x)));
  return r * (1.5f - 0.5f * x * r * r);
#else
  return 1.0f / std::sqrt(x);
#endif
}
inline glm::vec3 normalised_or_kept(v4 v, const glm::vec3& fallback) {
  const float len2 = dot3(v, v);
  // One comparison pair rejects zero, infinity and NaN alike.
  if (!(len2 > 1e-30f && len2 < 1e30f)) return fallback;
  return store3(v * splat(inverse_sqrt(len2)));
}

struct ActiveTarget {
  uint32_t index;
  float weight;
};

struct Job {
  const MeshDeformation& d;
  const Columns* palette;  // null: not skinned
  const std::vector<ActiveTarget>& active;
  bool morph_p, morph_n, morph_t;
  Mesh& out;
  // The same vertices in a KernelScene's arrays (the mesh's first vertex),
  // written from the same registers; null: only `out`.
  Vec3* kernel_positions = nullptr;
  Vec3* kernel_normals = nullptr;
  Vec4* kernel_tangents = nullptr;
};

inline void put_position(const Job& job, size_t v, const glm::vec3& p) {
  job.out.positions[v] = p;
  if (job.kernel_positions != nullptr) job.kernel_positions[v] = {p.x, p.y, p.z};
}
inline void put_normal(const Job& job, size_t v, const glm::vec3& n) {
  job.out.normals[v] = n;
  if (job.kernel_normals != nullptr) job.kernel_normals[v] = {n.x, n.y, n.z};
}
inline void put_tangent(const Job& job, size_t v, const glm::vec4& t) {
  job.out.tangents[v] = t;
  if (job.kernel_tangents != nullptr) job.kernel_tangents[v] = {t.x, t.y, t.z, t.w};
}

// One block of vertices; the template flags take every per-mesh decision
// out of the vertex loop. kInfluences: the mesh's influences per vertex
// known at compile time (0: read from the mesh), so the blend is unrolled;
// four (glTF's JOINTS_0 / WEIGHTS_0) is the common case, and the loop's
// counter, branch and index arithmetic were a tenth of the vertex's work.
template <bool kSkin, bool kMorph, bool kNormals, bool kTangents, uint32_t kInfluences = 0>
void deform_block(const Job& job, size_t begin, size_t end) {
  const MeshDeformation& d = job.d;
  const size_t vertices = d.vertex_count();
  const uint32_t influences = kInfluences != 0 ? kInfluences : d.influences;
  for (size_t v = begin; v != end; ++v) {
    glm::vec3 p = d.base_positions[v];
    glm::vec3 n = kNormals ? d.base_normals[v] : glm::vec3(0.0f);
    glm::vec4 t = kTangents ? d.base_tangents[v] : glm::vec4(0.0f);
    if (kMorph) {
      for (const ActiveTarget& a : job.active) {
        const size_t at = size_t(a.index) * vertices + v;
        if (job.morph_p) p += a.weight * d.position_deltas[at];
        if (kNormals && job.morph_n) n += a.weight * d.normal_deltas[at];
        if (kTangents && job.morph_t) t += glm::vec4(a.weight * d.tangent_deltas[at], 0.0f);
      }
    }
    if (!kSkin) {
      put_position(job, v, p);
      if (kNormals) put_normal(job, v, kMorph ? normalised_or_kept(n, n) : n);
      if (kTangents) {
        const glm::vec3 tx(t);
        put_tangent(job, v, glm::vec4(kMorph ? normalised_or_kept(tx, tx) : tx, t.w));
      }
      continue;
    }
    // The blended matrix: a weighted sum of the palette entries (zero
    // weights are multiplied too: cheaper than a branch that mispredicts).
    const uint16_t* joint = &d.joints[v * influences];
    const float* weight = &d.weights[v * influences];
    v4 c0 = splat(0.0f), c1 = c0, c2 = c0, c3 = c0;
    for (uint32_t i = 0; i < influences; ++i) {
      const v4 w = splat(weight[i]);
      const Columns& k = job.palette[joint[i]];
      c0 += w * k.c[0];
      c1 += w * k.c[1];
      c2 += w * k.c[2];
      c3 += w * k.c[3];
    }
    put_position(job, v, store3(c0 * splat(p.x) + c1 * splat(p.y) + c2 * splat(p.z) + c3));
    if (kNormals) {
      // Cofactor matrix (columns c1 x c2, c2 x c0, c0 x c1) = det * A^-T.
      const v4 k0 = cross(c1, c2), k1 = cross(c2, c0), k2 = cross(c0, c1);
      const float sign = dot3(c0, k0) < 0.0f ? -1.0f : 1.0f;
      const v4 sn = splat(sign) * (k0 * splat(n.x) + k1 * splat(n.y) + k2 * splat(n.z));
      if (kMorph) {
        put_normal(job, v, normalised_or_kept(sn, normalised_or_kept(n, n)));
      } else {
        job.out.normals[v] = store3(sn);  // normalised below, four at a time
      }
    }
    if (kTangents) {
      const v4 st = c0 * splat(t.x) + c1 * splat(t.y) + c2 * splat(t.z);
      put_tangent(job, v, glm::vec4(normalised_or_kept(st, glm::vec3(t)), t.w));
    }
  }
}

// normalised_or_kept() of the skinned normals a block left in out.normals,
// the unmorphed base normal kept where one collapsed. Four at a time: one
// vertex at a time, the chain of dot product, reciprocal square root and
// Newton step was half the skinning time, each vertex waiting for its own.
// Bit for bit the one-at-a-time result: the packed estimate and the same
// operations in the same order, lane by lane.
void normalise_block(const Job& job, size_t begin, size_t end) {
  glm::vec3* out = job.out.normals.data();
  const glm::vec3* base = job.d.base_normals.data();
  size_t v = begin;
#if defined(__SSE__)
  for (; v + 4 <= end; v += 4) {
    alignas(16) float len2[4], inv[4];
    for (int k = 0; k < 4; ++k)
      len2[k] = dot3(load3(out[v + k]), load3(out[v + k]));
    const __m128 x = _mm_load_ps(len2);
    const __m128 r = _mm_rsqrt_ps(x);
    const __m128 nr =
        _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(1.5f),
                                 _mm_mul_ps(_mm_mul_ps(_mm_mul_ps(_mm_set1_ps(0.5f), x), r), r)));
    _mm_store_ps(inv, nr);
    for (int k = 0; k < 4; ++k) {
      put_normal(job, v + k,
                 len2[k] > 1e-30f && len2[k] < 1e30f ? store3(load3(out[v + k]) * splat(inv[k]))
                                                     : base[v + k]);
    }
  }
#endif
  for (; v < end; ++v)
    put_normal(job, v, normalised_or_kept(load3(out[v]), base[v]));
}

template <bool kSkin, bool kMorph, bool kNormals, bool kTangents, uint32_t kInfluences = 0>
void deform_and_normalise_block(const Job& job, size_t begin, size_t end) {
  deform_block<kSkin, kMorph, kNormals, kTangents, kInfluences>(job, begin, end);
  normalise_block(job, begin, end);
}

using BlockFn = void (*)(const Job&, size_t, size_t);

template <bool kSkin, bool kMorph>
BlockFn pick(bool normals, bool tangents, uint32_t influences) {
  if (normals && kSkin && !kMorph) {
    if (influences == 4) {
      return tangents ? &deform_and_normalise_block<kSkin, kMorph, true, true, 4>
                      : &deform_and_normalise_block<kSkin, kMorph, true, false, 4>;
    }
    return tangents ? &deform_and_normalise_block<kSkin, kMorph, true, true>
                    : &deform_and_normalise_block<kSkin, kMorph, true, false>;
  }
  if (normals) {
    return tangents ? &deform_block<kSkin, kMorph, true, true>
                    : &deform_block<kSkin, kMorph, true, false>;
  }
  return tangents ? &deform_block<kSkin, kMorph, false, true>
                  : &deform_block<kSkin, kMorph, false, false>;
}

}  // namespace

namespace {

// Where a mesh's vertices lie in a KernelScene's arrays.
struct KernelTarget {
  Vec3* positions = nullptr;
  Vec3* normals = nullptr;
  Vec4* tangents = nullptr;
};

// The box of positions [begin, end) of a block just written (in the cache),
// with the comparisons of the compiler's copy_positions_with_bounds() in
// the same order: for finite positions min and max do not depend on the
// order, and the compiler's positive_zeros() makes -0 and +0 alike, so the
// box is the one the compiler would have taken.
struct BlockBox {
  float lo[3], hi[3];
  bool finite;
};
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr BlockBox kEmptyBox{{kInf, kInf, kInf}, {-kInf, -kInf, -kInf}, true};
// The compiler's RunningBox, started from the box so far: the path where
// there is no SSE (compiled everywhere, so it cannot rot unbuilt).
[[maybe_unused]] void grow_box_scalar(BlockBox& b, const Vec3* p, size_t begin, size_t end) {
  RunningBox r;
  r.lx = b.lo[0], r.ly = b.lo[1], r.lz = b.lo[2];
  r.hx = b.hi[0], r.hy = b.hi[1], r.hz = b.hi[2];
  r.finite = b.finite;
  for (size_t v = begin; v < end; ++v)
    r.add(p[v].x, p[v].y, p[v].z);
  b = {{r.lx, r.ly, r.lz}, {r.hx, r.hy, r.hz}, r.finite};
}
void grow_box(BlockBox& b, const Vec3* p, size_t begin, size_t end) {
#if defined(__SSE__)
  // One 16-byte load a vertex (the kernel positions have a readable element
  // past the last one; lane 3 is ignored): minps(x, lo) is x < lo ? x : lo
  // and maxps(x, hi) is hi < x ? x : hi, grow_box_scalar()'s comparisons lane
  // by lane. x - x is 0 for a finite x and NaN otherwise, and the NaN stays
  // in the sum.
  __m128 lo = _mm_setr_ps(b.lo[0], b.lo[1], b.lo[2], 0.0f);
  __m128 hi = _mm_setr_ps(b.hi[0], b.hi[1], b.hi[2], 0.0f);
  __m128 bad = _mm_setzero_ps();
  for (size_t v = begin; v < end; ++v) {
    const __m128 x = _mm_loadu_ps(&p[v].x);
    lo = _mm_min_ps(x, lo);
    hi = _mm_max_ps(x, hi);
    bad = _mm_add_ps(bad, _mm_sub_ps(x, x));
  }
  alignas(16) float l[4], h[4], n[4];
  _mm_store_ps(l, lo);
  _mm_store_ps(h, hi);
  _mm_store_ps(n, bad);
  b = {{l[0], l[1], l[2]},
       {h[0], h[1], h[2]},
       b.finite && n[0] == 0.0f && n[1] == 0.0f && n[2] == 0.0f};
#else
  grow_box_scalar(b, p, begin, end);
#endif
}
void join_box(BlockBox& a, const BlockBox& b) {
  for (int k = 0; k < 3; ++k) {
    a.lo[k] = b.lo[k] < a.lo[k] ? b.lo[k] : a.lo[k];
    a.hi[k] = a.hi[k] < b.hi[k] ? b.hi[k] : a.hi[k];
  }
  a.finite = a.finite && b.finite;
}

// deform_mesh(), also writing the vertices into `kernel` (when not null)
// and then returning their box in `box`; false when nothing was written
// or a position is not finite.
bool deform_into(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh& out, const KernelTarget* kernel, SceneBounds* box) {
  const size_t vertices = d.vertex_count();
  if (out.positions.size() != vertices) return false;  // not the mesh it was made for
  const bool normals = !d.base_normals.empty() && out.normals.size() == vertices;
  const bool tangents = !d.base_tangents.empty() && out.tangents.size() == vertices;
  // Only targets with a non-zero weight cost anything per vertex.
  std::vector<ActiveTarget> active;
  if (morph_weights != nullptr) {
    for (uint32_t k = 0; k < d.targets; ++k) {
      if (morph_weights[k] != 0.0f && std::isfinite(morph_weights[k]))
        active.push_back({k, morph_weights[k]});
    }
  }
  const bool skinned = d.skinned() && palette != nullptr;
  // The palette in column form, once per mesh and frame.
  std::vector<Columns> columns;
  if (skinned) {
    columns.resize(d.palette_size);
    for (uint32_t j = 0; j < d.palette_size; ++j)
      columns[j] = columns_of(palette[j]);
  }
  Job job{d,
          skinned ? columns.data() : nullptr,
          active,
          !d.position_deltas.empty(),
          normals && !d.normal_deltas.empty(),
          tangents && !d.tangent_deltas.empty(),
          out};
  if (kernel != nullptr) {
    job.kernel_positions = kernel->positions;
    job.kernel_normals = normals ? kernel->normals : nullptr;
    job.kernel_tangents = tangents ? kernel->tangents : nullptr;
  }
  const bool morph = !active.empty();
  const BlockFn fn = skinned ? (morph ? pick<true, true>(normals, tangents, d.influences)
                                      : pick<true, false>(normals, tangents, d.influences))
                             : (morph ? pick<false, true>(normals, tangents, d.influences)
                                      : pick<false, false>(normals, tangents, d.influences));
  if (kernel == nullptr) {
    tbb::parallel_for(tbb::blocked_range<size_t>(0, vertices, kBlock),
                      [&](const tbb::blocked_range<size_t>& r) { fn(job, r.begin(), r.end()); });
    return true;
  }
  // The box of each block while its positions are still in the cache: the
  // compiler, which no longer reads them, would have taken it.
  const BlockBox all = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, vertices, kBlock), kEmptyBox,
      [&](const tbb::blocked_range<size_t>& r, BlockBox acc) {
        fn(job, r.begin(), r.end());
        grow_box(acc, kernel->positions, r.begin(), r.end());
        return acc;
      },
      [](BlockBox a, const BlockBox& b) {
        join_box(a, b);
        return a;
      });
  if (vertices == 0 || !all.finite) return false;
  // positive_zeros(), as the compiler's box.
  box->lo = glm::vec3(all.lo[0], all.lo[1], all.lo[2]) + glm::vec3(0.0f);
  box->hi = glm::vec3(all.hi[0], all.hi[1], all.hi[2]) + glm::vec3(0.0f);
  box->empty = false;
  return true;
}

// The mesh's place in `ks`, when ks holds it as compiled from `mesh` with
// every array the deformation writes.
bool kernel_target(KernelScene& ks, const MeshDeformation& d, const Mesh& mesh, KernelTarget* out) {
  if (d.mesh >= ks.meshes.size() || ks.vertices_written.size() != ks.meshes.size()) return false;
  const KMesh& km = ks.meshes[d.mesh];
  const size_t n = d.vertex_count(), first = km.vertex_offset;
  if (km.vertex_count != n || mesh.positions.size() != n || first + n > ks.positions.size())
    return false;
  out->positions = ks.positions.data() + first;
  if (!d.base_normals.empty() && mesh.normals.size() == n) {
    if (first + n > ks.normals.size()) return false;
    out->normals = ks.normals.data() + first;
  }
  if (!d.base_tangents.empty() && mesh.tangents.size() == n) {
    if (first + n > ks.tangents.size()) return false;
    out->tangents = ks.tangents.data() + first;
  }
  return true;
}

}  // namespace

void deform_mesh(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh& out) {
  deform_into(d, palette, morph_weights, out, nullptr, nullptr);
}

void deform_scene_mesh(const MeshDeformation& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, KernelScene* kernel) {
  if (d.mesh >= scene.meshes().size()) return;
  // Straight into the kernel arrays only when they hold everything else of
  // the mesh already: no edit of its vertices since the last compile.
  const bool clean = !(scene.mesh_dirty()[d.mesh] & kDirtyVertices);
  Mesh& mesh = scene.edit_mesh_vertices(d.mesh);
  KernelTarget target;
  if (kernel == nullptr || !clean || !kernel_target(*kernel, d, mesh, &target)) {
    deform_mesh(d, palette, morph_weights, mesh);
    return;
  }
  SceneBounds box;
  if (deform_into(d, palette, morph_weights, mesh, &target, &box)) {
    scene.note_mesh_vertex_bounds(d.mesh, box);
    kernel->vertices_written[d.mesh] = scene.mesh_vertex_version(d.mesh);
  }
}

bool deform_scene_mesh(const MeshDeformation& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, DeformedPose& last,
                       KernelScene* kernel) {
  if (d.mesh >= scene.meshes().size()) return false;
  const size_t joints = d.skinned() && palette != nullptr ? d.palette_size : 0;
  const size_t targets = morph_weights != nullptr ? d.targets : 0;
  const bool same_pose =
      last.vertex_version != 0 && last.vertex_version == scene.mesh_vertex_version(d.mesh) &&
      last.palette.size() == joints && last.morph_weights.size() == targets &&
      (joints == 0 ||
       std::memcmp(last.palette.data(), palette, joints * sizeof(JointMatrix)) == 0) &&
      (targets == 0 ||
       std::memcmp(last.morph_weights.data(), morph_weights, targets * sizeof(float)) == 0);
  if (same_pose) return false;
  deform_scene_mesh(d, palette, morph_weights, scene, kernel);
  last.palette.assign(palette, palette + joints);
  last.morph_weights.assign(morph_weights, morph_weights + targets);
  last.vertex_version = scene.mesh_vertex_version(d.mesh);
  return true;
}

}  // namespace tandem
