// Textured materials through the API: a texture multiplies its factor as in
// glTF (a white one changes nothing, bit for bit), one texture serves
// several materials, a material can switch textures between frames, and
// bad textures or texture ids are errors that add nothing.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <string>
#include <vector>

#include "api_test_scene.h"

namespace {

using tandem::Error;
using namespace tandem_api_test;

std::vector<uint8_t> solid(uint32_t w, uint32_t h, uint8_t r, uint8_t g, uint8_t b) {
  std::vector<uint8_t> px(size_t(w) * h * 4);
  for (size_t i = 0; i < px.size(); i += 4)
    px[i] = r, px[i + 1] = g, px[i + 2] = b, px[i + 3] = 255;
  return px;
}

// A black and white checkerboard of 4x4 texels.
std::vector<uint8_t> checker() {
  std::vector<uint8_t> px(4 * 4 * 4);
  for (uint32_t y = 0; y < 4; ++y)
    for (uint32_t x = 0; x < 4; ++x) {
      const uint8_t v = (x + y) % 2 ? 255 : 0;
      uint8_t* p = &px[(y * 4 + x) * 4];
      p[0] = p[1] = p[2] = v, p[3] = 255;
    }
  return px;
}

// The floor and square of build_scene, the floor's material textured.
std::vector<float> render_floor(tandem::RendererOptions o, const std::vector<uint8_t>* pixels,
                                bool nearest = false) {
  tandem::Renderer r(o);
  const Quad floor(4.0f);
  tandem::MaterialDesc grey;
  if (pixels != nullptr) {
    tandem::TextureDesc t;
    t.width = t.height = uint32_t(std::lround(std::sqrt(double(pixels->size() / 4))));  // square
    t.rgba8 = pixels->data();
    t.nearest = nearest;
    grey.base_color_texture = r.add_texture(t);
  }
  r.add_instance(r.add_mesh(floor.data(), r.add_material(grey)), tandem::Transform::identity());
  add_light_and_camera(r);
  r.render_frame();
  return r.image_linear();
}

TEST(ApiTextures, ATextureMultipliesItsFactor) {
  const std::vector<float> plain = render_floor(small_options(), nullptr);
  const std::vector<uint8_t> white = solid(8, 8, 255, 255, 255);
  // sRGB 255 is exactly 1: the same light, up to the noise of a path that
  // draws its texture lookups from the sample's random numbers.
  tandem::RendererOptions many = small_options();
  many.samples_per_frame = 64;
  const std::vector<float> plain_many = render_floor(many, nullptr);
  const std::vector<float> white_many = render_floor(many, &white);
  EXPECT_NEAR(mean(white_many), mean(plain_many), 0.01 * mean(plain_many));
  const std::vector<uint8_t> board = checker();
  const std::vector<float> checked = render_floor(small_options(), &board, true);
  // Half the floor's texels are black: about half the light, and a pattern.
  EXPECT_LT(mean(checked), 0.75 * mean(plain));
  EXPECT_GT(mean(checked), 0.25 * mean(plain));
  size_t dark = 0;
  for (size_t i = 0; i < checked.size(); i += 3)
    dark += plain[i] > 0.05f && checked[i] < 0.01f * plain[i];
  EXPECT_GT(dark, checked.size() / 3 / 8) << "no black squares on the floor";
}

TEST(ApiTextures, MaterialsShareTexturesAndSwitchThemBetweenFrames) {
  tandem::Renderer r(small_options());
  build_scene(r);  // materials 0 (floor, grey) and 1 (square, red)
  const std::vector<uint8_t> board = checker();
  const std::vector<uint8_t> white = solid(4, 4, 255, 255, 255);
  tandem::TextureDesc t;
  t.width = t.height = 4;
  t.rgba8 = board.data();
  t.nearest = true;
  const tandem::TextureId board_id = r.add_texture(t);
  t.rgba8 = white.data();
  const tandem::TextureId white_id = r.add_texture(t);
  EXPECT_EQ(r.texture_count(), 2u);
  tandem::MaterialDesc grey, red;
  red.base_color[0] = 0.9f, red.base_color[1] = 0.1f, red.base_color[2] = 0.1f;
  grey.base_color_texture = board_id;
  red.base_color_texture = board_id;
  r.set_material({0}, grey);
  r.set_material({1}, red);
  const std::vector<float> first = (r.render_frame(), r.image_linear());
  grey.base_color_texture = white_id;
  r.set_material({0}, grey);
  const tandem::FrameInfo f = r.render_frame();
  EXPECT_TRUE(f.accumulation_reset);
  EXPECT_GT(mean(r.image_linear()), mean(first));
}

TEST(ApiTextures, BadTexturesAndIdsAreErrorsThatAddNothing) {
  tandem::Renderer r(small_options());
  const std::vector<uint8_t> px = solid(2, 2, 1, 2, 3);
  tandem::TextureDesc t;
  t.width = t.height = 2;
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(t); });  // null pixels
  t.rgba8 = px.data();
  t.width = 0;
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(t); });
  t.width = 20000;
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(t); })
                .find("20000x2 texture is empty or wider or taller than 16384"),
            std::string::npos);
  t.width = 2;
  t.wrap_u = tandem::TextureWrap(7);
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(t); });
  EXPECT_EQ(r.texture_count(), 0u);
  tandem::MaterialDesc m;
  m.emission_texture = tandem::TextureId{0};
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { r.add_material(m); })
                .find("add_material: emission_texture 0 does not exist (there are 0 textures)"),
            std::string::npos);
  EXPECT_EQ(r.material_count(), 0u);
  t.wrap_u = tandem::TextureWrap::kClampToEdge;
  m.emission_texture = r.add_texture(t);
  EXPECT_EQ(r.add_material(m).index, 0u);
}

}  // namespace
