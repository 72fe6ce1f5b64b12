// Work item -> pixel sample mapping of a tile batch, below and beyond 2^32
// items (the two paths of batch_item).
#include <gtest/gtest.h>

#include "core/kernel/tile_batch.h"

namespace tandem {
namespace {

TEST(TileBatch, ItemMapsToPixelAndSampleOnBothSidesOf32Bits) {
  // One 1920x1080 tile: 2,073,600 pixels; 4096 samples makes 8.5e9 items.
  const DeviceTile tile = {0, 0, 1920, 1080, 0};
  TileBatch batch;
  batch.tiles = &tile;
  batch.tile_count = 1;
  batch.pixel_count = 1920 * 1080;
  batch.sample_begin = 7;
  batch.sample_count = 4096;
  const uint64_t n = batch.pixel_count;
  const uint64_t edge = uint64_t(1) << 32;
  for (const uint64_t base :
       {uint64_t(0), edge - 3 * n, edge - 2, edge, edge + n - 1, batch.items() - 5}) {
    for (uint64_t item = base; item < base + 5 && item < batch.items(); ++item) {
      uint32_t x, y, sample;
      batch_item(batch, item, &x, &y, &sample);
      const uint64_t p = item % n;
      EXPECT_EQ(sample, 7u + uint32_t(item / n)) << item;
      EXPECT_EQ(x, uint32_t(p % 1920)) << item;
      EXPECT_EQ(y, uint32_t(p / 1920)) << item;
    }
  }
  // Every multiple of the pixel count starts a sample at pixel 0.
  for (uint64_t s = 2070; s < 2075; ++s) {
    uint32_t x, y, sample;
    batch_item(batch, s * n, &x, &y, &sample);
    EXPECT_EQ(x, 0u);
    EXPECT_EQ(y, 0u);
    EXPECT_EQ(sample, 7u + uint32_t(s));
    batch_item(batch, s * n - 1, &x, &y, &sample);
    EXPECT_EQ(x, 1919u);
    EXPECT_EQ(y, 1079u);
    EXPECT_EQ(sample, 6u + uint32_t(s));
  }
}

}  // namespace
}  // namespace tandem
