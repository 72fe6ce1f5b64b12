// Tiles: the unit of work handed to backends.
#pragma once

#include <atomic>
#include <cstdint>
#include <mutex>
#include <vector>

namespace tandem {

struct Tile {
  uint32_t x0, y0, x1, y1;  // pixel rectangle [x0, x1) x [y0, y1)
  uint32_t index;           // position in the frame's tile list
  uint32_t pixel_count() const { return (x1 - x0) * (y1 - y0); }
};

// Row-major grid of tiles covering a width x height frame.
std::vector<Tile> make_tile_grid(uint32_t width, uint32_t height, uint32_t tile_size);

// Where a backend pulls its tiles from. next() is called concurrently by
// many worker threads and must hand out each tile at most once.
class TileSource {
 public:
  virtual ~TileSource() = default;
  virtual bool next(Tile* tile) = 0;
};

// Hands out a fixed list of tiles in order.
class TileQueue final : public TileSource {
 public:
  explicit TileQueue(std::vector<Tile> tiles) : tiles_(std::move(tiles)) {}
  bool next(Tile* tile) override;
  size_t size() const { return tiles_.size(); }
  size_t taken() const;

 private:
  std::vector<Tile> tiles_;
  std::atomic<size_t> next_{0};
};

// Hands out `first` (tiles a failed backend took but did not finish), then
// whatever `rest` still has.
class ResumedTiles final : public TileSource {
 public:
  ResumedTiles(std::vector<Tile> first, TileSource& rest) : first_(std::move(first)), rest_(rest) {}
  bool next(Tile* tile) override;

 private:
  std::vector<Tile> first_;
  TileSource& rest_;
  std::mutex mutex_;
  size_t taken_ = 0;
};

// Hands out what `inner` has until `stop` is set, then nothing: a frame a
// caller cancels ends after the tiles already taken.
class CancellableTiles final : public TileSource {
 public:
  CancellableTiles(TileSource& inner, const std::atomic<bool>& stop) : inner_(inner), stop_(stop) {}
  bool next(Tile* tile) override {
    return !stop_.load(std::memory_order_relaxed) && inner_.next(tile);
  }

 private:
  TileSource& inner_;
  const std::atomic<bool>& stop_;
};

}  // namespace tandem
