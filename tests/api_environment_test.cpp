// Sky for a game's scene: a glTF file is lit by the built-in sky unless the
// host turns it off, and an environment map comes from a file, from the
// host's pixels (the same image either way) or the built-in sky; bad input
// is an Error that leaves the environment as it was.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "api_test_scene.h"
#include "test_temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tandem::Error;
using namespace tandem_api_test;

// An 8x4 sky: bright above the horizon, dim below, warmer towards +x.
std::vector<float> sky_pixels() {
  std::vector<float> rgb(8 * 4 * 3);
  for (int y = 0; y < 4; ++y) {
    for (int x = 0; x < 8; ++x) {
      float* p = &rgb[size_t(y * 8 + x) * 3];
      const float up = y < 2 ? 2.0f : 0.2f;
      p[0] = up * (1.0f + 0.1f * float(x));
      p[1] = up;
      p[2] = up * 1.5f;
    }
  }
  return rgb;
}

// The same pixels as a PFM file (rows bottom to top, little-endian).
void write_pfm(const fs::path& file, const std::vector<float>& rgb, int w, int h) {
  std::ofstream out(file, std::ios::binary);
  out << "PF\n" << w << " " << h << "\n-1.0\n";
  for (int row = h - 1; row >= 0; --row)
    out.write(reinterpret_cast<const char*>(&rgb[size_t(row) * size_t(w) * 3]),
              std::streamsize(size_t(w) * 3 * sizeof(float)));
}

std::vector<float> render(tandem::Renderer& r) {
  r.render_frame();
  return r.image_linear();
}

TEST(ApiEnvironment, AGltfSceneIsLitByTheBuiltInSkyUnlessTurnedOff) {
  tandem::TempDir dir("api_sky");
  const fs::path file = dir.path() / "triangle.gltf";  // no lights of its own
  write_triangle_gltf(file, "", "");
  tandem::Renderer lit(small_options());
  lit.load_gltf(file.string());
  EXPECT_GT(mean(render(lit)), 0.05);
  tandem::RendererOptions o = small_options();
  o.default_sky = false;
  tandem::Renderer dark(o);
  dark.load_gltf(file.string());
  EXPECT_EQ(mean(render(dark)), 0.0);
  // The built-in sky on request gives the lit image (a fresh renderer, so
  // that both images are of frame 0).
  tandem::Renderer asked(o);
  asked.load_gltf(file.string());
  asked.use_default_sky();
  tandem::Renderer lit_again(small_options());
  lit_again.load_gltf(file.string());
  EXPECT_EQ(render(asked), render(lit_again));
}

TEST(ApiEnvironment, AMapFromAFileOrFromPixelsIsTheSameSky) {
  tandem::TempDir dir("api_env");
  const std::vector<float> pixels = sky_pixels();
  const fs::path file = dir.path() / "sky.pfm";
  write_pfm(file, pixels, 8, 4);
  tandem::RendererOptions o = small_options();
  tandem::Renderer from_file(o), from_pixels(o);
  for (tandem::Renderer* r : {&from_file, &from_pixels})
    build_scene(*r);
  from_file.set_environment_map(file.string(), 2.0f, 0.5f);
  from_pixels.set_environment_pixels(8, 4, pixels.data(), 2.0f, 0.5f);
  const std::vector<float> a = render(from_file);
  EXPECT_EQ(a, render(from_pixels));
  // Intensity and rotation change the image.
  from_pixels.set_environment_pixels(8, 4, pixels.data(), 2.0f, 2.0f);
  EXPECT_NE(render(from_pixels), a);
}

TEST(ApiEnvironment, BadSkiesAreErrorsThatLeaveTheSkyAsItWas) {
  tandem::TempDir dir("api_env_bad");
  tandem::Renderer r(small_options());
  build_scene(r);
  const std::vector<float> pixels = sky_pixels();
  r.set_environment_pixels(8, 4, pixels.data());
  EXPECT_EQ(r.render_frame().accumulated_spp, 2u);
  const std::string missing = (dir.path() / "none.exr").string();
  EXPECT_NE(error_of(Error::Kind::kFile, [&] { r.set_environment_map(missing); }).find(missing),
            std::string::npos);
  std::vector<float> nan_pixels = pixels;
  nan_pixels[5] = std::nanf("");
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument,
                     [&] { r.set_environment_pixels(8, 4, nan_pixels.data()); })
                .find("value 5 is not a finite number >= 0"),
            std::string::npos);
  error_of(Error::Kind::kInvalidArgument, [&] { r.set_environment_pixels(0, 4, pixels.data()); });
  error_of(Error::Kind::kInvalidArgument, [&] { r.set_environment_pixels(8, 4, nullptr); });
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.set_environment_pixels(100000, 100000, pixels.data()); });
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.set_environment_pixels(8, 4, pixels.data(), -1.0f); });
  error_of(Error::Kind::kInvalidArgument, [&] { r.use_default_sky(1.0f, INFINITY); });
  // A radiance float sums cannot hold renders black: refused.
  error_of(Error::Kind::kInvalidArgument,
           [&] { r.set_environment_pixels(8, 4, pixels.data(), 3e38f); });
  // Nothing changed: the next frame adds to the image instead of restarting it.
  const tandem::FrameInfo after = r.render_frame();
  EXPECT_FALSE(after.accumulation_reset);
  EXPECT_EQ(after.accumulated_spp, 4u);
}

}  // namespace
