// tandem-view's display filters: edge-aware denoise, split-view tint, resize.
#include <gtest/gtest.h>

#include <cmath>

#include "app/view/image_filters.h"

namespace tandem {
namespace {

TEST(ViewDenoise, SmoothsNoiseButKeepsAStepEdge) {
  // Left half ~0.2, right half ~5 (an emitter's edge), with +-30% noise.
  ImageRGB img(32, 16);
  uint32_t state = 12345;
  auto noise = [&] {
    state = state * 1664525u + 1013904223u;
    return (float(state >> 8) / 16777216.0f - 0.5f) * 0.6f;
  };
  for (uint32_t y = 0; y < 16; ++y)
    for (uint32_t x = 0; x < 32; ++x)
      for (int c = 0; c < 3; ++c)
        img.pixel(x, y)[c] = (x < 16 ? 0.2f : 5.0f) * (1.0f + noise());
  const ImageRGB out = denoise_edge_aware(img);
  auto variance = [](const ImageRGB& im, uint32_t x0, uint32_t x1) {
    double s = 0, s2 = 0, n = 0;
    for (uint32_t y = 2; y < 14; ++y)
      for (uint32_t x = x0; x < x1; ++x) {
        s += im.pixel(x, y)[0], s2 += double(im.pixel(x, y)[0]) * im.pixel(x, y)[0], ++n;
      }
    return s2 / n - (s / n) * (s / n);
  };
  EXPECT_LT(variance(out, 2, 13), 0.5 * variance(img, 2, 13));
  EXPECT_LT(variance(out, 19, 30), 0.5 * variance(img, 19, 30));
  // The pixels next to the edge keep their side's level (no bleeding).
  for (uint32_t y = 0; y < 16; ++y) {
    EXPECT_LT(out.pixel(15, y)[0], 0.5f);
    EXPECT_GT(out.pixel(16, y)[0], 3.0f);
  }
}

TEST(ViewSplitOverlay, TintsEachTileByItsOwner) {
  const std::vector<Tile> tiles = make_tile_grid(8, 4, 4);  // two tiles side by side
  ASSERT_EQ(tiles.size(), 2u);
  std::vector<uint8_t> rgb(8 * 4 * 3, 128);
  tint_tile_owners(rgb, 8, 4, tiles, {0, 1});
  float c0[3], c1[3];
  backend_color(0, c0);
  backend_color(1, c1);
  const uint8_t* a = &rgb[(1 * 8 + 1) * 3];  // inside tile 0, off its border
  const uint8_t* b = &rgb[(1 * 8 + 5) * 3];  // inside tile 1
  EXPECT_NE(std::vector<uint8_t>(a, a + 3), std::vector<uint8_t>(b, b + 3));
  EXPECT_GT(a[1], a[2]);  // backend 0 is green
  EXPECT_GT(b[2], b[0]);  // backend 1 is blue
  std::vector<uint8_t> untouched(8 * 4 * 3, 128), copy = untouched;
  tint_tile_owners(copy, 8, 4, tiles, {-1, -1});
  EXPECT_EQ(copy, untouched);
}

TEST(ViewResize, UpscalesWithoutChangingAFlatImage) {
  std::vector<uint8_t> rgb(4 * 2 * 3, 77);
  const std::vector<uint8_t> big = resize_rgb8(rgb, 4, 2, 16, 8);
  ASSERT_EQ(big.size(), 16u * 8 * 3);
  for (uint8_t v : big)
    EXPECT_EQ(v, 77);
  EXPECT_EQ(resize_rgb8(rgb, 4, 2, 4, 2), rgb);
}

}  // namespace
}  // namespace tandem
