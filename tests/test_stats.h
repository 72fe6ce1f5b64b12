// Statistical helpers for the kernel sampling tests: Pearson's chi-square
// goodness-of-fit test with pooling of sparse cells, the chi-square survival
// function, a Sidak-corrected significance level, and adaptive cubature of a
// density over (theta, phi) cells of the sphere.
//
// The tests draw a fixed number of samples from a kernel sampler with a fixed
// seed, histogram them, and compare against the counts the sampler's claimed
// density predicts. A sampler whose pdf is wrong by a few percent anywhere
// that matters fails with overwhelming significance at 1e5 samples.
#pragma once

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdint>
#include <functional>
#include <numeric>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "core/kernel/math.h"
#include "core/kernel/rng.h"

namespace tandem::test_stats {

// Family-wise significance level of every group of statistical tests.
constexpr double kFamilySignificance = 1e-4;

// Per-test level so that `count` independent tests together reject a correct
// implementation with probability `family` (Sidak). Written with log1p/expm1
// because 1 - (1 - 1e-4)^(1/n) cancels badly in double.
inline double sidak_alpha(double family, int count) {
  return -std::expm1(std::log1p(-family) / double(std::max(count, 1)));
}

// Regularized upper incomplete gamma function Q(a, x) = Gamma(a, x) / Gamma(a).
// Below x = a + 1 the power series for P = 1 - Q converges fast; above it
// the continued fraction for Q does (evaluated with modified Lentz). The
// p-values we care about are tiny, which is the continued-fraction side, so
// no precision is lost to the 1 - P subtraction where it matters.
inline double regularized_gamma_q(double a, double x) {
  if (!(x > 0.0)) return 1.0;
  if (std::isinf(x)) return 0.0;
  const double log_prefactor = a * std::log(x) - x - std::lgamma(a);
  if (x < a + 1.0) {
    double term = 1.0 / a, sum = term;
    for (int n = 1; n < 100000; ++n) {
      term *= x / (a + double(n));
      sum += term;
      if (std::fabs(term) < std::fabs(sum) * 1e-17) break;
    }
    return std::clamp(1.0 - sum * std::exp(log_prefactor), 0.0, 1.0);
  }
  constexpr double kTiny = 1e-300;
  double b = x + 1.0 - a;
  double c = 1.0 / kTiny;
  double d = 1.0 / b;
  double h = d;
  for (int i = 1; i < 100000; ++i) {
    const double an = -double(i) * (double(i) - a);
    b += 2.0;
    d = an * d + b;
    if (std::fabs(d) < kTiny) d = kTiny;
    c = b + an / c;
    if (std::fabs(c) < kTiny) c = kTiny;
    d = 1.0 / d;
    const double delta = d * c;
    h *= delta;
    if (std::fabs(delta - 1.0) < 1e-16) break;
  }
  return std::clamp(std::exp(log_prefactor) * h, 0.0, 1.0);
}

// P(X >= x) for X ~ chi-square with `dof` degrees of freedom.
inline double chi2_survival(double x, double dof) {
  return regularized_gamma_q(0.5 * dof, 0.5 * x);
}

struct ChiSquareResult {
  double statistic = 0.0;
  int dof = 0;
  double p_value = 1.0;
  // Non-empty when the test failed outright: samples landed in a cell whose
  // expected count is zero, or the claimed density has mass > 1.
  std::string error;
  // The cells that contribute most to the statistic, for diagnosis.
  std::string worst_cells;

  bool passed(double alpha) const { return error.empty() && p_value >= alpha; }
  std::string summary() const {
    std::ostringstream s;
    s << "chi2=" << statistic << " dof=" << dof << " p=" << p_value;
    if (!error.empty()) s << " ERROR: " << error;
    s << " worst cells: " << worst_cells;
    return s.str();
  }
};

// Pearson's test of observed counts against expected counts (same total).
// Cells are sorted by expected count and the sparse ones (expected below
// `min_expected`, where the chi-square approximation breaks down) are pooled
// into one cell, which then absorbs the next cells until it is large enough.
// `label`, if given, names cells in the diagnostics.
inline ChiSquareResult chi_square_test(const std::vector<double>& observed,
                                       const std::vector<double>& expected,
                                       const std::function<std::string(size_t)>& label_fn = nullptr,
                                       double min_expected = 5.0) {
  ChiSquareResult r;
  const size_t n = observed.size();
  std::vector<size_t> order(n);
  std::iota(order.begin(), order.end(), size_t(0));
  std::sort(order.begin(), order.end(),
            [&](size_t a, size_t b) { return expected[a] < expected[b]; });
  auto label = [&](size_t i) { return label_fn ? label_fn(i) : "cell " + std::to_string(i); };

  double pool_obs = 0.0, pool_exp = 0.0;
  int cells = 0;
  std::vector<std::pair<double, size_t>> contributions;
  for (size_t i : order) {
    const double o = observed[i], e = expected[i];
    if (e < -1e-9 * double(n)) {
      r.error = label(i) + " has negative expected count " + std::to_string(e);
      return r;
    }
    if (!(e > 0.0)) {
      if (o > 0.0) {
        r.error = label(i) + " received " + std::to_string(o) + " samples but has expected count 0";
        return r;
      }
      continue;
    }
    if (e < min_expected || (pool_exp > 0.0 && pool_exp < min_expected)) {
      pool_obs += o;
      pool_exp += e;
      continue;
    }
    const double c = (o - e) * (o - e) / e;
    r.statistic += c;
    contributions.push_back({c, i});
    ++cells;
  }
  if (pool_exp > 0.0) {
    r.statistic += (pool_obs - pool_exp) * (pool_obs - pool_exp) / pool_exp;
    ++cells;
  }
  r.dof = cells - 1;
  r.p_value = r.dof > 0 ? chi2_survival(r.statistic, double(r.dof)) : 1.0;
  std::sort(contributions.rbegin(), contributions.rend());
  std::ostringstream w;
  for (size_t k = 0; k < std::min<size_t>(4, contributions.size()); ++k) {
    const size_t i = contributions[k].second;
    w << "[" << label(i) << ": obs " << observed[i] << " exp " << expected[i] << "] ";
  }
  if (pool_exp > 0.0) w << "[pool: obs " << pool_obs << " exp " << pool_exp << "]";
  r.worst_cells = w.str();
  return r;
}

// Deterministic uniform numbers in [0, 1) with the 24-bit resolution the
// kernel's own RNG has (u32_to_unit_float never returns 1).
struct TestRng {
  std::mt19937 gen;
  explicit TestRng(uint32_t seed) : gen(seed) {}
  float next() { return u32_to_unit_float(uint32_t(gen())); }
  double next_double() { return std::uniform_real_distribution<double>(0.0, 1.0)(gen); }
};

inline Vec3 spherical_direction(double theta, double phi) {
  const double s = std::sin(theta);
  return make_vec3(float(s * std::cos(phi)), float(s * std::sin(phi)), float(std::cos(theta)));
}

// 4-point Gauss-Legendre rule on [-1, 1].
constexpr double kGaussX[4] = {-0.86113631159405258, -0.33998104358485626, 0.33998104358485626,
                               0.86113631159405258};
constexpr double kGaussW[4] = {0.34785484513745386, 0.65214515486254614, 0.65214515486254614,
                               0.34785484513745386};

template <class F>
double gauss_rect(const F& f, double x0, double x1, double y0, double y1) {
  const double hx = 0.5 * (x1 - x0), hy = 0.5 * (y1 - y0);
  const double cx = 0.5 * (x0 + x1), cy = 0.5 * (y0 + y1);
  double sum = 0.0;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j)
      sum += kGaussW[i] * kGaussW[j] * f(cx + hx * kGaussX[i], cy + hy * kGaussX[j]);
  }
  return sum * hx * hy;
}

// Adaptive cubature of f over a rectangle: split in four until the children
// agree with their parent to `tol` (absolute). Sharp lobes and the
// discontinuities of piecewise-constant densities are what need refining.
constexpr int kMaxAdaptiveDepth = 8;
// Total-mass error of the cubature below which a density counts as
// normalised (see sphere_chi_square).
constexpr double kCubatureMassTolerance = 1e-3;

template <class F>
double adaptive_rect(const F& f, double x0, double x1, double y0, double y1, double coarse,
                     double tol, int depth) {
  const double xm = 0.5 * (x0 + x1), ym = 0.5 * (y0 + y1);
  const double q[4] = {gauss_rect(f, x0, xm, y0, ym), gauss_rect(f, xm, x1, y0, ym),
                       gauss_rect(f, x0, xm, ym, y1), gauss_rect(f, xm, x1, ym, y1)};
  const double fine = q[0] + q[1] + q[2] + q[3];
  if (depth <= 0 || std::fabs(fine - coarse) <= tol) return fine;
  return adaptive_rect(f, x0, xm, y0, ym, q[0], 0.5 * tol, depth - 1) +
         adaptive_rect(f, xm, x1, y0, ym, q[1], 0.5 * tol, depth - 1) +
         adaptive_rect(f, x0, xm, ym, y1, q[2], 0.5 * tol, depth - 1) +
         adaptive_rect(f, xm, x1, ym, y1, q[3], 0.5 * tol, depth - 1);
}

// Integral of a solid-angle density over the cell [t0, t1] x [p0, p1] in
// (theta, phi). `samples` sets the accuracy we need: the integration error
// must be far below the statistical error sqrt(p / samples) of the count.
template <class Pdf>
double integrate_cell(const Pdf& pdf, double t0, double t1, double p0, double p1, double samples) {
  auto f = [&](double theta, double phi) {
    return double(pdf(spherical_direction(theta, phi))) * std::sin(theta);
  };
  const double coarse = gauss_rect(f, t0, t1, p0, p1);
  const double tol = 0.01 * std::sqrt(std::max(std::fabs(coarse), 1.0 / samples) / samples);
  return adaptive_rect(f, t0, t1, p0, p1, coarse, tol, kMaxAdaptiveDepth);
}

// Chi-square tests over a rows x cols grid of cells followed by any number
// of extra cells (outside the grid, failed samples): the full 2D test and
// the two 1D marginals (the extra cells kept as they are). The fine 2D test
// dilutes a smooth, low-frequency error (a warp a few percent off across a
// whole hemisphere) over thousands of cells; the marginals concentrate it.
struct GridTestResult {
  ChiSquareResult full, row_marginal, col_marginal;

  // All three must pass (Sidak over the three).
  bool passed(double alpha) const {
    const double a = sidak_alpha(alpha, 3);
    return full.passed(a) && row_marginal.passed(a) && col_marginal.passed(a);
  }
  std::string summary() const {
    return "2D: " + full.summary() + "\nrow marginal: " + row_marginal.summary() +
           "\ncolumn marginal: " + col_marginal.summary();
  }
};

inline GridTestResult grid_chi_square(const std::vector<double>& observed,
                                      const std::vector<double>& expected, int rows, int cols,
                                      const std::function<std::string(size_t)>& label = nullptr) {
  const size_t cells = size_t(rows) * size_t(cols), extra = observed.size() - cells;
  std::vector<double> obs_r(rows + extra, 0.0), exp_r(rows + extra, 0.0);
  std::vector<double> obs_c(cols + extra, 0.0), exp_c(cols + extra, 0.0);
  for (int i = 0; i < rows; ++i) {
    for (int j = 0; j < cols; ++j) {
      obs_r[i] += observed[i * cols + j], exp_r[i] += expected[i * cols + j];
      obs_c[j] += observed[i * cols + j], exp_c[j] += expected[i * cols + j];
    }
  }
  for (size_t e = 0; e < extra; ++e) {
    obs_r[rows + e] = obs_c[cols + e] = observed[cells + e];
    exp_r[rows + e] = exp_c[cols + e] = expected[cells + e];
  }
  auto name = [&](size_t c) { return label ? label(c) : "cell " + std::to_string(c); };
  GridTestResult r;
  r.full = chi_square_test(observed, expected, name);
  r.row_marginal = chi_square_test(obs_r, exp_r, [&](size_t i) {
    return i < size_t(rows) ? "row " + std::to_string(i) : name(cells + i - rows);
  });
  r.col_marginal = chi_square_test(obs_c, exp_c, [&](size_t j) {
    return j < size_t(cols) ? "column " + std::to_string(j) : name(cells + j - cols);
  });
  return r;
}

struct SphereTestResult {
  GridTestResult test;            // rows: theta bands, columns: phi sectors
  double success_fraction = 0.0;  // fraction of sample() calls that returned a direction
  double pdf_integral = 0.0;      // integral of pdf over the sphere

  bool passed(double alpha) const { return test.passed(alpha); }
  std::string summary() const { return test.summary(); }
};

// Chi-square test of a direction sampler against its density. Cells are
// uniform in (theta, phi) with theta in [0, theta_max] (directions beyond go
// to one extra cell, integrated as a whole); one more cell counts failed
// samples, whose expected share is 1 - integral(pdf). That last cell is what
// makes the test also check that the sampler produces exactly the mass the
// pdf claims (a sampler that drops samples the pdf accounts for fails).
// Uniform theta (rather than cos theta) bins keep peaked lobes at the poles
// resolved.
//
// sample(Vec3* dir) -> bool draws one direction; pdf(Vec3) -> float/double
// is the claimed solid-angle density.
template <class Sample, class Pdf>
SphereTestResult sphere_chi_square(Sample&& sample, Pdf&& pdf, int n_samples, int n_theta,
                                   int n_phi, double theta_max = double(kPi)) {
  const int n_cells = n_theta * n_phi;
  const int outside = n_cells, failed = n_cells + 1;
  std::vector<double> observed(n_cells + 2, 0.0), expected(n_cells + 2, 0.0);
  const double dtheta = theta_max / n_theta, dphi = 2.0 * double(kPi) / n_phi;
  int successes = 0;
  for (int s = 0; s < n_samples; ++s) {
    Vec3 d;
    if (!sample(&d)) {
      observed[failed] += 1.0;
      continue;
    }
    ++successes;
    const double theta = std::acos(std::clamp(double(d.z), -1.0, 1.0));
    double phi = std::atan2(double(d.y), double(d.x));
    if (phi < 0.0) phi += 2.0 * double(kPi);
    if (theta > theta_max) {
      observed[outside] += 1.0;
      continue;
    }
    const int i = std::min(int(theta / dtheta), n_theta - 1);
    const int j = std::min(int(phi / dphi), n_phi - 1);
    observed[i * n_phi + j] += 1.0;
  }
  const double n = double(n_samples);
  double total = 0.0;
  for (int i = 0; i < n_theta; ++i) {
    for (int j = 0; j < n_phi; ++j) {
      const double p =
          integrate_cell(pdf, i * dtheta, (i + 1) * dtheta, j * dphi, (j + 1) * dphi, n);
      expected[i * n_phi + j] = p * n;
      total += p;
    }
  }
  if (theta_max < double(kPi)) {
    double p = 0.0;
    for (int j = 0; j < n_phi; ++j) {
      p += integrate_cell(pdf, theta_max, double(kPi), j * dphi, (j + 1) * dphi, n);
    }
    expected[outside] = p * n;
    total += p;
  }
  // A density that integrates to 1 up to cubature error leaves no room for
  // failures; clamp that error instead of producing a negative expectation
  // (real excess mass is reported as an error below).
  const double fail_mass = 1.0 - total;
  expected[failed] = std::max(fail_mass, 0.0) * n;
  // A failure mass within the cubature's own error is not resolved:
  // near-singular lobes (rough transmission at grazing view) leave the sum
  // ~5e-4 short of 1 (checked against a brute-force 16000^2 midpoint sum),
  // which would demand failures a correct sampler never produces, while a few
  // real failures (reflections below the horizon) make the sum short by less.
  // The cell then leaves the test; callers compare the success fraction with
  // the pdf integral directly.
  if (std::fabs(fail_mass) < kCubatureMassTolerance) {
    observed[failed] = 0.0;
    expected[failed] = 0.0;
  }

  auto label = [&](size_t c) -> std::string {
    if (c == size_t(outside)) return "theta > theta_max";
    if (c == size_t(failed)) return "failed samples";
    const int i = int(c) / n_phi, j = int(c) % n_phi;
    std::ostringstream l;
    l << "theta[" << i * dtheta << "," << (i + 1) * dtheta << "] phi[" << j * dphi << ","
      << (j + 1) * dphi << "]";
    return l.str();
  };

  SphereTestResult r;
  r.test = grid_chi_square(observed, expected, n_theta, n_phi, label);
  if (r.test.full.error.empty() && fail_mass < -1e-4) {
    r.test.full.error = "pdf integrates to " + std::to_string(total) + " > 1";
  }
  r.success_fraction = double(successes) / n;
  r.pdf_integral = total;
  return r;
}

// Runs body(i) for every i in [0, n) on all hardware threads. Each index
// must own its inputs (its own seeded RNG) and output slot, so results do not
// depend on the thread count; gtest assertions belong on the calling thread.
template <class Body>
void parallel_for(int n, const Body& body) {
  const int threads = int(std::max(1u, std::thread::hardware_concurrency()));
  std::atomic<int> next{0};
  std::vector<std::thread> pool;
  for (int t = 0; t < std::min(threads, n); ++t) {
    pool.emplace_back([&] {
      for (int i = next++; i < n; i = next++)
        body(i);
    });
  }
  for (std::thread& t : pool)
    t.join();
}

// Mean and standard error of a running sample.
struct MeanAccumulator {
  double sum = 0.0, sum_sq = 0.0;
  long count = 0;
  void add(double x) {
    sum += x;
    sum_sq += x * x;
    ++count;
  }
  double mean() const { return count ? sum / double(count) : 0.0; }
  double std_error() const {
    if (count < 2) return 0.0;
    const double m = mean();
    const double var =
        std::max(0.0, sum_sq / double(count) - m * m) * double(count) / double(count - 1);
    return std::sqrt(var / double(count));
  }
};

}  // namespace tandem::test_stats
