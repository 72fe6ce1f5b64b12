// Environment lighting: a constant colour or an equirectangular HDR map,
// importance sampled in proportion to what the lookup returns: a texel by
// the mean luminance of the bilinear lookup over it * sin(theta) (a
// piecewise-constant 2D distribution), the point inside it by the lookup's
// luminance there. A sun of a few texels is then as clean as a soft one.
#pragma once

#include "core/kernel/kernel_data.h"
#include "core/kernel/sampling.h"

namespace tandem {
TANDEM_KERNEL_BEGIN

// d turned about +y by the angle whose cosine and sine are c and s.
TANDEM_HD Vec3 rotate_y_cs(Vec3 d, float c, float s) {
  return {c * d.x + s * d.z, d.y, -s * d.x + c * d.z};
}

TANDEM_HD Vec3 rotate_y(Vec3 d, float angle) {
  const SinCos sc = sincos_pi(angle * kInvPi);
  return rotate_y_cs(d, sc.cos, sc.sin);
}

// Sets the environment's rotation (radians about +y) and the cosine and
// sine the kernels turn by, those of rotate_y(d, radians).
TANDEM_HD void set_environment_rotation(KEnvironment& env, float radians) {
  const SinCos sc = sincos_pi(radians * kInvPi);
  env.rotation = radians;
  env.rotation_cos = sc.cos;
  env.rotation_sin = sc.sin;
}

TANDEM_HD Vec3 env_texel(const KernelData& kd, uint32_t x, uint32_t y) {
  return xyz(kd.env_texels[y * kd.constants.environment.width + x]);
}

// Unnormalised density of texel (x, y): the distribution the sampler follows.
// Shared with the host-side table builder so both use identical numbers.
//
// Its luminance is the mean over the texel of what env_radiance_at returns
// there, not the texel's own value: the lookup is bilinear between texel
// centres, so a texel next to a small bright source (an HDRI's sun) returns
// up to half of it near their shared edge. Weighted by its own value alone
// such a texel was almost never sampled yet bright when hit, and the ratio
// of the two left speckles at any sample count. The mean of the bilinear
// function over [x, x + 1] is 3/4 of the texel's value and 1/8 of each
// neighbour's, per axis (wrapping in x and clamped at the poles, as the
// lookup is); env_sample then places the point inside the texel by the
// lookup itself (env_pdf_uv_at), so radiance / pdf is nearly constant.
TANDEM_HD float env_texel_weight(const KernelData& kd, uint32_t x, uint32_t y) {
  const KEnvironment& env = kd.constants.environment;
  const uint32_t w = env.width, h = env.height;
  const uint32_t xs[3] = {x == 0 ? w - 1 : x - 1, x, x + 1 == w ? 0 : x + 1};
  const uint32_t ys[3] = {y == 0 ? 0 : y - 1, y, y + 1 == h ? y : y + 1};
  const float k[3] = {0.125f, 0.75f, 0.125f};
  float mean = 0.0f;
  for (int j = 0; j < 3; ++j) {
    float row = 0.0f;
    for (int i = 0; i < 3; ++i)
      row += k[i] * luminance(env_texel(kd, xs[i], ys[j]));
    mean += k[j] * row;
  }
  const float sin_theta = sin_pi((float(y) + 0.5f) / float(env.height));
  // A small floor keeps every direction reachable by light sampling
  // (kEnvLuminanceFloor, below).
  return (mean + 1e-4f) * sin_theta;
}

// The map coordinates of direction dir ((0, 0) without a map, where the
// _at functions below do not read them): two atan2f, a square root and a
// sincos, so a caller that needs both the radiance and the pdf of one
// direction (a path that missed) computes them once.
TANDEM_HD_INLINE Vec2 env_map_uv(const KernelData& kd, Vec3 dir) {
  const KEnvironment& env = kd.constants.environment;
  if (!env.has_map) return make_vec2(0.0f, 0.0f);
  // rotate_y(dir, -env.rotation), bit for bit: sincos_pi(-x) is (-sin, cos).
  return direction_to_equirect(rotate_y_cs(dir, env.rotation_cos, -env.rotation_sin));
}

// env_radiance at the map coordinates env_map_uv(kd, dir) (unused without
// a map): the same bits.
TANDEM_HD Vec3 env_radiance_at(const KernelData& kd, Vec2 uv) {
  const KEnvironment& env = kd.constants.environment;
  if (!env.has_map) return env.color;
  // Bilinear with horizontal wrap-around and clamped poles.
  const float x = uv.x * float(env.width) - 0.5f, y = uv.y * float(env.height) - 0.5f;
  const float x0f = floorf(x), y0f = floorf(y);
  const float tx = x - x0f, ty = y - y0f;
  const int w = int(env.width), h = int(env.height);
  // uv from env_map_uv puts x0f in [-1, w - 1]: there a compare gives the
  // remainder (an integer division was a tenth of a missed ray's shading).
  int x0 = int(x0f);
  if (x0 == -1) {
    x0 = w - 1;
  } else if (x0 < 0 || x0 >= w) {
    x0 %= w;
    if (x0 < 0) x0 += w;
  }
  const int x1 = x0 + 1 == w ? 0 : x0 + 1;
  const int y0 = int(clamp_f(y0f, 0.0f, float(h - 1))),
            y1 = int(clamp_f(y0f + 1.0f, 0.0f, float(h - 1)));
  const Vec3 c = env_texel(kd, uint32_t(x0), uint32_t(y0)) * ((1 - tx) * (1 - ty)) +
                 env_texel(kd, uint32_t(x1), uint32_t(y0)) * (tx * (1 - ty)) +
                 env_texel(kd, uint32_t(x0), uint32_t(y1)) * ((1 - tx) * ty) +
                 env_texel(kd, uint32_t(x1), uint32_t(y1)) * (tx * ty);
  return c * env.color;
}

TANDEM_HD Vec3 env_radiance(const KernelData& kd, Vec3 dir) {
  return env_radiance_at(kd, env_map_uv(kd, dir));
}

// The floor env_texel_weight adds to every texel's luminance.
constexpr float kEnvLuminanceFloor = 1e-4f;

// Position x in [0, 1] drawn from the density proportional to
// (1 - x) * a + x * b (a, b >= 0, not both 0) by u in [0, 1): the inverse
// of its CDF, in the form that stays finite when a and b are equal.
TANDEM_HD float sample_linear(float u, float a, float b) {
  const float x = u * (a + b) / (a + sqrtf((1.0f - u) * a * a + u * b * b));
  return x < 1.0f ? x : 0.99999994f;
}

// Texel (x, y)'s neighbours as the bilinear lookup takes them: wrapping in
// x, clamped at the poles in y.
struct EnvNeighbours {
  uint32_t xm, xp, ym, yp;
};
TANDEM_HD EnvNeighbours env_neighbours(const KEnvironment& env, uint32_t x, uint32_t y) {
  return {x == 0 ? env.width - 1 : x - 1, x + 1 == env.width ? 0 : x + 1, y == 0 ? 0 : y - 1,
          y + 1 == env.height ? y : y + 1};
}

TANDEM_HD float env_lum(const KernelData& kd, uint32_t x, uint32_t y) {
  return luminance(env_texel(kd, x, y)) + kEnvLuminanceFloor;
}

// Density over the map's unit square of env_sample's (u, v) inside texel
// (x, y): what the lookup's luminance (plus the floor) is there, times the
// texel's sin(theta), normalised. env_texel_weight is its mean over the
// texel, so choosing the texel by that weight and the point inside it by
// the lookup (env_sample) gives exactly this.
TANDEM_HD float env_pdf_uv_at(const KernelData& kd, Vec2 uv, uint32_t x, uint32_t y) {
  const KEnvironment& env = kd.constants.environment;
  // The luminance env_radiance_at returns at uv (luminance is linear, so
  // that of the bilinear mix is the mix of the texels' own).
  const float fx = uv.x * float(env.width) - float(x), fy = uv.y * float(env.height) - float(y);
  const EnvNeighbours n = env_neighbours(env, x, y);
  const uint32_t x1 = fx < 0.5f ? n.xm : n.xp, y1 = fy < 0.5f ? n.ym : n.yp;
  const float tx = fx < 0.5f ? 0.5f - fx : fx - 0.5f, ty = fy < 0.5f ? 0.5f - fy : fy - 0.5f;
  const float f = env_lum(kd, x, y) * ((1 - tx) * (1 - ty)) + env_lum(kd, x1, y) * (tx * (1 - ty)) +
                  env_lum(kd, x, y1) * ((1 - tx) * ty) + env_lum(kd, x1, y1) * (tx * ty);
  const float sin_theta = sin_pi((float(y) + 0.5f) / float(env.height));
  return f * sin_theta * float(env.width) * float(env.height) / env.map_integral;
}

// Binary search for u between cdf[lo] and cdf[hi] (a non-decreasing array
// of n + 1 entries; lo < hi <= n, cdf[lo] <= u unless lo is 0, cdf[hi] > u
// unless hi is n). For a non-decreasing array exactly one index i meets
// both bounds, so every bracket that holds it gives the same i.
TANDEM_HD uint32_t find_interval_between(const float* cdf, uint32_t lo, uint32_t hi, float u) {
  while (hi - lo > 1) {
    const uint32_t mid = (lo + hi) / 2;
    if (cdf[mid] <= u)
      lo = mid;
    else
      hi = mid;
  }
  return lo;
}

// Index i with cdf[i] <= u < cdf[i + 1] in an array of n + 1 entries.
TANDEM_HD uint32_t find_interval(const float* cdf, uint32_t n, float u) {
  return find_interval_between(cdf, 0, n, u);
}

// find_interval's index, from a bracket read in a guide table of n + 1
// entries (guide[k] = find_interval(cdf, n, k / n), guide[n] = n - 1): one
// or two search steps where find_interval takes log2(n), each a load the
// next depends on (a third of sampling the environment). The upper bound
// always holds: k = floor(u * n) < k + 1 means u < (k + 1) / n exactly
// (rounding is monotone), so u is at most the float nearest (k + 1) / n,
// where guide[k + 1] was searched. The lower one is checked: u * n can
// round up to k from below k / n; then the bracket starts at 0.
TANDEM_HD uint32_t find_interval_guided(const float* cdf, const uint32_t* guide, uint32_t n,
                                        float u) {
  const float s = u * float(n);
  const uint32_t k = s > 0.0f ? (s < float(n) ? uint32_t(s) : n - 1) : 0u;  // NaN: 0
  uint32_t lo = guide[k];
  const uint32_t hi = guide[k + 1] + 1;
  if (lo > 0 && !(cdf[lo] <= u)) lo = 0;
  return find_interval_between(cdf, lo, hi, u);
}

// Solid-angle pdf of env_sample returning dir, whose map coordinates are
// uv = env_map_uv(kd, dir) (unused without a map).
TANDEM_HD float env_pdf_at(const KernelData& kd, Vec3 dir, Vec2 uv) {
  const KEnvironment& env = kd.constants.environment;
  if (!env.has_map) return kInv4Pi;
  const uint32_t x = min_u(uint32_t(uv.x * float(env.width)), env.width - 1);
  const uint32_t y = min_u(uint32_t(uv.y * float(env.height)), env.height - 1);
  // Jacobian of the (u, v) -> direction map at the actual direction, with
  // sin(theta) taken from the direction itself (the rotation about +y keeps
  // it), not from v: float v near 1 is a multiple of 6e-8, which 5e-5 from
  // the pole is already a 1e-3 relative error in sin(theta); the
  // direction's components keep ~1e-7 relative all the way to the pole.
  const float sin_theta =
      sqrtf((dir.x * dir.x + dir.z * dir.z) / (dir.x * dir.x + dir.y * dir.y + dir.z * dir.z));
  if (!(sin_theta > 0.0f) || !(env.map_integral > 0.0f)) return 0.0f;
  return env_pdf_uv_at(kd, uv, x, y) / (2.0f * kPi * kPi * sin_theta);
}

// Solid-angle pdf of env_sample returning dir.
TANDEM_HD float env_pdf(const KernelData& kd, Vec3 dir) {
  return env_pdf_at(kd, dir, env_map_uv(kd, dir));
}

// Position in [0, 1) drawn by u from the density that is linear from
// `start` to `mid` on [0, 1/2] and from `mid` to `end` on [1/2, 1] (the
// lookup across a texel: its edges are half-way to the neighbours).
TANDEM_HD float env_sample_halves(float u, float start, float mid, float end) {
  const float first = start + mid, second = mid + end;  // twice each half's area
  const float p = first / (first + second);
  if (u < p) return 0.5f * sample_linear(p > 0.0f ? u / p : 0.0f, start, mid);
  const float rest = (u - p) / (1.0f - p);
  return 0.5f + 0.5f * sample_linear(rest < 1.0f ? rest : 0.99999994f, mid, end);
}

struct EnvSample {
  Vec3 dir;
  Vec3 radiance;
  float pdf;
};

TANDEM_HD EnvSample env_sample(const KernelData& kd, float u1, float u2) {
  const KEnvironment& env = kd.constants.environment;
  EnvSample s;
  if (!env.has_map) {
    s.dir = sample_uniform_sphere(u1, u2);
    s.radiance = env.color;
    s.pdf = kInv4Pi;
    return s;
  }
  const uint32_t y =
      find_interval_guided(kd.env_marginal_cdf, kd.env_marginal_guide, env.height, u1);
  const float* row = kd.env_conditional_cdf + y * (env.width + 1);
  const uint32_t* row_guide = kd.env_conditional_guide + y * (env.width + 1);
  const uint32_t x = find_interval_guided(row, row_guide, env.width, u2);
  // Continuous position inside the chosen texel (reuse the leftover of u).
  const float my0 = kd.env_marginal_cdf[y], my1 = kd.env_marginal_cdf[y + 1];
  const float mx0 = row[x], mx1 = row[x + 1];
  const float dy = saturate(my1 > my0 ? (u1 - my0) / (my1 - my0) : 0.5f);
  const float dx = saturate(mx1 > mx0 ? (u2 - mx0) / (mx1 - mx0) : 0.5f);
  // The point inside the texel follows the lookup's luminance there
  // (env_pdf_uv_at): piecewise bilinear between the texel's centre and its
  // neighbours'. First its row position t by the luminance averaged along
  // the row (linear in t on each half of the texel), then its column
  // position s along the row at t (linear on each half too).
  const EnvNeighbours n = env_neighbours(env, x, y);
  auto row_mean = [&](uint32_t r) {
    return 0.125f * env_lum(kd, n.xm, r) + 0.75f * env_lum(kd, x, r) +
           0.125f * env_lum(kd, n.xp, r);
  };
  const float m_up = row_mean(n.ym), m_mid = row_mean(y), m_down = row_mean(n.yp);
  const float t = env_sample_halves(dy, 0.5f * (m_up + m_mid), m_mid, 0.5f * (m_mid + m_down));
  // Rows r0 (the upper neighbour or this one) and r1 mixed at t.
  const uint32_t r0 = t < 0.5f ? n.ym : y, r1 = t < 0.5f ? y : n.yp;
  const float a = t < 0.5f ? t + 0.5f : t - 0.5f;
  auto at_t = [&](uint32_t c) { return (1 - a) * env_lum(kd, c, r0) + a * env_lum(kd, c, r1); };
  const float g_left = at_t(n.xm), g_mid = at_t(x), g_right = at_t(n.xp);
  const float sx = env_sample_halves(dx, 0.5f * (g_left + g_mid), g_mid, 0.5f * (g_mid + g_right));
  const float u = (float(x) + sx) / float(env.width);
  const float v = (float(y) + t) / float(env.height);
  s.dir = rotate_y_cs(equirect_to_direction(u, v), env.rotation_cos, env.rotation_sin);
  const float sin_theta = sin_pi(v);
  const float pdf_uv = env_pdf_uv_at(kd, make_vec2(u, v), x, y);
  s.pdf = sin_theta > 0.0f ? pdf_uv / (2.0f * kPi * kPi * sin_theta) : 0.0f;
  // At the sampled (u, v) itself, not at the coordinates of s.dir turned
  // back (a rotation, two arctangents and a square root to land within
  // 2e-7 of the same point).
  s.radiance = env_radiance_at(kd, make_vec2(u, v));
  return s;
}

TANDEM_KERNEL_END
}  // namespace tandem
