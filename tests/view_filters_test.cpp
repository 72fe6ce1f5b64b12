// tandem-view's display filters: split-view tint, resize.
#include <gtest/gtest.h>

#include <cmath>

#include "app/view/image_filters.h"

namespace tandem {
namespace {

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
