#include "scenes/mesh_deformer.h"

#include "core/kernel/host_isa.h"
#include "core/kernel/math.h"
#include "core/world/mesh_pose.h"
#include "core/world/running_box.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <memory>

#if defined(__SSE__)
#include <xmmintrin.h>
#endif

namespace tandem {

DeformIsaChoice deform_isa{host_cpu_has_avx2()};

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

struct ActiveTarget {
  uint32_t index;
  float weight;
};

struct Job {
  const MeshDeformation& d;
  const Columns* palette;   // null: not skinned
  const JointMatrix* rows;  // the same palette as given (rows); null: not skinned
  const std::vector<ActiveTarget>& active;
  bool morph_p, morph_n, morph_t;
  // The Scene mesh's arrays; null: not written (only the kernel's). Normals
  // and tangents are null too when the mesh has none.
  glm::vec3* out_positions = nullptr;
  glm::vec3* out_normals = nullptr;
  glm::vec4* out_tangents = nullptr;
  // The same vertices in a KernelScene's arrays (the mesh's first vertex),
  // written from the same registers; null: only the Scene's.
  Vec3* kernel_positions = nullptr;
  Vec3* kernel_normals = nullptr;
  Vec4* kernel_tangents = nullptr;
};

inline void put_position(const Job& job, size_t v, const glm::vec3& p) {
  if (job.out_positions != nullptr) job.out_positions[v] = p;
  if (job.kernel_positions != nullptr) job.kernel_positions[v] = {p.x, p.y, p.z};
}
inline void put_normal(const Job& job, size_t v, const glm::vec3& n) {
  if (job.out_normals != nullptr) job.out_normals[v] = n;
  if (job.kernel_normals != nullptr) job.kernel_normals[v] = {n.x, n.y, n.z};
}
inline void put_tangent(const Job& job, size_t v, const glm::vec4& t) {
  if (job.out_tangents != nullptr) job.out_tangents[v] = t;
  if (job.kernel_tangents != nullptr) job.kernel_tangents[v] = {t.x, t.y, t.z, t.w};
}
// Where a skinned normal waits, not yet normalised, for normalise_block():
// the first of the two copies that is written.
inline float* unnormalised_normal(const Job& job, size_t v) {
  return job.out_normals != nullptr ? &job.out_normals[v].x : &job.kernel_normals[v].x;
}

// One block of vertices; the template flags take every per-mesh decision
// out of the vertex loop. kInfluences: the mesh's influences per vertex
// known at compile time (0: read from the mesh), so the blend is unrolled;
// four (glTF's JOINTS_0 / WEIGHTS_0) is the common case, and the loop's
// counter, branch and index arithmetic were a tenth of the vertex's work.
template <bool kSkin, bool kMorph, bool kNormals, bool kTangents, uint32_t kInfluences = 0>
void deform_block(const Job& job, size_t begin, size_t end, BlockBox* box) {
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
        const glm::vec3 raw = store3(sn);  // normalised below, four at a time
        float* slot = unnormalised_normal(job, v);
        slot[0] = raw.x, slot[1] = raw.y, slot[2] = raw.z;
      }
    }
    if (kTangents) {
      const v4 st = c0 * splat(t.x) + c1 * splat(t.y) + c2 * splat(t.z);
      put_tangent(job, v, glm::vec4(normalised_or_kept(st, glm::vec3(t)), t.w));
    }
  }
  // The block's box while its positions are still in the cache.
  if (box != nullptr) grow_box(*box, job.kernel_positions, begin, end);
}

// normalised_or_kept() of the skinned normals a block left unnormalised,
// the unmorphed base normal kept where one collapsed. Four at a time: one
// vertex at a time, the chain of dot product, reciprocal square root and
// Newton step was half the skinning time, each vertex waiting for its own.
// Bit for bit the one-at-a-time result: the packed estimate and the same
// operations in the same order, lane by lane.
void normalise_block(const Job& job, size_t begin, size_t end) {
  const glm::vec3* base = job.d.base_normals.data();
  auto raw = [&](size_t v) {
    const float* n = unnormalised_normal(job, v);
    return glm::vec3(n[0], n[1], n[2]);
  };
  size_t v = begin;
#if defined(__SSE__)
  for (; v + 4 <= end; v += 4) {
    alignas(16) float len2[4], inv[4];
    for (int k = 0; k < 4; ++k)
      len2[k] = dot3(load3(raw(v + k)), load3(raw(v + k)));
    const __m128 x = _mm_load_ps(len2);
    const __m128 r = _mm_rsqrt_ps(x);
    const __m128 nr =
        _mm_mul_ps(r, _mm_sub_ps(_mm_set1_ps(1.5f),
                                 _mm_mul_ps(_mm_mul_ps(_mm_mul_ps(_mm_set1_ps(0.5f), x), r), r)));
    _mm_store_ps(inv, nr);
    for (int k = 0; k < 4; ++k) {
      put_normal(job, v + k,
                 len2[k] > 1e-30f && len2[k] < 1e30f ? store3(load3(raw(v + k)) * splat(inv[k]))
                                                     : base[v + k]);
    }
  }
#endif
  for (; v < end; ++v)
    put_normal(job, v, normalised_or_kept(load3(raw(v)), base[v]));
}

#if TANDEM_HOST_AVX2
// The common skin (four influences, normals, no tangents, no morph) eight
// vertices at a time for CPUs with AVX2: what follows the blend, a vertex
// a lane. One vertex a 4-float register (the baseline loop) leaves a lane
// idle and spends a shuffle on every broadcast and cross product; here the
// position, cofactor, sign and normalisation are plain multiplies and adds
// of eight lanes. The blend gathers each vertex's matrices through its
// joints, two vertices a register (v + k in the low half, v + 4 + k in the
// high), the matrices as their three rows; one in-lane transpose a row
// then gives each matrix element for the eight vertices in order.
//
// Bit for bit deform_block() + normalise_block(): the same operations on
// the same operands in the same order, lane by lane (the blend's sums from
// +0, the column combinations, cross(), dot3(), the estimate and Newton
// step), and no FMA. Tests compare the two (deform_isa).
#define TANDEM_AVX2_INLINE TANDEM_TARGET_AVX2 __attribute__((always_inline)) inline

struct Soa8 {
  __m256 x, y, z;
};
// In each 128-bit half, the 4x4 transpose of rows a, b, c, d.
struct Transposed8 {
  __m256 t[4];
};
TANDEM_AVX2_INLINE Transposed8 transpose8(__m256 a, __m256 b, __m256 c, __m256 d) {
  const __m256 ab_lo = _mm256_unpacklo_ps(a, b), cd_lo = _mm256_unpacklo_ps(c, d);
  const __m256 ab_hi = _mm256_unpackhi_ps(a, b), cd_hi = _mm256_unpackhi_ps(c, d);
  return {{_mm256_shuffle_ps(ab_lo, cd_lo, _MM_SHUFFLE(1, 0, 1, 0)),
           _mm256_shuffle_ps(ab_lo, cd_lo, _MM_SHUFFLE(3, 2, 3, 2)),
           _mm256_shuffle_ps(ab_hi, cd_hi, _MM_SHUFFLE(1, 0, 1, 0)),
           _mm256_shuffle_ps(ab_hi, cd_hi, _MM_SHUFFLE(3, 2, 3, 2))}};
}
// Eight consecutive 12-byte vertices from `at`; the 16-byte load of the
// eighth reads the x of a ninth, which must exist.
TANDEM_AVX2_INLINE Soa8 load_soa8(const float* at) {
  const Transposed8 t =
      transpose8(_mm256_loadu2_m128(at + 12, at), _mm256_loadu2_m128(at + 15, at + 3),
                 _mm256_loadu2_m128(at + 18, at + 6), _mm256_loadu2_m128(at + 21, at + 9));
  return {t.t[0], t.t[1], t.t[2]};
}
// The eight vertices back as 24 consecutive floats.
TANDEM_AVX2_INLINE void store_soa8(float* at, const Soa8& s) {
  // Per half: x0 y0 z0 x1 | y1 z1 x2 y2 | z2 x3 y3 z3 of its four vertices.
  const __m256 xy01 = _mm256_unpacklo_ps(s.x, s.y), xy23 = _mm256_unpackhi_ps(s.x, s.y);
  const __m256 z0_x1 = _mm256_shuffle_ps(s.z, s.x, _MM_SHUFFLE(1, 1, 0, 0));
  const __m256 y1_z1 = _mm256_shuffle_ps(xy01, s.z, _MM_SHUFFLE(1, 1, 3, 3));
  const __m256 z2_x3_y3 = _mm256_shuffle_ps(s.z, xy23, _MM_SHUFFLE(3, 2, 2, 2));
  const __m256 y3_z3 = _mm256_shuffle_ps(xy23, s.z, _MM_SHUFFLE(3, 3, 3, 3));
  const __m256 a = _mm256_shuffle_ps(xy01, z0_x1, _MM_SHUFFLE(2, 0, 1, 0));
  const __m256 b = _mm256_shuffle_ps(y1_z1, xy23, _MM_SHUFFLE(1, 0, 2, 0));
  const __m256 c = _mm256_shuffle_ps(z2_x3_y3, y3_z3, _MM_SHUFFLE(2, 1, 2, 0));
  _mm256_storeu_ps(at, _mm256_permute2f128_ps(a, b, 0x20));
  _mm256_storeu_ps(at + 8, _mm256_permute2f128_ps(c, a, 0x30));
  _mm256_storeu_ps(at + 16, _mm256_permute2f128_ps(b, c, 0x31));
}
// a * x + b * y + c * z, summed in that order.
TANDEM_AVX2_INLINE __m256 combine8(__m256 a, __m256 x, __m256 b, __m256 y, __m256 c, __m256 z) {
  return _mm256_add_ps(_mm256_add_ps(_mm256_mul_ps(a, x), _mm256_mul_ps(b, y)),
                       _mm256_mul_ps(c, z));
}
TANDEM_AVX2_INLINE __m256 add3_8(__m256 a, __m256 b, __m256 c) {
  return _mm256_add_ps(_mm256_add_ps(a, b), c);
}
// cross(v4, v4)'s products and differences, a coordinate a register.
TANDEM_AVX2_INLINE Soa8 cross8(const Soa8& a, const Soa8& b) {
  return {_mm256_sub_ps(_mm256_mul_ps(a.y, b.z), _mm256_mul_ps(a.z, b.y)),
          _mm256_sub_ps(_mm256_mul_ps(a.z, b.x), _mm256_mul_ps(a.x, b.z)),
          _mm256_sub_ps(_mm256_mul_ps(a.x, b.y), _mm256_mul_ps(a.y, b.x))};
}
// One influence of the blend: rows += weight * the joint's rows.
template <int kInfluence>
TANDEM_AVX2_INLINE void blend_influence8(__m256 weights, const JointMatrix& lo,
                                         const JointMatrix& hi, __m256 rows[3]) {
  const __m256 w =
      _mm256_permute_ps(weights, _MM_SHUFFLE(kInfluence, kInfluence, kInfluence, kInfluence));
  for (int r = 0; r < 3; ++r) {
    rows[r] =
        _mm256_add_ps(rows[r], _mm256_mul_ps(w, _mm256_loadu2_m128(hi.m + 4 * r, lo.m + 4 * r)));
  }
}

// The blend of vertices v..v + 7, each from its own joints' rows.
TANDEM_AVX2_INLINE void blend_gathered8(const MeshDeformation& d, const JointMatrix* palette,
                                        size_t v, Soa8 c[4]) {
  __m256 rows[4][3];  // [pair k: vertices v + k and v + 4 + k][row]
  for (int k = 0; k < 4; ++k) {
    const size_t a = v + size_t(k), b = a + 4;
    const uint16_t* ja = &d.joints[4 * a];
    const uint16_t* jb = &d.joints[4 * b];
    const __m256 w = _mm256_loadu2_m128(&d.weights[4 * b], &d.weights[4 * a]);
    rows[k][0] = rows[k][1] = rows[k][2] = _mm256_setzero_ps();
    blend_influence8<0>(w, palette[ja[0]], palette[jb[0]], rows[k]);
    blend_influence8<1>(w, palette[ja[1]], palette[jb[1]], rows[k]);
    blend_influence8<2>(w, palette[ja[2]], palette[jb[2]], rows[k]);
    blend_influence8<3>(w, palette[ja[3]], palette[jb[3]], rows[k]);
  }
  // Row r of the eight matrices, transposed: element (r, j) of column j.
  for (int r = 0; r < 3; ++r) {
    const Transposed8 t = transpose8(rows[0][r], rows[1][r], rows[2][r], rows[3][r]);
    for (int j = 0; j < 4; ++j)
      (r == 0 ? c[j].x : r == 1 ? c[j].y : c[j].z) = t.t[j];
  }
}
// Whether eight vertices (their 4 x 8 joint indices at `joints`) have the
// same four joints in the same order: almost every group of the generated
// grid; a real skin's only where its file numbers neighbouring vertices
// together and lists their joints alike (RiggedFigure: none).
TANDEM_AVX2_INLINE bool same_joints8(const uint16_t* joints) {
  int64_t first;
  std::memcpy(&first, joints, sizeof first);
  const __m256i f = _mm256_set1_epi64x(first);
  const __m256i a = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(joints));
  const __m256i b = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(joints + 16));
  const __m256i eq = _mm256_and_si256(_mm256_cmpeq_epi64(a, f), _mm256_cmpeq_epi64(b, f));
  return _mm256_movemask_epi8(eq) == -1;
}
// The blend of eight vertices that share their joints: each matrix element
// a register, the joint's element broadcast and the eight weights a vertex
// a lane (one transpose of the weights, none of the matrices): about 60 %
// of blend_gathered8()'s operations. The same sums lane by lane (from +0,
// influences in order, multiply then add).
TANDEM_AVX2_INLINE void blend_shared_joints8(const float* w, const JointMatrix* palette,
                                             const uint16_t* joints, Soa8 c[4]) {
  // Weight i of vertices 0..3 in the low half, 4..7 in the high.
  const Transposed8 wt =
      transpose8(_mm256_loadu2_m128(w + 16, w), _mm256_loadu2_m128(w + 20, w + 4),
                 _mm256_loadu2_m128(w + 24, w + 8), _mm256_loadu2_m128(w + 28, w + 12));
  const float* m[4] = {palette[joints[0]].m, palette[joints[1]].m, palette[joints[2]].m,
                       palette[joints[3]].m};
  for (int j = 0; j < 4; ++j) {
    __m256 x = _mm256_setzero_ps(), y = x, z = x;
    for (int i = 0; i < 4; ++i) {
      x = _mm256_add_ps(x, _mm256_mul_ps(wt.t[i], _mm256_broadcast_ss(m[i] + j)));
      y = _mm256_add_ps(y, _mm256_mul_ps(wt.t[i], _mm256_broadcast_ss(m[i] + 4 + j)));
      z = _mm256_add_ps(z, _mm256_mul_ps(wt.t[i], _mm256_broadcast_ss(m[i] + 8 + j)));
    }
    c[j] = {x, y, z};
  }
}

TANDEM_TARGET_AVX2 __attribute__((flatten)) void skin4_normals_block_avx2(const Job& job,
                                                                          size_t begin, size_t end,
                                                                          BlockBox* box) {
  const MeshDeformation& d = job.d;
  const JointMatrix* palette = job.rows;
  // The box of the positions, lane by lane from the registers (grow_box()'s
  // minimum, maximum and x - x sum; the order of a minimum does not matter
  // but for the sign of a zero, which the caller's box makes positive).
  Soa8 lo{_mm256_set1_ps(kInf), _mm256_set1_ps(kInf), _mm256_set1_ps(kInf)};
  Soa8 hi{_mm256_set1_ps(-kInf), _mm256_set1_ps(-kInf), _mm256_set1_ps(-kInf)};
  __m256 bad = _mm256_setzero_ps();
  // Groups whose 16-byte loads of the eighth vertex stay inside the arrays.
  const size_t last = d.vertex_count() - 1;
  size_t v = begin;
  for (; v + 8 <= end && v + 8 <= last; v += 8) {
    // c[j]: column j of the eight blended matrices, a vertex a lane.
    Soa8 c[4];
    if (same_joints8(&d.joints[4 * v])) {
      blend_shared_joints8(&d.weights[4 * v], palette, &d.joints[4 * v], c);
    } else {
      blend_gathered8(d, palette, v, c);
    }
    const Soa8 p = load_soa8(&d.base_positions[v].x);
    const Soa8 n = load_soa8(&d.base_normals[v].x);
    const Soa8 sp{_mm256_add_ps(combine8(c[0].x, p.x, c[1].x, p.y, c[2].x, p.z), c[3].x),
                  _mm256_add_ps(combine8(c[0].y, p.x, c[1].y, p.y, c[2].y, p.z), c[3].y),
                  _mm256_add_ps(combine8(c[0].z, p.x, c[1].z, p.y, c[2].z, p.z), c[3].z)};
    if (job.out_positions != nullptr) store_soa8(&job.out_positions[v].x, sp);
    if (job.kernel_positions != nullptr) store_soa8(&job.kernel_positions[v].x, sp);
    if (box != nullptr) {
      lo = {_mm256_min_ps(sp.x, lo.x), _mm256_min_ps(sp.y, lo.y), _mm256_min_ps(sp.z, lo.z)};
      hi = {_mm256_max_ps(sp.x, hi.x), _mm256_max_ps(sp.y, hi.y), _mm256_max_ps(sp.z, hi.z)};
      bad = _mm256_add_ps(bad, add3_8(_mm256_sub_ps(sp.x, sp.x), _mm256_sub_ps(sp.y, sp.y),
                                      _mm256_sub_ps(sp.z, sp.z)));
    }
    // The cofactor columns, the determinant's sign, the skinned normal.
    const Soa8 k0 = cross8(c[1], c[2]), k1 = cross8(c[2], c[0]), k2 = cross8(c[0], c[1]);
    const __m256 det = combine8(c[0].x, k0.x, c[0].y, k0.y, c[0].z, k0.z);
    const __m256 sign = _mm256_blendv_ps(_mm256_set1_ps(1.0f), _mm256_set1_ps(-1.0f),
                                         _mm256_cmp_ps(det, _mm256_setzero_ps(), _CMP_LT_OQ));
    const Soa8 sn{_mm256_mul_ps(sign, combine8(k0.x, n.x, k1.x, n.y, k2.x, n.z)),
                  _mm256_mul_ps(sign, combine8(k0.y, n.x, k1.y, n.y, k2.y, n.z)),
                  _mm256_mul_ps(sign, combine8(k0.z, n.x, k1.z, n.y, k2.z, n.z))};
    // normalise_block(): the estimate, one Newton step, the base normal
    // where the length is zero, huge or NaN.
    const __m256 len2 = combine8(sn.x, sn.x, sn.y, sn.y, sn.z, sn.z);
    const __m256 r = _mm256_rsqrt_ps(len2);
    const __m256 inv = _mm256_mul_ps(
        r, _mm256_sub_ps(
               _mm256_set1_ps(1.5f),
               _mm256_mul_ps(_mm256_mul_ps(_mm256_mul_ps(_mm256_set1_ps(0.5f), len2), r), r)));
    const __m256 ok = _mm256_and_ps(_mm256_cmp_ps(len2, _mm256_set1_ps(1e-30f), _CMP_GT_OQ),
                                    _mm256_cmp_ps(len2, _mm256_set1_ps(1e30f), _CMP_LT_OQ));
    const Soa8 un{_mm256_blendv_ps(n.x, _mm256_mul_ps(sn.x, inv), ok),
                  _mm256_blendv_ps(n.y, _mm256_mul_ps(sn.y, inv), ok),
                  _mm256_blendv_ps(n.z, _mm256_mul_ps(sn.z, inv), ok)};
    if (job.out_normals != nullptr) store_soa8(&job.out_normals[v].x, un);
    if (job.kernel_normals != nullptr) store_soa8(&job.kernel_normals[v].x, un);
  }
  if (box != nullptr) {
    alignas(32) float l[3][8], h[3][8], n[8];
    _mm256_store_ps(l[0], lo.x), _mm256_store_ps(l[1], lo.y), _mm256_store_ps(l[2], lo.z);
    _mm256_store_ps(h[0], hi.x), _mm256_store_ps(h[1], hi.y), _mm256_store_ps(h[2], hi.z);
    _mm256_store_ps(n, bad);
    BlockBox lanes = kEmptyBox;
    for (int k = 0; k < 8; ++k) {
      join_box(lanes, {{l[0][k], l[1][k], l[2][k]}, {h[0][k], h[1][k], h[2][k]}, n[k] == 0.0f});
    }
    join_box(*box, lanes);
  }
  // The rest one vertex at a time (still AVX2's encoding: flatten).
  deform_block<true, false, true, false, 4>(job, v, end, box);
  normalise_block(job, v, end);
}
#undef TANDEM_AVX2_INLINE
#endif

template <bool kSkin, bool kMorph, bool kNormals, bool kTangents, uint32_t kInfluences = 0>
void deform_and_normalise_block(const Job& job, size_t begin, size_t end, BlockBox* box) {
  deform_block<kSkin, kMorph, kNormals, kTangents, kInfluences>(job, begin, end, box);
  normalise_block(job, begin, end);
}

// A block of vertices [begin, end); with `box` (only when writing the
// kernel arrays), the box of their positions added to it.
using BlockFn = void (*)(const Job&, size_t, size_t, BlockBox*);

template <bool kSkin, bool kMorph>
BlockFn pick(bool normals, bool tangents, uint32_t influences) {
  if (normals && kSkin && !kMorph) {
    if (influences == 4) {
#if TANDEM_HOST_AVX2
      if (!tangents && deform_isa.avx2) return &skin4_normals_block_avx2;
#endif
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

// deform_mesh() into `out` (when not null) and into `kernel` (when not
// null: then also returning their box in `box`); false when nothing was
// written or a position is not finite. With both, the attributes written
// are those `out` has.
bool deform_into(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh* out, const MeshVertexTarget* kernel, SceneBounds* box) {
  const size_t vertices = d.vertex_count();
  bool normals = false, tangents = false;
  if (out != nullptr) {
    if (out->positions.size() != vertices) return false;  // not the mesh it was made for
    normals = !d.base_normals.empty() && out->normals.size() == vertices;
    tangents = !d.base_tangents.empty() && out->tangents.size() == vertices;
  } else if (kernel != nullptr) {
    if (kernel->vertex_count != vertices || kernel->positions == nullptr) return false;
    normals = !d.base_normals.empty() && kernel->normals != nullptr;
    tangents = !d.base_tangents.empty() && kernel->tangents != nullptr;
  } else {
    return false;
  }
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
          skinned ? palette : nullptr,
          active,
          !d.position_deltas.empty(),
          normals && !d.normal_deltas.empty(),
          tangents && !d.tangent_deltas.empty()};
  if (out != nullptr) {
    job.out_positions = out->positions.data();
    job.out_normals = normals ? out->normals.data() : nullptr;
    job.out_tangents = tangents ? out->tangents.data() : nullptr;
  }
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
    tbb::parallel_for(
        tbb::blocked_range<size_t>(0, vertices, kBlock),
        [&](const tbb::blocked_range<size_t>& r) { fn(job, r.begin(), r.end(), nullptr); });
    return true;
  }
  // The box of each block, taken while its positions are still in the
  // cache (or in registers): the compiler, which no longer reads them,
  // would have taken it.
  const BlockBox all = tbb::parallel_reduce(
      tbb::blocked_range<size_t>(0, vertices, kBlock), kEmptyBox,
      [&](const tbb::blocked_range<size_t>& r, BlockBox acc) {
        fn(job, r.begin(), r.end(), &acc);
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

// A pose of one deformation: what the Scene holds for the mesh until the
// compiler writes it into the kernel arrays or something reads the Scene's
// copy. It holds the deformation, so the animator may go first.
class DeformedMeshPose final : public MeshPose {
 public:
  DeformedMeshPose(std::shared_ptr<const MeshDeformation> d, const JointMatrix* palette,
                   const float* morph_weights)
      : d_(std::move(d)) {
    if (d_->skinned() && palette != nullptr) palette_.assign(palette, palette + d_->palette_size);
    if (morph_weights != nullptr) morph_weights_.assign(morph_weights, morph_weights + d_->targets);
  }
  size_t vertex_count() const override { return d_->vertex_count(); }
  void write(Mesh& out) const override {
    deform_into(*d_, palette(), weights(), &out, nullptr, nullptr);
  }
  bool write(const MeshVertexTarget& target, SceneBounds* box) const override {
    return deform_into(*d_, palette(), weights(), nullptr, &target, box);
  }

 private:
  const JointMatrix* palette() const { return palette_.empty() ? nullptr : palette_.data(); }
  const float* weights() const { return morph_weights_.empty() ? nullptr : morph_weights_.data(); }
  std::shared_ptr<const MeshDeformation> d_;
  std::vector<JointMatrix> palette_;  // empty: not skinned
  std::vector<float> morph_weights_;  // empty: none given
};

// The DeformedPose check, then the pose: given to the Scene as a pose
// (Scene::pose_mesh) with `shared`, else written through
// Scene::edit_mesh_vertices.
bool write_new_pose(const MeshDeformation& d, const std::shared_ptr<const MeshDeformation>* shared,
                    const JointMatrix* palette, const float* morph_weights, Scene& scene,
                    DeformedPose& last) {
  if (d.mesh >= scene.mesh_count()) return false;
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
  if (shared != nullptr && d.vertex_count() == scene.mesh_vertex_count(d.mesh)) {
    scene.pose_mesh(d.mesh, std::make_shared<DeformedMeshPose>(*shared, palette, morph_weights));
  } else {
    deform_mesh(d, palette, morph_weights, scene.edit_mesh_vertices(d.mesh));
  }
  last.palette.assign(palette, palette + joints);
  last.morph_weights.assign(morph_weights, morph_weights + targets);
  last.vertex_version = scene.mesh_vertex_version(d.mesh);
  return true;
}

}  // namespace

void deform_mesh(const MeshDeformation& d, const JointMatrix* palette, const float* morph_weights,
                 Mesh& out) {
  deform_into(d, palette, morph_weights, &out, nullptr, nullptr);
}

bool deform_scene_mesh(const MeshDeformation& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, DeformedPose& last) {
  return write_new_pose(d, nullptr, palette, morph_weights, scene, last);
}

bool deform_scene_mesh(const std::shared_ptr<const MeshDeformation>& d, const JointMatrix* palette,
                       const float* morph_weights, Scene& scene, DeformedPose& last) {
  if (d == nullptr) return false;
  return write_new_pose(*d, &d, palette, morph_weights, scene, last);
}

}  // namespace tandem
