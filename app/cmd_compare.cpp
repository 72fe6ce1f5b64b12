// `tandem compare A B`: do two Monte Carlo renders of the same scene agree
// up to noise? Used to validate Tandem against an independent renderer.
//
// The core test works on blocks of N x N pixels. For each block and channel
// it forms the mean of the per-pixel difference d = B - A and divides it by
// its standard error sqrt(var(d) / n). Because both images share the same
// expected picture, the image structure inside a block (edges, gradients)
// cancels in d, so var(d) estimates only var_A + var_B of the noise; the
// variances of A and B taken separately would include the structure and make
// the test blind exactly where geometry differences would show. Pixels of a
// Monte Carlo render are independent estimates, so n = N^2 pixels give an
// (n - 1)-dof estimate and z is close to standard normal when A and B agree.
#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "app/cli_args.h"
#include "app/cli_options.h"
#include "app/commands.h"
#include "core/image/image.h"
#include "core/util/errors.h"

namespace tandem {

namespace {

// Verdict thresholds, documented in --help. The three channels of a block
// are often strongly correlated (at direct lighting they are exactly
// proportional), so counts and averages over block-channels are calibrated
// per block, where tests are independent, not per block-channel.
constexpr double kBlockOutlierZ = 3.32;      // max over 3 channels: <= 0.27% per block if agreeing
constexpr double kBlockOutlierRate = 0.005;  // assumed rate: 0.27% doubled for heavier tails
constexpr double kCountFalseAlarm = 1e-3;    // P(more outlier blocks than allowed | agreement)
constexpr double kMeanZSigmas = 5.0;         // |mean z| <= 5 sqrt(3/K) ...
constexpr double kMinMeanZTolerance = 0.05;  // ... or 0.05, whichever is larger
constexpr double kMaxGlobalZ = 5.0;          // whole-image mean of any channel
constexpr double kMaxBlockZ = 8.0;           // no block, however few disagree, may exceed this

// Largest count of outlier blocks still consistent with agreement:
// P(Poisson(lambda) > c) < kCountFalseAlarm.
size_t allowed_outlier_blocks(size_t blocks) {
  const double lambda = kBlockOutlierRate * double(blocks);
  if (lambda > 100.0) return size_t(lambda + 3.1 * std::sqrt(lambda) + 1.0);  // normal limit
  double pmf = std::exp(-lambda), cdf = pmf;
  size_t c = 0;
  while (1.0 - cdf >= kCountFalseAlarm) {
    pmf *= lambda / double(++c);
    cdf += pmf;
  }
  return c;
}

const std::vector<OptionSpec>& compare_options() {
  static const std::vector<OptionSpec> specs = compose_options({
      {
          {"block", true, "block edge in pixels (default 16; >= 8 keeps z near-normal)", "N"},
          {"reference-noise", true,
           "second render by A's renderer, other seed: control test A vs C", "C"},
          {"json", false, "print the results as one JSON object"},
      },
      help_options(),
  });
  return specs;
}

struct BlockTest {
  size_t tested = 0;     // block-channels with a defined z
  size_t identical = 0;  // block-channels where A and B agree exactly (e.g. black background)
  size_t outliers = 0;   // |z| > 3
  size_t blocks = 0, outlier_blocks = 0;  // blocks with a z; those with max |z| > kBlockOutlierZ
  size_t testable_blocks = 0;             // blocks of at least 2 pixels (a variance exists)
  double mean_z = 0.0, max_abs_z = 0.0;
  uint32_t worst_x = 0, worst_y = 0;  // top-left pixel of the block with the largest |z|
  int worst_channel = 0;
  double global_z[3] = {};          // whole-image mean difference over its standard error
  std::vector<double> var_of_diff;  // per block-channel var(d), in scan order, for noise ratios
  double outlier_fraction() const { return tested ? double(outliers) / double(tested) : 0.0; }
  double mean_z_tolerance() const {
    return std::max(kMinMeanZTolerance,
                    kMeanZSigmas * std::sqrt(3.0 / double(std::max<size_t>(tested, 1))));
  }
  bool agree() const {
    bool ok = outlier_blocks <= allowed_outlier_blocks(blocks) &&
              std::fabs(mean_z) <= mean_z_tolerance() && max_abs_z <= kMaxBlockZ;
    for (double g : global_z)
      ok = ok && std::fabs(g) <= kMaxGlobalZ;
    return ok;
  }
};

BlockTest block_test(const ImageRGB& a, const ImageRGB& b, uint32_t block) {
  BlockTest t;
  double sum_z = 0.0, sum_d[3] = {}, sum_var[3] = {};
  for (uint32_t by = 0; by < a.height; by += block) {
    for (uint32_t bx = 0; bx < a.width; bx += block) {
      const uint32_t x1 = std::min(a.width, bx + block), y1 = std::min(a.height, by + block);
      const double n = double(x1 - bx) * double(y1 - by);
      if (n < 2) continue;  // edge blocks of one pixel have no variance estimate
      ++t.testable_blocks;
      double block_max_z = -1.0;
      for (int c = 0; c < 3; ++c) {
        double s = 0.0, s2 = 0.0;
        for (uint32_t y = by; y < y1; ++y) {
          for (uint32_t x = bx; x < x1; ++x) {
            const double d = double(b.pixel(x, y)[c]) - double(a.pixel(x, y)[c]);
            s += d;
            s2 += d * d;
          }
        }
        const double mean = s / n;
        const double var = std::max(0.0, (s2 - s * mean) / (n - 1.0));  // var(d) per pixel
        sum_d[c] += s;
        sum_var[c] += var * n;
        t.var_of_diff.push_back(var);
        if (var == 0.0 && mean == 0.0) {
          ++t.identical;
          continue;
        }
        const double z = var > 0.0 ? mean / std::sqrt(var / n) : std::copysign(1e300, mean);
        ++t.tested;
        sum_z += std::clamp(z, -1e6, 1e6);  // keep one degenerate block from swamping the mean
        if (std::fabs(z) > t.max_abs_z) {
          t.max_abs_z = std::fabs(z);
          t.worst_x = bx, t.worst_y = by, t.worst_channel = c;
        }
        if (std::fabs(z) > 3.0) ++t.outliers;
        block_max_z = std::max(block_max_z, std::fabs(z));
      }
      if (block_max_z >= 0.0) ++t.blocks;
      if (block_max_z > kBlockOutlierZ) ++t.outlier_blocks;
    }
  }
  t.mean_z = t.tested ? sum_z / double(t.tested) : 0.0;
  for (int c = 0; c < 3; ++c) {
    t.global_z[c] = sum_var[c] > 0.0 ? sum_d[c] / std::sqrt(sum_var[c]) : 0.0;
  }
  return t;
}

// JSON numbers cannot be inf/nan.
std::string num(double v) {
  if (!std::isfinite(v)) return v > 0 ? "1e308" : (v < 0 ? "-1e308" : "null");
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", v);
  return buf;
}

std::string quoted(const std::string& text) {
  std::string s("\"");
  for (char ch : text) {
    if (ch == '"' || ch == '\\') s += '\\';
    if (static_cast<unsigned char>(ch) >= 0x20) s += ch;  // drop control characters
  }
  return s + "\"";
}

std::string triple(const double* v) {
  // Appending (rather than "[" + ...) sidesteps a GCC 12 -Wrestrict false positive.
  std::string s("[");
  s.append(num(v[0])).append(", ").append(num(v[1])).append(", ").append(num(v[2])).append("]");
  return s;
}

std::string test_json(const BlockTest& t) {
  return "{\"block_channels\": " + std::to_string(t.tested) +
         ", \"identical_block_channels\": " + std::to_string(t.identical) +
         ", \"fraction_abs_z_gt_3\": " + num(t.outlier_fraction()) +
         ", \"blocks\": " + std::to_string(t.blocks) +
         ", \"outlier_blocks\": " + std::to_string(t.outlier_blocks) +
         ", \"allowed_outlier_blocks\": " + std::to_string(allowed_outlier_blocks(t.blocks)) +
         ", \"mean_z\": " + num(t.mean_z) + ", \"mean_z_tolerance\": " + num(t.mean_z_tolerance()) +
         ", \"max_abs_z\": " + num(t.max_abs_z) + ", \"worst_block\": [" +
         std::to_string(t.worst_x) + ", " + std::to_string(t.worst_y) + ", " +
         std::to_string(t.worst_channel) + "]" + ", \"global_z\": " + triple(t.global_z) +
         ", \"verdict\": \"" + (t.agree() ? "AGREE" : "DISAGREE") + "\"}";
}

void print_test(const char* label, const BlockTest& t) {
  std::printf("%s: %zu block-channels tested (%zu identical, skipped)\n", label, t.tested,
              t.identical);
  std::printf("  |z| > 3:      %.3f%% of block-channels (~0.3%% expected under agreement)\n",
              100.0 * t.outlier_fraction());
  std::printf("  outliers:     %zu of %zu blocks with max |z| > %.2f (limit %zu)\n",
              t.outlier_blocks, t.blocks, kBlockOutlierZ, allowed_outlier_blocks(t.blocks));
  std::printf("  mean z:       %+.4f (limit +-%.4f)\n", t.mean_z, t.mean_z_tolerance());
  // A block whose difference is the same in every pixel has no noise to
  // measure it against: its z is infinite (a constant offset, not noise).
  char max_z[32];
  if (t.max_abs_z >= 1e300) {
    std::snprintf(max_z, sizeof max_z, "inf (a constant difference)");
  } else {
    std::snprintf(max_z, sizeof max_z, "%.2f", t.max_abs_z);
  }
  std::printf("  max |z|:      %s (limit %.0f; block at x %u, y %u, channel %c)\n", max_z,
              kMaxBlockZ, t.worst_x, t.worst_y, "RGB"[t.worst_channel]);
  std::printf(
      "  global z:     R %+.2f  G %+.2f  B %+.2f (limit +-%.0f; whole-image mean difference "
      "/ its std. error)\n",
      t.global_z[0], t.global_z[1], t.global_z[2], kMaxGlobalZ);
}

void print_compare_help() {
  std::printf(
      "usage: tandem compare A B [options]\n\n"
      "Compares two linear images (.exr, .pfm, .hdr) of the same scene rendered with the same\n"
      "settings, e.g. Tandem vs another renderer, and tells whether they agree up to Monte Carlo\n"
      "noise. Prints per-channel means, their relative difference (B - A) / A, the RMSE, and a\n"
      "block test: the image is cut into N x N blocks; per block and channel,\n"
      "  z = mean(B - A) / sqrt(var(B - A) / n)\n"
      "with the variance taken over the block's n per-pixel differences, i.e. var_A/n + var_B/n\n"
      "of the noise (the picture itself cancels in B - A). If the renders agree, z is close to\n"
      "standard normal, so about 0.3%% of block-channels have |z| > 3. Block-channels where A and\n"
      "B are exactly equal (black background, a saturated light) are skipped. The channels of a\n"
      "block can be strongly correlated (exactly, under direct light only), so the verdict counts\n"
      "blocks: a block is an outlier if its largest |z| exceeds %.2f (<= 0.27%% of blocks under\n"
      "agreement, whatever the correlation). With K blocks and M tested block-channels:\n"
      "  DISAGREE  if the outlier blocks exceed the count a Poisson(%.3f K) law exceeds with\n"
      "            probability < %g (%.1f%% per block: twice the normal rate, for heavier tails),\n"
      "         or |mean z| > max(%.2f, %.0f sqrt(3/M)) (a brightness bias shifts the mean z;\n"
      "            5 sigma even if the 3 channels are fully correlated),\n"
      "         or any channel's global z (whole-image mean difference over its standard error)\n"
      "            exceeds %.0f in magnitude,\n"
      "         or any block has |z| > %.0f (a small region that plainly differs);\n"
      "  AGREE     otherwise.\n"
      "Noise estimates assume the pixels of each render are independent estimates (true for path\n"
      "tracers that seed each pixel separately); use enough spp that pixel noise is not skewed.\n\n"
      "With --reference-noise C (a second render by A's renderer with another seed) the same test\n"
      "is also run on A vs C, which agree by construction: its numbers show what agreement looks\n"
      "like for these images, and a control DISAGREE means the test itself is not calibrated for\n"
      "them. C also gives A's noise alone, hence the noise of B relative to A at equal samples\n"
      "(median over blocks; it cannot resolve ratios much below 0.2, which read as upper "
      "bounds).\n\n"
      "Exit code 0 when the comparison ran (whatever the verdict), 1 on unreadable images or\n"
      "size mismatches, 2 on usage errors.\n\n%s",
      kBlockOutlierZ, kBlockOutlierRate, kCountFalseAlarm, 100.0 * kBlockOutlierRate,
      kMinMeanZTolerance, kMeanZSigmas, kMaxGlobalZ, kMaxBlockZ,
      format_options_help(compare_options()).c_str());
}
}  // namespace

int run_compare(const std::vector<std::string>& argv) {
  const ParsedArgs args("compare", compare_options(), argv);
  if (args.has("help")) {
    print_compare_help();
    return 0;
  }
  if (args.positionals().size() != 2) throw UsageError("compare: expected two images A and B");
  const uint32_t block = args.get_u32("block", 16, 2, 4096);
  const std::string path_a = args.positionals()[0], path_b = args.positionals()[1];
  // Reads an image; rejects NaN/inf and sizes other than the first image's.
  auto load = [](const std::string& path, const ImageRGB* first, const std::string& first_path) {
    ImageRGB img = read_image(path);
    if (first && (img.width != first->width || img.height != first->height)) {
      throw InputError("compare: " + path + " is " + std::to_string(img.width) + "x" +
                       std::to_string(img.height) + " but " + first_path + " is " +
                       std::to_string(first->width) + "x" + std::to_string(first->height) +
                       "; the images must have the same size");
    }
    const size_t bad = size_t(
        std::count_if(img.rgb.begin(), img.rgb.end(), [](float v) { return !std::isfinite(v); }));
    if (bad) throw InputError(path + ": contains " + std::to_string(bad) + " NaN/inf values");
    return img;
  };
  // compare tests linear radiance; an 8-bit image has been through a tone
  // curve and exposure, which the sRGB decoding on reading does not undo.
  auto warn_if_tone_mapped = [](const std::string& path) {
    std::string ext = std::filesystem::path(path).extension().string();
    for (char& ch : ext)
      ch = char(std::tolower(static_cast<unsigned char>(ch)));
    if (ext != ".exr" && ext != ".pfm" && ext != ".hdr") {
      std::fprintf(stderr,
                   "tandem: warning: %s is an 8-bit (tone-mapped) image; compare expects linear "
                   "renders (.exr, .pfm, .hdr), so its tone curve and exposure are compared as "
                   "if they were radiance\n",
                   path.c_str());
    }
  };
  const ImageRGB a = load(path_a, nullptr, path_a), b = load(path_b, &a, path_a);
  warn_if_tone_mapped(path_a);
  warn_if_tone_mapped(path_b);
  const std::optional<std::string> path_c = args.value("reference-noise");
  const ImageRGB c = path_c ? load(*path_c, &a, path_a) : ImageRGB();
  if (path_c) warn_if_tone_mapped(*path_c);

  double mean_a[3] = {}, mean_b[3] = {}, rel[3] = {}, sq = 0.0;
  const size_t pixels = size_t(a.width) * a.height;
  for (size_t i = 0; i < pixels; ++i) {
    for (int ch = 0; ch < 3; ++ch) {
      const double va = a.rgb[i * 3 + ch], vb = b.rgb[i * 3 + ch];
      mean_a[ch] += va;
      mean_b[ch] += vb;
      sq += (vb - va) * (vb - va);
    }
  }
  for (int ch = 0; ch < 3; ++ch) {
    mean_a[ch] /= double(pixels);
    mean_b[ch] /= double(pixels);
    rel[ch] = mean_a[ch] != 0.0
                  ? (mean_b[ch] - mean_a[ch]) / mean_a[ch]
                  : (mean_b[ch] == 0.0 ? 0.0 : std::numeric_limits<double>::infinity());
  }
  const double rmse = std::sqrt(sq / double(pixels * 3));
  const BlockTest ab = block_test(a, b, block);
  // With no block of two pixels there is no noise estimate at all: no
  // verdict, rather than an AGREE that tested nothing.
  if (ab.testable_blocks == 0) {
    throw InputError("compare: " + path_a + " is " + std::to_string(a.width) + "x" +
                     std::to_string(a.height) +
                     ": too small for the block test (a block needs at least 2 pixels)");
  }
  BlockTest ac;
  double noise_ratio[3] = {};  // std. dev. of B's noise / A's, at the samples each was given
  if (path_c) {
    ac = block_test(a, c, block);
    for (int ch = 0; ch < 3; ++ch) {
      // Per block, var(B - A) = var_A + var_B and var(C - A) = 2 var_A. The median over blocks
      // is robust to the few pixels (light edges, fireflies) that dominate pooled variances.
      std::vector<double> ratios;
      for (size_t i = size_t(ch); i < ac.var_of_diff.size(); i += 3) {
        const double var_a = 0.5 * ac.var_of_diff[i];
        if (var_a > 0.0) ratios.push_back(ab.var_of_diff[i] / var_a - 1.0);
      }
      if (ratios.empty()) continue;
      std::nth_element(ratios.begin(), ratios.begin() + long(ratios.size() / 2), ratios.end());
      noise_ratio[ch] = std::sqrt(std::max(0.0, ratios[ratios.size() / 2]));
    }
  }

  if (args.has("json")) {
    std::string out =
        "{\"a\": " + quoted(path_a) + ", \"b\": " + quoted(path_b) +
        ", \"width\": " + std::to_string(a.width) + ", \"height\": " + std::to_string(a.height) +
        ", \"block\": " + std::to_string(block) + ", \"mean_a\": " + triple(mean_a) +
        ", \"mean_b\": " + triple(mean_b) + ", \"relative_difference\": " + triple(rel) +
        ", \"rmse\": " + num(rmse) + ", \"test\": " + test_json(ab);
    if (path_c) {
      out +=
          ", \"control\": " + test_json(ac) + ", \"noise_ratio_b_over_a\": " + triple(noise_ratio);
    }
    std::printf("%s, \"verdict\": \"%s\"}\n", out.c_str(), ab.agree() ? "AGREE" : "DISAGREE");
    return 0;
  }
  std::printf("A: %s\nB: %s\n%ux%u pixels, %ux%u blocks\n", path_a.c_str(), path_b.c_str(), a.width,
              a.height, block, block);
  std::printf("mean A:       R %.6g  G %.6g  B %.6g\n", mean_a[0], mean_a[1], mean_a[2]);
  std::printf("mean B:       R %.6g  G %.6g  B %.6g\n", mean_b[0], mean_b[1], mean_b[2]);
  std::printf("(B - A) / A:  R %+.4f%%  G %+.4f%%  B %+.4f%%\n", 100.0 * rel[0], 100.0 * rel[1],
              100.0 * rel[2]);
  std::printf("RMSE:         %.6g\n", rmse);
  print_test("block test A vs B", ab);
  if (path_c) {
    print_test("control A vs C", ac);
    std::printf("noise of B / noise of A (std. dev.): R %.3f  G %.3f  B %.3f\n", noise_ratio[0],
                noise_ratio[1], noise_ratio[2]);
    if (!ac.agree()) {
      std::printf(
          "warning: the control A vs C does not pass the test either; the verdict below is "
          "not reliable for these images\n");
    }
  }
  std::printf("verdict: %s\n", ab.agree() ? "AGREE" : "DISAGREE");
  return 0;
}

}  // namespace tandem
