// Image post-processing for tandem-view's display: the tile-ownership tint
// of the split view and resampling to the window size. Pure functions on
// images. (Motion frames are denoised by SVGF: app/view/denoise_view.h.)
#pragma once

#include <cstdint>
#include <vector>

#include "core/image/image.h"
#include "core/render/tiles.h"

namespace tandem {

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
// The same for linear radiance (what the motion quality is measured on).
ImageRGB resize_linear(const ImageRGB& image, uint32_t out_width, uint32_t out_height);

}  // namespace tandem
