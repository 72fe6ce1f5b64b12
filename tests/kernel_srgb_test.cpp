// The sRGB decode table (core/kernel/srgb_table.h) against the exact curve,
// and the texture fetch going through it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <vector>

#include "core/kernel/texture.h"

namespace tandem {
namespace {

// IEC 61966-2-1 decode in double.
double srgb_decode_exact(double c) {
  return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, sizeof u);
  return u;
}

TEST(KernelSrgb, EveryTableEntryIsTheCorrectlyRoundedCurve) {
  for (uint32_t i = 0; i < 256; ++i) {
    const float rounded = float(srgb_decode_exact(double(i) / 255.0));
    const float entry = kSrgb8ToLinear[i];
    // Positive floats order like their bit patterns: the difference counts ulps.
    const int64_t ulps = int64_t(bits(entry)) - int64_t(bits(rounded));
    EXPECT_LE(std::llabs(ulps), 1) << "entry " << i << ": " << entry << " vs " << rounded;
  }
  EXPECT_EQ(kSrgb8ToLinear[0], 0.0f);
  EXPECT_EQ(kSrgb8ToLinear[255], 1.0f);
  for (uint32_t i = 1; i < 256; ++i)
    EXPECT_LT(kSrgb8ToLinear[i - 1], kSrgb8ToLinear[i]) << i;
}

TEST(KernelSrgb, DecodeUsesOnlyTheLowByte) {
  for (uint32_t i = 0; i < 256; ++i) {
    EXPECT_EQ(bits(srgb8_to_linear(i)), bits(kSrgb8ToLinear[i]));
    EXPECT_EQ(bits(srgb8_to_linear(0xabcdef00u | i)), bits(kSrgb8ToLinear[i]));
  }
}

// A 256 x 1 texture whose texel i holds (i, 255 - i, i / 2, i): sampled at
// every texel centre, an sRGB texture must return the table's entries bit for
// bit (and alpha linearly), a linear one i / 255.
struct RampTexture {
  std::vector<uint32_t> texels;
  KTexture tex{};
  KernelData kd{};
  explicit RampTexture(uint32_t flags) {
    for (uint32_t i = 0; i < 256; ++i)
      texels.push_back(i | (255 - i) << 8 | (i / 2) << 16 | i << 24);
    tex.width = 256;
    tex.height = 1;
    tex.flags = flags;
    tex.wrap_s = tex.wrap_t = kWrapClamp;
    kd.texels = texels.data();
    kd.texels_count = uint32_t(texels.size());
    kd.textures = &tex;
    kd.textures_count = 1;
  }
  Vec4 at(uint32_t i) const { return sample_texture(kd, 0, {(float(i) + 0.5f) / 256.0f, 0.5f}); }
};

TEST(KernelSrgb, SrgbTexturesDecodeThroughTheTable) {
  for (uint32_t flags : {uint32_t(kTextureSrgb), uint32_t(kTextureSrgb | kTextureNearest)}) {
    const RampTexture ramp(flags);
    for (uint32_t i = 0; i < 256; ++i) {
      const Vec4 c = ramp.at(i);
      ASSERT_EQ(bits(c.x), bits(kSrgb8ToLinear[i])) << i << " flags " << flags;
      ASSERT_EQ(bits(c.y), bits(kSrgb8ToLinear[255 - i])) << i;
      ASSERT_EQ(bits(c.z), bits(kSrgb8ToLinear[i / 2])) << i;
      ASSERT_EQ(c.w, float(i) * (1.0f / 255.0f)) << "alpha stays linear, texel " << i;
    }
  }
}

TEST(KernelSrgb, LinearTexturesAreNotDecoded) {
  const RampTexture ramp(kTextureNearest);
  for (uint32_t i = 0; i < 256; ++i) {
    const Vec4 c = ramp.at(i);
    ASSERT_EQ(c.x, float(i) * (1.0f / 255.0f)) << i;
    ASSERT_EQ(c.y, float(255 - i) * (1.0f / 255.0f)) << i;
  }
}

}  // namespace
}  // namespace tandem
