// The libpng texture decoder gives stb's pixels, bit for bit: every colour
// type and bit depth up to 8, interlaced or not, with and without tRNS,
// written here with libpng; the shared models' own PNGs; and damaged files,
// which are errors, not crashes.
#include <gtest/gtest.h>
#include <png.h>
#include <stb_image.h>

#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "scenes/gltf_internal.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

struct PngSpec {
  int color_type, bit_depth;
  bool interlaced, trns;
};

// A w x h PNG of pseudo-random samples in the given layout.
std::vector<unsigned char> make_png(const PngSpec& spec, uint32_t w, uint32_t h, uint32_t seed) {
  std::vector<unsigned char> out;
  png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, nullptr, nullptr, nullptr);
  png_infop info = png_create_info_struct(png);
  png_set_write_fn(
      png, &out,
      [](png_structp p, png_bytep data, png_size_t n) {
        auto* o = static_cast<std::vector<unsigned char>*>(png_get_io_ptr(p));
        o->insert(o->end(), data, data + n);
      },
      nullptr);
  png_set_IHDR(png, info, w, h, spec.bit_depth, spec.color_type,
               spec.interlaced ? PNG_INTERLACE_ADAM7 : PNG_INTERLACE_NONE,
               PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
  const int entries = 1 << spec.bit_depth;
  std::vector<png_color> palette(size_t(std::min(entries, 256)));
  if (spec.color_type == PNG_COLOR_TYPE_PALETTE) {
    for (size_t i = 0; i < palette.size(); ++i)
      palette[i] = {png_byte(i * 37), png_byte(255 - i * 11), png_byte(i * 5 + 3)};
    png_set_PLTE(png, info, palette.data(), int(palette.size()));
  }
  std::vector<png_byte> alpha(palette.size());
  png_color_16 key{};
  if (spec.trns) {
    if (spec.color_type == PNG_COLOR_TYPE_PALETTE) {
      for (size_t i = 0; i < alpha.size(); ++i)
        alpha[i] = png_byte(i * 53);
      png_set_tRNS(png, info, alpha.data(), int(alpha.size()), nullptr);
    } else {
      key.gray = 1;
      key.red = 3, key.green = 5, key.blue = 7;
      png_set_tRNS(png, info, nullptr, 0, &key);
    }
  }
  png_set_gAMA(png, info, 1.0);  // a gamma chunk, which the decoders must ignore
  png_write_info(png, info);
  const int channels = png_get_channels(png, info);
  const size_t row_bytes = (size_t(w) * channels * spec.bit_depth + 7) / 8;
  std::mt19937 rng(seed);
  std::vector<std::vector<png_byte>> rows(h, std::vector<png_byte>(row_bytes));
  std::vector<png_bytep> pointers;
  for (auto& row : rows) {
    for (png_byte& b : row)
      b = png_byte(rng() & 0xff);
    if (spec.color_type == PNG_COLOR_TYPE_PALETTE && spec.bit_depth == 8) {
      for (png_byte& b : row)
        b = png_byte(b % palette.size());
    }
    pointers.push_back(row.data());
  }
  png_write_image(png, pointers.data());
  png_write_end(png, nullptr);
  png_destroy_write_struct(&png, &info);
  return out;
}

// stb's RGBA8 decoding as packed texels, or empty.
std::vector<uint32_t> stb_rgba8(const std::vector<unsigned char>& bytes, int& w, int& h) {
  int c = 0;
  unsigned char* p = stbi_load_from_memory(bytes.data(), int(bytes.size()), &w, &h, &c, 4);
  if (p == nullptr) return {};
  std::vector<uint32_t> out(size_t(w) * size_t(h));
  std::memcpy(out.data(), p, out.size() * 4);
  stbi_image_free(p);
  return out;
}

TEST(ScenesPng, EveryLayoutDecodesToStbsPixels) {
  const PngSpec specs[] = {
      {PNG_COLOR_TYPE_GRAY, 1, false, false},       {PNG_COLOR_TYPE_GRAY, 2, true, false},
      {PNG_COLOR_TYPE_GRAY, 4, false, true},        {PNG_COLOR_TYPE_GRAY, 8, true, true},
      {PNG_COLOR_TYPE_GRAY_ALPHA, 8, false, false}, {PNG_COLOR_TYPE_RGB, 8, false, false},
      {PNG_COLOR_TYPE_RGB, 8, true, true},          {PNG_COLOR_TYPE_RGB_ALPHA, 8, true, false},
      {PNG_COLOR_TYPE_RGB_ALPHA, 8, false, false},  {PNG_COLOR_TYPE_PALETTE, 1, false, false},
      {PNG_COLOR_TYPE_PALETTE, 4, true, true},      {PNG_COLOR_TYPE_PALETTE, 8, false, true},
  };
  uint32_t seed = 1;
  for (const PngSpec& spec : specs) {
    SCOPED_TRACE("colour type " + std::to_string(spec.color_type) + ", " +
                 std::to_string(spec.bit_depth) + " bits" +
                 (spec.interlaced ? ", interlaced" : "") + (spec.trns ? ", tRNS" : ""));
    const std::vector<unsigned char> png = make_png(spec, 37, 23, seed++);
    int w = 0, h = 0;
    const std::vector<uint32_t> expected = stb_rgba8(png, w, h);
    ASSERT_FALSE(expected.empty());
    uint32_t dw = 0, dh = 0;
    std::vector<uint32_t> got;
    std::string error;
    ASSERT_TRUE(gltf::decode_png_rgba8(png.data(), png.size(), dw, dh, got, error)) << error;
    EXPECT_EQ(dw, uint32_t(w));
    EXPECT_EQ(dh, uint32_t(h));
    EXPECT_EQ(got, expected);
  }
}

TEST(ScenesPng, TheSharedModelsTexturesDecodeToStbsPixels) {
  const fs::path shared = fs::path(TANDEM_SHARED_DIR) / "scenes";
  size_t compared = 0;
  for (const auto& entry : fs::recursive_directory_iterator(shared)) {
    if (entry.path().extension() != ".png" || entry.file_size() > (size_t(1) << 20)) continue;
    std::ifstream in(entry.path(), std::ios::binary);
    const std::vector<unsigned char> bytes{std::istreambuf_iterator<char>(in), {}};
    if (bytes.size() < 26 || bytes[24] != 8) continue;  // 8-bit PNGs only
    int w = 0, h = 0;
    const std::vector<uint32_t> expected = stb_rgba8(bytes, w, h);
    uint32_t dw = 0, dh = 0;
    std::vector<uint32_t> got;
    std::string error;
    ASSERT_TRUE(gltf::decode_png_rgba8(bytes.data(), bytes.size(), dw, dh, got, error))
        << entry.path() << ": " << error;
    EXPECT_EQ(got, expected) << entry.path();
    ++compared;
  }
  EXPECT_GE(compared, 5u);
}

TEST(ScenesPng, DamagedFilesAreErrorsNotCrashes) {
  const std::vector<unsigned char> good =
      make_png({PNG_COLOR_TYPE_RGB_ALPHA, 8, true, false}, 64, 40, 99);
  std::mt19937 rng(5);
  size_t errors = 0;
  for (size_t cut : {size_t(8), size_t(33), good.size() / 2, good.size() - 16}) {
    uint32_t w = 0, h = 0;
    std::vector<uint32_t> px;
    std::string error;
    EXPECT_FALSE(gltf::decode_png_rgba8(good.data(), cut, w, h, px, error)) << cut;
    EXPECT_NE(error.find("could not be decoded"), std::string::npos) << error;
  }
  for (int trial = 0; trial < 300; ++trial) {
    std::vector<unsigned char> bad = good;
    bad[33 + rng() % (bad.size() - 33)] ^= uint8_t(1u << (rng() % 8));
    uint32_t w = 0, h = 0;
    std::vector<uint32_t> px;
    std::string error;
    if (!gltf::decode_png_rgba8(bad.data(), bad.size(), w, h, px, error)) {
      ++errors;
      EXPECT_TRUE(px.empty());
    } else {
      EXPECT_EQ(px.size(), size_t(w) * h);
    }
  }
  EXPECT_GT(errors, 100u);  // libpng checks every chunk's CRC
}

}  // namespace
}  // namespace tandem
