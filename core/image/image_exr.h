// OpenEXR through the OpenEXR library (Debian's libopenexr-dev), kept
// behind this internal header so that nothing else includes its headers.
//
// Reading takes every compression (ZIP, PIZ, DWAA, B44, ...), scanline and
// tiled (level 0 of mipmaps), half, float, and multi-part or multi-layer
// files (the first RGB or Y layer, with a warning naming the others).
// The header is checked first by the library's C core, which parses it
// without reading pixels: parts, data window and channels are judged
// against ImageReadLimits before any pixel memory exists.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "core/image/image.h"

namespace tandem {

ImageRGB decode_exr(const uint8_t* data, size_t size, const std::string& name,
                    const ImageReadLimits& limits);

std::vector<uint8_t> encode_exr(const ImageRGB& image, ExrPixelType pixel_type,
                                ExrCompression compression);

// Shared by the readers: throws InputError "name: why".
[[noreturn]] void fail_image(const std::string& name, const std::string& why);
// Throws InputError naming the file when w x h is empty or over the limits.
void check_image_pixels(const std::string& name, const char* format, uint64_t w, uint64_t h,
                        const ImageReadLimits& limits);

}  // namespace tandem
