// OpenEXR as users' tools write it: every compression, half and float,
// tiled mipmaps, multi-part and multi-layer files (Blender's layout),
// luminance-only images; and damaged files, which must be errors naming
// the file, never a crash. Files are written here with the OpenEXR
// library itself, the way other applications make them.
#include <ImfChannelList.h>
#include <ImfFrameBuffer.h>
#include <ImfHeader.h>
#include <ImfMultiPartOutputFile.h>
#include <ImfOutputFile.h>
#include <ImfOutputPart.h>
#include <ImfPartType.h>
#include <ImfTiledOutputFile.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "core/image/image.h"
#include "core/util/errors.h"
#include "core/util/log.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

// A smooth high-dynamic-range test image with a few bright spots, of an
// odd size so that chunks (16 or 32 scanlines) and tiles end part-way.
ImageRGB test_image(uint32_t w = 67, uint32_t h = 45) {
  ImageRGB img(w, h);
  for (uint32_t y = 0; y < h; ++y) {
    for (uint32_t x = 0; x < w; ++x) {
      float* p = img.pixel(x, y);
      p[0] = 0.05f + 0.9f * float(x) / float(w);
      p[1] = 0.02f + 0.5f * float(y) / float(h);
      p[2] = 0.3f + 0.2f * std::sin(0.3f * float(x + y));
      if ((x * 7 + y * 3) % 97 == 0) p[0] = p[1] = p[2] = 900.0f;
    }
  }
  return img;
}

std::vector<uint8_t> read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return std::vector<uint8_t>(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const fs::path& path, const std::vector<uint8_t>& bytes) {
  std::ofstream(path, std::ios::binary)
      .write(reinterpret_cast<const char*>(bytes.data()), std::streamsize(bytes.size()));
}

std::string read_error(const fs::path& path, const ImageReadLimits& limits = {}) {
  try {
    read_image(path, limits);
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

// Warnings while alive, instead of stderr.
class CapturedLog {
 public:
  CapturedLog() {
    set_log_sink([this](LogLevel, const std::string& m) { messages_ += m + "\n"; });
  }
  ~CapturedLog() { set_log_sink(nullptr); }
  const std::string& text() const { return messages_; }

 private:
  std::string messages_;
};

// One channel's slice of an interleaved float RGB image.
Imf::Slice slice(const ImageRGB& img, int channel) {
  return Imf::Slice(Imf::FLOAT,
                    reinterpret_cast<char*>(const_cast<float*>(img.rgb.data()) + channel),
                    3 * sizeof(float), 3 * sizeof(float) * img.width);
}

// The same as half values (a HALF channel is written from a HALF slice).
struct HalfImage {
  explicit HalfImage(const ImageRGB& img)
      : width(img.width), values(img.rgb.begin(), img.rgb.end()) {}
  Imf::Slice slice(int channel) {
    return Imf::Slice(Imf::HALF, reinterpret_cast<char*>(values.data() + channel),
                      3 * sizeof(Imath::half), 3 * sizeof(Imath::half) * width);
  }
  uint32_t width;
  std::vector<Imath::half> values;
};

TEST(ImageExr, EveryCompressionReadsBackWhatWasWritten) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image();
  const char* const compressions[] = {"none",  "rle", "zips", "zip",  "piz",
                                      "pxr24", "b44", "b44a", "dwaa", "dwab"};
  for (const char* type : {"float", "half"}) {
    for (const char* name : compressions) {
      SCOPED_TRACE(std::string(type) + " " + name);
      ImageWriteOptions options;
      options.exr_pixel_type = parse_exr_pixel_type(type);
      options.exr_compression = parse_exr_compression(name);
      const fs::path file = dir.path() / (std::string(type) + "_" + name + ".exr");
      write_image(file, src, options);
      const ImageRGB back = read_image(file);
      ASSERT_EQ(back.width, src.width);
      ASSERT_EQ(back.height, src.height);
      const std::string n = name;
      const bool half = std::string(type) == "half";
      // Lossless for the type: exact for float, one half rounding for
      // half. PXR24 keeps 15 mantissa bits of a float; DWA is lossy, B44
      // for half channels (it stores float channels losslessly).
      const bool lossy = n == "dwaa" || n == "dwab" || (half && (n == "b44" || n == "b44a"));
      const double max_rel = lossy ? 0.25 : half ? 1.0 / 2048 : n == "pxr24" ? 1.0 / 32768 : 0.0;
      double mean_rel = 0.0, worst = 0.0;
      for (size_t i = 0; i < src.rgb.size(); ++i) {
        const double rel = std::abs(double(back.rgb[i]) - src.rgb[i]) / std::abs(src.rgb[i]);
        mean_rel += rel / double(src.rgb.size());
        worst = std::max(worst, rel);
      }
      EXPECT_LE(worst, max_rel);
      EXPECT_LE(mean_rel, lossy ? 0.03 : max_rel);
    }
  }
}

TEST(ImageExr, OutputIsZipCompressedFloatByDefault) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(256, 128);
  const fs::path file = dir.path() / "default.exr";
  write_image(file, src);
  const std::vector<uint8_t> bytes = read_bytes(file);
  const std::string text(bytes.begin(), bytes.end());
  // The compression attribute: name, type, size 1, value 3 (ZIP).
  const std::string zip_attribute = std::string("compression\0compression\0\1\0\0\0\3", 29);
  EXPECT_NE(text.find(zip_attribute), std::string::npos);
  // Three FLOAT (type 2) channels B, G, R.
  const std::string float_b = std::string("B\0\2\0\0\0", 6);
  EXPECT_NE(text.find(float_b), std::string::npos);
  EXPECT_LT(bytes.size(), src.rgb.size() * sizeof(float) / 2);  // it compresses a smooth image
  EXPECT_EQ(read_image(file).rgb, src.rgb);
}

TEST(ImageExr, BlenderMultiLayerFileReadsTheCombinedPassWithANotice) {
  TempDir dir("tandem_exr");
  const ImageRGB combined = test_image(40, 20);
  ImageRGB diffuse(40, 20);
  for (float& v : diffuse.rgb)
    v = 7.0f;
  HalfImage combined_half(combined), diffuse_half(diffuse);
  // Blender's multilayer layout: "<view layer>.<pass>.<channel>", sorted.
  Imf::Header header(40, 20);
  header.compression() = Imf::PIZ_COMPRESSION;
  Imf::FrameBuffer frame;
  const char* rgb[3] = {"R", "G", "B"};
  for (int c = 0; c < 3; ++c) {
    for (const auto& [layer, img] : {std::pair<const char*, HalfImage*>{"DiffCol", &diffuse_half},
                                     {"Combined", &combined_half}}) {
      const std::string name = std::string("ViewLayer.") + layer + "." + rgb[c];
      header.channels().insert(name, Imf::Channel(Imf::HALF));
      frame.insert(name, img->slice(c));
    }
  }
  header.channels().insert("ViewLayer.Depth.Z", Imf::Channel(Imf::FLOAT));
  frame.insert("ViewLayer.Depth.Z", slice(diffuse, 0));
  const fs::path file = dir.path() / "multilayer.exr";
  {
    Imf::OutputFile out(file.c_str(), header);
    out.setFrameBuffer(frame);
    out.writePixels(20);
  }
  CapturedLog log;
  const ImageRGB back = read_image(file);
  for (size_t i = 0; i < back.rgb.size(); ++i)
    ASSERT_NEAR(back.rgb[i], combined.rgb[i], combined.rgb[i] / 1024) << i;
  EXPECT_NE(log.text().find(file.string() + ": reading layer 'ViewLayer.Combined' of part 0; not "
                                            "read: layer 'ViewLayer.DiffCol'"),
            std::string::npos)
      << log.text();
}

TEST(ImageExr, MultiPartFileReadsTheFirstColourPart) {
  TempDir dir("tandem_exr");
  const ImageRGB beauty = test_image(30, 17);
  std::vector<Imf::Header> headers(3, Imf::Header(30, 17));
  const char* names[3] = {"depth", "beauty", "extra"};
  for (int p = 0; p < 3; ++p) {
    headers[p].setName(names[p]);
    headers[p].setType(Imf::SCANLINEIMAGE);
    headers[p].compression() = Imf::ZIP_COMPRESSION;
    if (p == 0) {
      headers[p].channels().insert("Z", Imf::Channel(Imf::FLOAT));
    } else {
      for (const char* c : {"R", "G", "B"})
        headers[p].channels().insert(c, Imf::Channel(Imf::FLOAT));
    }
  }
  const fs::path file = dir.path() / "parts.exr";
  {
    Imf::MultiPartOutputFile out(file.c_str(), headers.data(), 3);
    for (int p = 0; p < 3; ++p) {
      Imf::OutputPart part(out, p);
      Imf::FrameBuffer frame;
      if (p == 0) {
        frame.insert("Z", slice(beauty, 0));
      } else {
        for (int c = 0; c < 3; ++c)
          frame.insert(c == 0 ? "R" : c == 1 ? "G" : "B", slice(beauty, c));
      }
      part.setFrameBuffer(frame);
      part.writePixels(17);
    }
  }
  CapturedLog log;
  EXPECT_EQ(read_image(file).rgb, beauty.rgb);
  EXPECT_NE(log.text().find("reading the unnamed layer of part 1; not read: part 'extra'"),
            std::string::npos)
      << log.text();
}

TEST(ImageExr, TiledMipmappedFileReadsItsFullResolutionLevel) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(50, 37);
  Imf::Header header(50, 37);
  header.setTileDescription(Imf::TileDescription(16, 16, Imf::MIPMAP_LEVELS));
  header.compression() = Imf::PIZ_COMPRESSION;
  for (const char* c : {"R", "G", "B"})
    header.channels().insert(c, Imf::Channel(Imf::FLOAT));
  const fs::path file = dir.path() / "tiled.exr";
  {
    Imf::TiledOutputFile out(file.c_str(), header);
    for (int level = 0; level < out.numLevels(); ++level) {
      // Every level from the full-resolution image (nearest texel): the
      // reader must take level 0, whose pixels are src.
      const int lw = out.levelWidth(level), lh = out.levelHeight(level);
      ImageRGB img{uint32_t(lw), uint32_t(lh)};
      for (int y = 0; y < lh; ++y)
        for (int x = 0; x < lw; ++x)
          for (int c = 0; c < 3; ++c)
            img.pixel(uint32_t(x), uint32_t(y))[c] =
                src.pixel(uint32_t(x << level), uint32_t(y << level))[c];
      Imf::FrameBuffer frame;
      for (int c = 0; c < 3; ++c)
        frame.insert(c == 0 ? "R" : c == 1 ? "G" : "B", slice(img, c));
      out.setFrameBuffer(frame);
      out.writeTiles(0, out.numXTiles(level) - 1, 0, out.numYTiles(level) - 1, level);
    }
  }
  EXPECT_EQ(read_image(file).rgb, src.rgb);
}

TEST(ImageExr, LuminanceOnlyFileIsGrey) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(9, 5);
  Imf::Header header(9, 5);
  header.channels().insert("Y", Imf::Channel(Imf::HALF));
  const fs::path file = dir.path() / "grey.exr";
  HalfImage src_half(src);
  {
    Imf::OutputFile out(file.c_str(), header);
    Imf::FrameBuffer frame;
    frame.insert("Y", src_half.slice(1));
    out.setFrameBuffer(frame);
    out.writePixels(5);
  }
  const ImageRGB back = read_image(file);
  for (uint32_t y = 0; y < 5; ++y) {
    for (uint32_t x = 0; x < 9; ++x) {
      const float want = src.pixel(x, y)[1];
      for (int c = 0; c < 3; ++c)
        ASSERT_NEAR(back.pixel(x, y)[c], want, want / 1024);
    }
  }
}

TEST(ImageExr, FilesWithoutColourOrOverTheLimitsAreRefusedBeforeDecoding) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(600, 400);
  auto write_channels = [&](const fs::path& file, const char* name, Imf::PixelType type) {
    Imf::Header header(600, 400);
    header.channels().insert(name, Imf::Channel(type));
    std::vector<uint32_t> ids(600 * 400, 3);
    Imf::OutputFile out(file.c_str(), header);
    Imf::FrameBuffer frame;
    if (type == Imf::UINT) {
      frame.insert(name, Imf::Slice(Imf::UINT, reinterpret_cast<char*>(ids.data()), 4, 4 * 600));
    } else {
      frame.insert(name, slice(src, 0));
    }
    out.setFrameBuffer(frame);
    out.writePixels(400);
  };
  const fs::path ids = dir.path() / "ids.exr";
  write_channels(ids, "R", Imf::UINT);
  EXPECT_NE(read_error(ids).find(ids.string() + ": OpenEXR channel 'R' holds unsigned integers"),
            std::string::npos)
      << read_error(ids);
  const fs::path depth = dir.path() / "depth.exr";
  write_channels(depth, "Z", Imf::FLOAT);
  EXPECT_NE(read_error(depth).find(depth.string() +
                                   ": OpenEXR file has no colour image: no R, G, B or Y channel "
                                   "(it has 1 channels, the first 'Z')"),
            std::string::npos)
      << read_error(depth);
  const fs::path big = dir.path() / "big.exr";
  write_image(big, src);
  ImageReadLimits limits;
  limits.max_pixels = 1000;
  EXPECT_NE(read_error(big, limits).find("OpenEXR header claims 600x400 pixels, over the limit"),
            std::string::npos);
}

TEST(ImageExr, TilesFarLargerThanTheImageAreRefused) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(8, 8);
  Imf::Header header(8, 8);
  header.setTileDescription(Imf::TileDescription(2048, 1024, Imf::ONE_LEVEL));
  header.channels().insert("R", Imf::Channel(Imf::FLOAT));
  const fs::path file = dir.path() / "tiles.exr";
  {
    Imf::TiledOutputFile out(file.c_str(), header);
    Imf::FrameBuffer frame;
    frame.insert("R", slice(src, 0));
    out.setFrameBuffer(frame);
    out.writeTiles(0, 0, 0, 0);
  }
  EXPECT_NE(read_error(file).find(file.string() +
                                  ": OpenEXR tiles of 2048x1024 pixels are larger than the 8x8"),
            std::string::npos)
      << read_error(file);
}

// Damage as downloads and disks do it: cut files and flipped bytes, in
// files of each common compression. Every outcome is an image of the
// right size or an InputError naming the file; never a crash.
TEST(ImageExr, DamagedCompressedFilesAreErrorsNotCrashes) {
  TempDir dir("tandem_exr");
  const ImageRGB src = test_image(64, 40);
  std::mt19937 rng(12345);
  for (const char* compression : {"zip", "piz", "dwaa", "b44", "rle", "pxr24"}) {
    SCOPED_TRACE(compression);
    ImageWriteOptions options;
    options.exr_pixel_type = ExrPixelType::kHalf;
    options.exr_compression = parse_exr_compression(compression);
    const fs::path good = dir.path() / (std::string(compression) + ".exr");
    write_image(good, src, options);
    const std::vector<uint8_t> bytes = read_bytes(good);
    const fs::path bad = dir.path() / "bad.exr";
    // Cut anywhere past the magic number.
    for (size_t cut : {size_t(8), bytes.size() / 4, bytes.size() / 2, bytes.size() - 1}) {
      write_bytes(bad, std::vector<uint8_t>(bytes.begin(), bytes.begin() + long(cut)));
      const std::string error = read_error(bad);
      EXPECT_EQ(error.rfind(bad.string() + ": ", 0), 0u) << "cut at " << cut << ": " << error;
    }
    int errors = 0;
    for (int trial = 0; trial < 150; ++trial) {
      std::vector<uint8_t> damaged = bytes;
      for (int k = 0; k < 4; ++k)
        damaged[8 + rng() % (damaged.size() - 8)] ^= uint8_t(1u << (rng() % 8));
      write_bytes(bad, damaged);
      try {
        const ImageRGB img = read_image(bad);
        EXPECT_EQ(img.rgb.size(), src.rgb.size());
      } catch (const InputError& e) {
        ++errors;
        EXPECT_EQ(std::string(e.what()).rfind(bad.string() + ": ", 0), 0u) << e.what();
      }
    }
    EXPECT_GT(errors, 0);  // the damage was seen at least sometimes
  }
}

TEST(ImageExr, OptionsNameTheirValues) {
  EXPECT_EQ(parse_exr_compression("piz"), ExrCompression::kPiz);
  EXPECT_EQ(parse_exr_compression("dwab"), ExrCompression::kDwab);
  EXPECT_EQ(parse_exr_pixel_type("half"), ExrPixelType::kHalf);
  EXPECT_THROW(parse_exr_compression("zip2"), UsageError);
  EXPECT_THROW(parse_exr_pixel_type("double"), UsageError);
}

}  // namespace
}  // namespace tandem
