#include "core/render/svgf_cpu_rows.h"

#if TANDEM_SVGF_HAVE_AVX2

#include <immintrin.h>

namespace tandem::svgf_cpu_detail {

namespace {

TANDEM_SVGF_AVX2 inline __m256 avx2_exp_neg(__m256 x) {
  const __m256 y =
      _mm256_max_ps(_mm256_mul_ps(x, _mm256_set1_ps(1.44269504f)), _mm256_set1_ps(-126.0f));
  const __m256 in_range = _mm256_cmp_ps(y, _mm256_set1_ps(-126.0f), _CMP_GT_OQ);
  const __m256 nf = _mm256_floor_ps(y);
  const __m256 g = _mm256_sub_ps(_mm256_sub_ps(y, nf), _mm256_set1_ps(0.5f));
  __m256 p = _mm256_fmadd_ps(g, _mm256_set1_ps(0.00133335581f), _mm256_set1_ps(0.00961812911f));
  p = _mm256_fmadd_ps(g, p, _mm256_set1_ps(0.0555041087f));
  p = _mm256_fmadd_ps(g, p, _mm256_set1_ps(0.240226507f));
  p = _mm256_fmadd_ps(g, p, _mm256_set1_ps(0.693147182f));
  p = _mm256_fmadd_ps(g, p, _mm256_set1_ps(1.0f));
  p = _mm256_mul_ps(_mm256_set1_ps(1.41421356f), p);
  const __m256i bits =
      _mm256_slli_epi32(_mm256_add_epi32(_mm256_cvttps_epi32(nf), _mm256_set1_epi32(127)), 23);
  return _mm256_mul_ps(_mm256_and_ps(in_range, p), _mm256_castsi256_ps(bits));
}

// An index the compiler cannot see as affine in the loop variable: it then
// addresses every plane through it instead of making an induction
// variable per plane and tap.
inline ptrdiff_t avx2_opaque(ptrdiff_t j) {
  asm("" : "+r"(j));
  return j;
}

}  // namespace

// The 3x3 a-trous iteration over the interior run [x0, x1) of row y, 8
// pixels a vector, written with AVX2 intrinsics: the same arithmetic as
// svgf_atrous_pixel_core<kSvgfUnchecked, 1> (same taps in the same order,
// the same exp polynomial), so it differs from the generic clone only in
// float rounding. What GCC made of the generic body spent a quarter of
// its instructions on spills and pointer reloads: it strength-reduces
// each of the 9 planes x 9 taps into an address register of its own.
// Here each tap's index is computed once (and hidden from that
// transformation) and the 9 plane pointers stay in registers; the centre's
// miss flag is folded into its per-pixel constants, and the normal stop's
// sigma too. About half the instructions per pixel (profile in
// docs/performance/log/denoiser.md). The remainder (< 8 pixels)
// goes through the generic pixel function.
TANDEM_SVGF_AVX2 void svgf_atrous_interior_r1_avx2(const SvgfParams& params,
                                                   const SvgfAtrousPlanes& in, uint32_t step, int y,
                                                   int x0, int x1, const IllumPlanes& out) {
  const SvgfParams p = params;
  const SvgfAtrousPlanes ab = in;
  const IllumPlanes o = out;
  const float* const nxp = ab.guide.normal_x;
  const float* const nyp = ab.guide.normal_y;
  const float* const nzp = ab.guide.normal_z;
  const float* const dp = ab.guide.depth;
  const int* const mp = reinterpret_cast<const int*>(ab.guide.material);
  const float* const rp = ab.r;
  const float* const gp = ab.g;
  const float* const bp = ab.b;
  const float* const vp = ab.var;
  const float* const slope = reinterpret_cast<const float*>(ab.guide.depth_slope);
  const ptrdiff_t w = ptrdiff_t(p.width), s = ptrdiff_t(step);
  const ptrdiff_t row = ptrdiff_t(y) * w;
  // Tap offsets in the order of the generic loop (ky outer, kx inner).
  const ptrdiff_t off[8] = {-s * w - s, -s * w, -s * w + s, -s, s, s * w - s, s * w, s * w + s};
  // Kernel weight tap_x * tap_y of each tap, and which inv_exp it uses
  // (0: |kx| = 1, ky = 0; 1: kx = 0, |ky| = 1; 2: both 1).
  const float kw[8] = {0.0625f, 0.125f, 0.0625f, 0.125f, 0.125f, 0.0625f, 0.125f, 0.0625f};
  const int which[8] = {2, 1, 2, 0, 0, 2, 1, 2};
  const __m256 abs_mask = _mm256_castsi256_ps(_mm256_set1_epi32(0x7fffffff));
  const __m256 one = _mm256_set1_ps(1.0f), zero = _mm256_setzero_ps();
  const __m256 lw_r = _mm256_set1_ps(0.2126f), lw_g = _mm256_set1_ps(0.7152f),
               lw_b = _mm256_set1_ps(0.0722f);
  const __m256 sigma_n = _mm256_set1_ps(p.sigma_normal);
  const __m256 sigma_d = _mm256_set1_ps(p.sigma_depth);
  const __m256 sigma_l = _mm256_set1_ps(p.sigma_luminance);
  const __m256 fs = _mm256_set1_ps(float(s));
  const __m256i invalid = _mm256_set1_epi32(int(kInvalidIndex));
  int x = x0;
  for (; x + 8 <= x1; x += 8) {
    const ptrdiff_t i = row + x;
    const __m256 cnx = _mm256_loadu_ps(nxp + i), cny = _mm256_loadu_ps(nyp + i),
                 cnz = _mm256_loadu_ps(nzp + i), cd = _mm256_loadu_ps(dp + i);
    const __m256i cm = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(mp + i));
    const __m256 hit = _mm256_andnot_ps(_mm256_castsi256_ps(_mm256_cmpeq_epi32(cm, invalid)), one);
    // The slopes (x, y records) of the 8 pixels, de-interleaved.
    const __m256 s_lo = _mm256_loadu_ps(slope + 2 * i), s_hi = _mm256_loadu_ps(slope + 2 * i + 8);
    const __m256 sxy_x = _mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(s_lo, s_hi, _MM_SHUFFLE(2, 0, 2, 0))), 0xd8));
    const __m256 sxy_y = _mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(s_lo, s_hi, _MM_SHUFFLE(3, 1, 3, 1))), 0xd8));
    const __m256 sx = _mm256_mul_ps(sigma_d, sxy_x), sy = _mm256_mul_ps(sigma_d, sxy_y);
    const __m256 floor_depth =
        _mm256_add_ps(_mm256_mul_ps(_mm256_set1_ps(1e-3f), cd), _mm256_set1_ps(1e-8f));
    // inv_exp [1][0], [0][1], [1][1] of the generic code, times the miss flag.
    const __m256 ax = _mm256_mul_ps(sx, fs), ay = _mm256_mul_ps(sy, fs);
    __m256 inv[3];
    inv[0] = _mm256_mul_ps(_mm256_div_ps(one, _mm256_add_ps(ax, floor_depth)), hit);
    inv[1] = _mm256_mul_ps(_mm256_div_ps(one, _mm256_add_ps(ay, floor_depth)), hit);
    inv[2] =
        _mm256_mul_ps(_mm256_div_ps(one, _mm256_add_ps(_mm256_add_ps(ax, ay), floor_depth)), hit);
    const __m256 sn = _mm256_mul_ps(sigma_n, hit);
    const __m256 cr = _mm256_loadu_ps(rp + i), cg = _mm256_loadu_ps(gp + i),
                 cb = _mm256_loadu_ps(bp + i), cv = _mm256_loadu_ps(vp + i);
    const __m256 lum_c =
        _mm256_fmadd_ps(lw_b, cb, _mm256_fmadd_ps(lw_g, cg, _mm256_mul_ps(lw_r, cr)));
    // The 3x3 blur of the variance (weights 1/16, 1/8, 1/4; they sum to 1).
    __m256 vb = zero;
    for (int dy = -1; dy <= 1; ++dy) {
      for (int dx = -1; dx <= 1; ++dx) {
        const float k = (dx == 0 ? 0.5f : 0.25f) * (dy == 0 ? 0.5f : 0.25f);
        vb = _mm256_fmadd_ps(_mm256_loadu_ps(vp + i + dy * w + dx), _mm256_set1_ps(k), vb);
      }
    }
    const __m256 lum_scale = _mm256_div_ps(
        one,
        _mm256_fmadd_ps(sigma_l, _mm256_sqrt_ps(_mm256_max_ps(vb, zero)), _mm256_set1_ps(1e-10f)));
    __m256 sr = _mm256_mul_ps(cr, _mm256_set1_ps(0.25f));
    __m256 sg = _mm256_mul_ps(cg, _mm256_set1_ps(0.25f));
    __m256 sb = _mm256_mul_ps(cb, _mm256_set1_ps(0.25f));
    __m256 svar = _mm256_mul_ps(cv, _mm256_set1_ps(0.0625f));
    __m256 wsum = _mm256_set1_ps(0.25f);
    TANDEM_SVGF_UNROLL
    for (int t = 0; t < 8; ++t) {
      const ptrdiff_t j = avx2_opaque(i + off[t]);
      const __m256 qr = _mm256_loadu_ps(rp + j), qg = _mm256_loadu_ps(gp + j),
                   qb = _mm256_loadu_ps(bp + j);
      const __m256 lum_q =
          _mm256_fmadd_ps(lw_b, qb, _mm256_fmadd_ps(lw_g, qg, _mm256_mul_ps(lw_r, qr)));
      const __m256 lum_term =
          _mm256_mul_ps(_mm256_and_ps(_mm256_sub_ps(lum_q, lum_c), abs_mask), lum_scale);
      const __m256 dz = _mm256_and_ps(_mm256_sub_ps(cd, _mm256_loadu_ps(dp + j)), abs_mask);
      __m256 dot = _mm256_mul_ps(cnx, _mm256_loadu_ps(nxp + j));
      dot = _mm256_fmadd_ps(cny, _mm256_loadu_ps(nyp + j), dot);
      dot = _mm256_fmadd_ps(cnz, _mm256_loadu_ps(nzp + j), dot);
      const __m256 geo =
          _mm256_fmadd_ps(dz, inv[which[t]], _mm256_mul_ps(sn, _mm256_sub_ps(one, dot)));
      const __m256 same = _mm256_castsi256_ps(
          _mm256_cmpeq_epi32(_mm256_loadu_si256(reinterpret_cast<const __m256i*>(mp + j)), cm));
      const __m256 e =
          _mm256_and_ps(same, avx2_exp_neg(_mm256_sub_ps(zero, _mm256_add_ps(geo, lum_term))));
      const __m256 hw = _mm256_mul_ps(_mm256_set1_ps(kw[t]), e);
      sr = _mm256_fmadd_ps(qr, hw, sr);
      sg = _mm256_fmadd_ps(qg, hw, sg);
      sb = _mm256_fmadd_ps(qb, hw, sb);
      svar = _mm256_fmadd_ps(_mm256_mul_ps(_mm256_loadu_ps(vp + j), hw), hw, svar);
      wsum = _mm256_add_ps(wsum, hw);
    }
    const __m256 winv = _mm256_div_ps(one, wsum);
    _mm256_storeu_ps(o.r + i, _mm256_mul_ps(sr, winv));
    _mm256_storeu_ps(o.g + i, _mm256_mul_ps(sg, winv));
    _mm256_storeu_ps(o.b + i, _mm256_mul_ps(sb, winv));
    _mm256_storeu_ps(o.var + i, _mm256_mul_ps(_mm256_mul_ps(svar, winv), winv));
  }
  for (; x < x1; ++x)
    store(o, size_t(row + x), svgf_atrous_pixel_r<false, 1>(p, ab, step, x, y));
}

}  // namespace tandem::svgf_cpu_detail

#endif
