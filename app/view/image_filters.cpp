#include "app/view/image_filters.h"

#include <algorithm>
#include <cmath>

namespace tandem {

void backend_color(size_t i, float rgb[3]) {
  static const float palette[4][3] = {
      {0.2f, 0.9f, 0.3f}, {0.25f, 0.5f, 1.0f}, {1.0f, 0.55f, 0.1f}, {0.9f, 0.2f, 0.9f}};
  for (int c = 0; c < 3; ++c)
    rgb[c] = palette[i % 4][c];
}

void tint_tile_owners(std::vector<uint8_t>& rgb, uint32_t width, uint32_t height,
                      const std::vector<Tile>& tiles, const std::vector<int32_t>& owners,
                      float strength) {
  for (size_t t = 0; t < tiles.size() && t < owners.size(); ++t) {
    if (owners[t] < 0) continue;
    float col[3];
    backend_color(size_t(owners[t]), col);
    const Tile& tile = tiles[t];
    for (uint32_t y = tile.y0; y < std::min(tile.y1, height); ++y) {
      for (uint32_t x = tile.x0; x < std::min(tile.x1, width); ++x) {
        uint8_t* p = &rgb[(size_t(y) * width + x) * 3];
        const bool border = x == tile.x0 || y == tile.y0;
        for (int c = 0; c < 3; ++c) {
          float v = float(p[c]) * (1.0f - strength) + 255.0f * col[c] * strength;
          if (border) v *= 0.5f;
          p[c] = uint8_t(std::clamp(v, 0.0f, 255.0f));
        }
      }
    }
  }
}

namespace {

// Bilinear resampling of 3-channel images, pixel centres aligned: put(x, y,
// c, v) receives each output value, at(x, y, c) reads the input.
template <class At, class Put>
void resize_bilinear(uint32_t w, uint32_t h, uint32_t ow, uint32_t oh, At at, Put put) {
  for (uint32_t y = 0; y < oh; ++y) {
    const float fy =
        std::clamp((float(y) + 0.5f) * float(h) / float(oh) - 0.5f, 0.0f, float(h - 1));
    const uint32_t y0 = uint32_t(fy), y1 = std::min(y0 + 1, h - 1);
    const float ty = fy - float(y0);
    for (uint32_t x = 0; x < ow; ++x) {
      const float fx =
          std::clamp((float(x) + 0.5f) * float(w) / float(ow) - 0.5f, 0.0f, float(w - 1));
      const uint32_t x0 = uint32_t(fx), x1 = std::min(x0 + 1, w - 1);
      const float tx = fx - float(x0);
      for (int c = 0; c < 3; ++c) {
        const float v = (at(x0, y0, c) * (1 - tx) + at(x1, y0, c) * tx) * (1 - ty) +
                        (at(x0, y1, c) * (1 - tx) + at(x1, y1, c) * tx) * ty;
        put(x, y, c, v);
      }
    }
  }
}

}  // namespace

std::vector<uint8_t> resize_rgb8(const std::vector<uint8_t>& rgb, uint32_t w, uint32_t h,
                                 uint32_t ow, uint32_t oh) {
  if (w == ow && h == oh) return rgb;
  std::vector<uint8_t> out(size_t(ow) * oh * 3);
  resize_bilinear(
      w, h, ow, oh,
      [&](uint32_t x, uint32_t y, int c) { return float(rgb[(size_t(y) * w + x) * 3 + c]); },
      [&](uint32_t x, uint32_t y, int c, float v) {
        out[(size_t(y) * ow + x) * 3 + c] = uint8_t(std::lround(std::clamp(v, 0.0f, 255.0f)));
      });
  return out;
}

ImageRGB resize_linear(const ImageRGB& image, uint32_t ow, uint32_t oh) {
  if (image.width == ow && image.height == oh) return image;
  ImageRGB out(ow, oh);
  const uint32_t w = image.width;
  resize_bilinear(
      w, image.height, ow, oh,
      [&](uint32_t x, uint32_t y, int c) { return image.rgb[(size_t(y) * w + x) * 3 + c]; },
      [&](uint32_t x, uint32_t y, int c, float v) { out.rgb[(size_t(y) * ow + x) * 3 + c] = v; });
  return out;
}

}  // namespace tandem
