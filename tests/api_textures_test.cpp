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

// A floor whose material is `m` (its texture slots point into `textures`,
// added first in order), lit by the scene's light: the linear image.
std::vector<float> render_material(tandem::MaterialDesc m,
                                   const std::vector<tandem::TextureDesc>& textures,
                                   bool with_light = true) {
  tandem::Renderer r(small_options());
  for (const tandem::TextureDesc& t : textures)
    r.add_texture(t);
  const Quad floor(4.0f);
  r.add_instance(r.add_mesh(floor.data(), r.add_material(m)), tandem::Transform::identity());
  add_light_and_camera(r);
  if (!with_light) r.remove_light(tandem::LightId{0});
  r.render_frame();
  return r.image_linear();
}

tandem::TextureDesc desc(const std::vector<uint8_t>& px, uint32_t size) {
  tandem::TextureDesc t;
  t.width = t.height = size;
  t.rgba8 = px.data();
  return t;
}

// An 8-bit texture declared linear reads as a float texture of the same
// values (bit for bit), unlike the sRGB decode the base colour slot gives
// by default; a float emission texture carries radiance beyond 1.
TEST(ApiTextures, FloatTexturesCarryHdrAndColourSpacesAreTheCallersToChoose) {
  const std::vector<uint8_t> board = checker();
  std::vector<float> board_f(board.size());
  for (size_t i = 0; i < board.size(); ++i)
    board_f[i] = float(board[i]) * (1.0f / 255.0f);
  const std::vector<uint8_t> grey = solid(4, 4, 128, 128, 128);
  std::vector<float> grey_f(grey.size());
  for (size_t i = 0; i < grey.size(); ++i)
    grey_f[i] = float(grey[i]) * (1.0f / 255.0f);
  tandem::TextureDesc by_slot = desc(grey, 4), linear = by_slot, as_float = by_slot;
  linear.color_space = tandem::TextureColorSpace::kLinear;
  as_float.rgba8 = nullptr;
  as_float.rgba32f = grey_f.data();
  tandem::MaterialDesc m;
  m.base_color[0] = m.base_color[1] = m.base_color[2] = 1.0f;
  m.base_color_texture = tandem::TextureId{0};
  const std::vector<float> srgb_image = render_material(m, {by_slot});
  const std::vector<float> linear_image = render_material(m, {linear});
  EXPECT_EQ(linear_image, render_material(m, {as_float}));
  // sRGB 128 is about 0.216 linear, 128/255 about 0.502: the diffuse light
  // 2.3 times as much (the specular part, which the albedo does not scale,
  // brings the ratio down a little).
  EXPECT_GT(mean(linear_image) / mean(srgb_image), 1.9);
  EXPECT_LT(mean(linear_image) / mean(srgb_image), 0.502 / 0.216 + 0.01);
  // kSrgb in a linear slot (transmission) decodes: less transmission.
  tandem::TextureDesc srgb = by_slot;
  srgb.color_space = tandem::TextureColorSpace::kSrgb;
  tandem::MaterialDesc glass;
  glass.transmission = 1.0f;
  glass.transmission_texture = tandem::TextureId{0};
  EXPECT_NE(render_material(glass, {srgb}), render_material(glass, {by_slot}));

  // Emission only (no light, black sky): what the camera sees is the
  // emission times the texture, 4x for texels of 4.
  std::vector<float> four(4 * 4 * 4, 4.0f), one(4 * 4 * 4, 1.0f);
  tandem::TextureDesc hdr = by_slot;
  hdr.rgba8 = nullptr;
  hdr.rgba32f = four.data();
  tandem::TextureDesc unit = hdr;
  unit.rgba32f = one.data();
  tandem::MaterialDesc lamp;
  lamp.base_color[0] = lamp.base_color[1] = lamp.base_color[2] = 0.0f;
  lamp.emission[0] = lamp.emission[1] = lamp.emission[2] = 0.5f;
  lamp.emission_texture = tandem::TextureId{0};
  const std::vector<float> bright = render_material(lamp, {hdr}, false);
  const std::vector<float> dim = render_material(lamp, {unit}, false);
  EXPECT_GT(mean(dim), 0.05);
  EXPECT_NEAR(mean(bright), 4.0 * mean(dim), 1e-4 * mean(dim));

  // Bad float textures, and emission a float texture would overflow.
  tandem::Renderer r(small_options());
  tandem::TextureDesc both = by_slot;
  both.rgba32f = four.data();
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(both); });
  tandem::TextureDesc srgb_float = hdr;
  srgb_float.color_space = tandem::TextureColorSpace::kSrgb;
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(srgb_float); });
  for (float bad : {std::nanf(""), -1.0f, 2e6f, INFINITY}) {
    std::vector<float> px = four;
    px[5] = bad;
    tandem::TextureDesc t = hdr;
    t.rgba32f = px.data();
    EXPECT_NE(
        error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(t); }).find("rgba32f value 5"),
        std::string::npos);
  }
  EXPECT_EQ(r.texture_count(), 0u);
  std::vector<float> peak(4 * 4 * 4, 1e6f);
  hdr.rgba32f = peak.data();
  lamp.emission_texture = r.add_texture(hdr);
  lamp.emission_strength = 1e25f;
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_material(lamp); });
  lamp.emission_strength = 1e20f;
  r.add_material(lamp);
}

// The slots the glTF loader fills are all reachable: each texture changes
// the image, a masked-out square is not there at all, and bad enums are
// refused.
TEST(ApiTextures, EverySlotOfTheGltfMaterialIsReachable) {
  const std::vector<uint8_t> board = checker();
  const std::vector<tandem::TextureDesc> textures = {desc(board, 4)};
  const tandem::TextureId t{0};
  tandem::MaterialDesc base;
  base.roughness = 0.3f;
  base.clearcoat = 1.0f;
  base.clearcoat_roughness = 0.6f;
  base.sheen_color[0] = base.sheen_color[1] = base.sheen_color[2] = 1.0f;
  base.sheen_roughness = 0.5f;
  const std::vector<float> plain = render_material(base, textures);
  std::vector<tandem::TextureId tandem::MaterialDesc::*> slots = {
      &tandem::MaterialDesc::normal_texture, &tandem::MaterialDesc::clearcoat_texture,
      &tandem::MaterialDesc::clearcoat_roughness_texture,
      &tandem::MaterialDesc::sheen_color_texture, &tandem::MaterialDesc::sheen_roughness_texture};
  for (size_t i = 0; i < slots.size(); ++i) {
    tandem::MaterialDesc m = base;
    m.*slots[i] = t;
    EXPECT_NE(render_material(m, textures), plain) << "slot " << i;
  }

  // A square cut out by alpha: the floor alone, bit for bit.
  auto floor_and_square = [](float alpha, tandem::MaterialAlpha mode) {
    tandem::Renderer r(small_options());
    build_scene(r);
    tandem::MaterialDesc red;
    red.alpha = alpha;
    red.alpha_mode = mode;
    r.set_material(tandem::MaterialId{1}, red);
    r.render_frame();
    return r.image_linear();
  };
  tandem::Renderer floor_only(small_options());
  build_scene(floor_only, false);
  floor_only.render_frame();
  EXPECT_EQ(floor_and_square(0.25f, tandem::MaterialAlpha::kMask), floor_only.image_linear());
  EXPECT_NE(floor_and_square(0.25f, tandem::MaterialAlpha::kOpaque), floor_only.image_linear());
  EXPECT_NE(floor_and_square(0.25f, tandem::MaterialAlpha::kBlend), floor_only.image_linear());

  tandem::Renderer r(small_options());
  tandem::MaterialDesc bad;
  bad.alpha_mode = tandem::MaterialAlpha(9);
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_material(bad); });
  tandem::TextureDesc bad_space = textures[0];
  bad_space.color_space = tandem::TextureColorSpace(9);
  error_of(Error::Kind::kInvalidArgument, [&] { r.add_texture(bad_space); });
  tandem::MaterialDesc missing;
  missing.sheen_roughness_texture = tandem::TextureId{3};
  EXPECT_NE(error_of(Error::Kind::kInvalidArgument, [&] { r.add_material(missing); })
                .find("sheen_roughness_texture 3 does not exist"),
            std::string::npos);
}

}  // namespace
