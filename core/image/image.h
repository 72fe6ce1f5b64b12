// Linear RGB images, tone mapping, and image files.
//
// Writers are atomic: the image goes to a temporary file in the destination
// directory which is renamed over the target only when complete, so a crash
// or a full disk never leaves a half-written output behind.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace tandem {

struct ImageRGB {
  uint32_t width = 0, height = 0;
  std::vector<float> rgb;  // linear, row 0 = top, 3 floats per pixel

  ImageRGB() = default;
  ImageRGB(uint32_t w, uint32_t h) : width(w), height(h), rgb(size_t(w) * h * 3, 0.0f) {}
  float* pixel(uint32_t x, uint32_t y) { return &rgb[(size_t(y) * width + x) * 3]; }
  const float* pixel(uint32_t x, uint32_t y) const { return &rgb[(size_t(y) * width + x) * 3]; }
};

// Relative MSE against `reference` (same size): the mean over pixels and
// channels of (a - ref)^2 / (ref^2 + 0.01), the noise metric the denoiser
// and motion-quality figures use.
double relative_mse(const ImageRGB& image, const ImageRGB& reference);

enum class ToneMap { kStandard, kAces, kReinhard };

// Parses "standard" | "aces" | "reinhard"; throws UsageError otherwise.
ToneMap parse_tone_map(const std::string& name);

// Exposure (in stops) + tone curve + sRGB encoding to 8-bit RGB.
std::vector<uint8_t> tone_map_to_srgb8(const ImageRGB& image, float exposure_stops, ToneMap curve);
// The same into `out` (image.rgb.size() bytes).
void tone_map_to_srgb8_into(const ImageRGB& image, float exposure_stops, ToneMap curve,
                            uint8_t* out);

// How .exr output stores its pixels: 32-bit float keeps every value a
// render produces; half (16-bit) is what texture and compositing tools
// usually take, at half the size, and clamps above 65504.
enum class ExrPixelType { kFloat, kHalf };
// OpenEXR's compressions, by their names in the format. ZIP is lossless
// and what Blender writes by default; DWAA/DWAB and B44 are lossy.
enum class ExrCompression { kNone, kRle, kZips, kZip, kPiz, kPxr24, kB44, kB44a, kDwaa, kDwab };

// Parse "float" | "half" and "none" | "rle" | "zips" | "zip" | "piz" |
// "pxr24" | "b44" | "b44a" | "dwaa" | "dwab"; throw UsageError otherwise.
ExrPixelType parse_exr_pixel_type(const std::string& name);
ExrCompression parse_exr_compression(const std::string& name);

struct ImageWriteOptions {
  float exposure = 0.0f;  // stops, PNG only
  ToneMap tone_map = ToneMap::kStandard;
  ExrPixelType exr_pixel_type = ExrPixelType::kFloat;     // EXR only
  ExrCompression exr_compression = ExrCompression::kZip;  // EXR only
};

// Chooses the format from the extension: .png (tone mapped sRGB), .exr
// (linear RGB, ZIP-compressed float by default) or .pfm (32-bit float
// RGB). Throws InputError naming the file for unknown extensions or write
// failures.
void write_image(const std::filesystem::path& path, const ImageRGB& image,
                 const ImageWriteOptions& options = {});

// Writes 8-bit RGB data as PNG (atomically).
void write_png_rgb8(const std::filesystem::path& path, uint32_t width, uint32_t height,
                    const std::vector<uint8_t>& rgb);

// Writes `bytes` to a temporary file beside `path` and renames it over
// `path`, so readers see the old file or the new one, never a part. Every
// output file of Tandem (images, benchmark reports) goes through it. Throws
// InputError naming the file (missing directory, write or rename failure).
void write_file_atomically(const std::filesystem::path& path, const std::vector<uint8_t>& bytes);

// Checks that `path` can be written before anything is spent on producing
// it: not a directory, in an existing, writable directory. Throws
// InputError naming the path and the reason.
void check_output_path(const std::filesystem::path& path);

// What readers accept. Every header field and the file length are checked
// against these (in 64-bit arithmetic) before any pixel is allocated.
struct ImageReadLimits {
  uint64_t max_pixels = uint64_t(1) << 27;      // 16384 x 8192: 1.5 GiB as float RGB
  uint64_t max_file_bytes = uint64_t(4) << 30;  // read into memory whole
  // For the message of an image over max_pixels: what the image is for
  // ("an environment map") and the bytes a pixel takes there in the end.
  const char* use = nullptr;
  uint32_t bytes_per_pixel_in_use = 0;
  const char* advice = nullptr;  // what to do instead, after "; "
};

// Reads .hdr (Radiance RGBE), .exr (any compression, scanline or tiled,
// half or float, the first RGB layer of a multi-part file), .pfm,
// PNG and JPEG (8-bit, decoded from sRGB to linear).
// Throws InputError naming the file and the reason.
ImageRGB read_image(const std::filesystem::path& path, const ImageReadLimits& limits = {});
// The same for bytes in memory; `name` names them in messages and its
// extension picks the format.
ImageRGB read_image_from_memory(const uint8_t* data, size_t size, const std::string& name,
                                const ImageReadLimits& limits = {});

// What the header of a PNG or JPEG says, without decoding it. PNG/JPEG are
// recognised by their signature; header_ok is false (with `problem` saying
// why) when the header is corrupt or truncated.
struct EncodedImageInfo {
  enum Format { kUnknown, kPng, kJpeg } format = kUnknown;
  bool header_ok = false;
  uint32_t width = 0, height = 0;
  // What a decoder produces (for the memory decoding takes): channels
  // (a palette PNG counts as 4) and bytes per channel (2 for 16-bit PNGs).
  int channels = 4, bytes_per_channel = 1;
  std::string problem;
};
EncodedImageInfo probe_encoded_image(const uint8_t* data, size_t size);

}  // namespace tandem
