// Image post-processing for tandem-view's display: an edge-aware denoise
// for low-sample motion frames, the tile-ownership tint of the split view,
// and resampling to the window size. Pure functions on images.
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/render/tiles.h"

namespace tandem {

// Edge-aware (bilateral) filter on linear radiance: neighbours within
// `radius` pixels are averaged with weights that fall off with distance and
// with the difference in log luminance, so noise inside flat regions is
// smoothed while object edges and highlights stay sharp. Without a G-buffer
// this is what one noisy frame offers to steer by.
ImageRGB denoise_edge_aware(const ImageRGB& image, int radius = 2, float range_sigma = 0.6f);

// Tints 8-bit RGB pixels of each tile by the colour of the backend that
// rendered it (owner index into a fixed palette; -1: untouched) and darkens
// tile borders so the split is visible.
void tint_tile_owners(std::vector<uint8_t>& rgb, uint32_t width, uint32_t height,
                      const std::vector<Tile>& tiles, const std::vector<int32_t>& owners,
                      float strength = 0.35f);

// Palette colour (0..1) used for backend i in the overlay and the panel.
void backend_color(size_t i, float rgb[3]);

// Bilinear resampling of 8-bit RGB to another size (for screenshots of
// frames rendered at a reduced resolution scale).
std::vector<uint8_t> resize_rgb8(const std::vector<uint8_t>& rgb, uint32_t width, uint32_t height,
                                 uint32_t out_width, uint32_t out_height);

}  // namespace tandem
