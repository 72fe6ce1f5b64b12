#include "core/render/tiles.h"

#include <algorithm>

namespace tandem {

std::vector<Tile> make_tile_grid(uint32_t width, uint32_t height, uint32_t tile_size) {
  std::vector<Tile> tiles;
  tile_size = std::max(tile_size, 1u);
  for (uint32_t y = 0; y < height; y += tile_size) {
    for (uint32_t x = 0; x < width; x += tile_size) {
      tiles.push_back({x, y, std::min(x + tile_size, width), std::min(y + tile_size, height),
                       uint32_t(tiles.size())});
    }
  }
  return tiles;
}

bool TileQueue::next(Tile* tile) {
  const size_t i = next_.fetch_add(1, std::memory_order_relaxed);
  if (i >= tiles_.size()) return false;
  *tile = tiles_[i];
  return true;
}

size_t TileQueue::taken() const {
  return std::min(next_.load(std::memory_order_relaxed), tiles_.size());
}

bool ResumedTiles::next(Tile* tile) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (taken_ < first_.size()) {
      *tile = first_[taken_++];
      return true;
    }
  }
  return rest_.next(tile);
}

}  // namespace tandem
