// Every call of the API with what a buggy or hostile host passes: NaN,
// infinities, huge and out-of-range values in every float field, and ids
// that no longer exist (after clear_scene or load_gltf). Each must be a
// tandem::Error of the documented kind, never a signal, and must leave the
// renderer working: it renders a frame after every refusal.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "api_test_scene.h"
#include "test_temp_dir.h"

namespace {

using tandem::Error;
using namespace tandem_api_test;

const float kBad[] = {std::numeric_limits<float>::quiet_NaN(),
                      std::numeric_limits<float>::infinity(),
                      -std::numeric_limits<float>::infinity(), 3e38f, -3e38f};

struct Built {
  tandem::MaterialId material;
  tandem::MeshId mesh;
  tandem::InstanceId instance;
  tandem::LightId light;
  tandem::TextureId texture;
};

Built build(tandem::Renderer& r) {
  Built b;
  b.instance = build_scene(r);
  b.material = {1};
  b.mesh = {1};
  b.light = {0};
  const std::vector<uint8_t> px(4 * 4, 200);
  tandem::TextureDesc t;
  t.width = t.height = 2;
  t.rgba8 = px.data();
  b.texture = r.add_texture(t);
  return b;
}

// After a refused or accepted call the renderer still renders, and its
// image holds only finite values.
void expect_still_renders(tandem::Renderer& r, const std::string& what) {
  if (r.instance_count() == 0) return;
  EXPECT_NO_THROW(r.render_frame()) << "after " << what;
  for (float v : r.image_linear()) {
    if (!std::isfinite(v)) {
      ADD_FAILURE() << "after " << what << ": a pixel of " << v;
      return;
    }
  }
}

// `call` must throw a tandem::Error of `kind`. With `may_accept`, a huge
// but finite value may also be taken (a light direction is normalised, an
// instance beyond the traceable range is documented as not drawn).
void expect_refused(tandem::Renderer& r, Error::Kind kind, const std::string& what,
                    const std::function<void()>& call, bool may_accept = false) {
  try {
    call();
    if (!may_accept) ADD_FAILURE() << what << ": accepted";
  } catch (const Error& e) {
    EXPECT_EQ(int(e.kind()), int(kind)) << what << ": " << e.what();
  }
  expect_still_renders(r, what);
}

TEST(ApiHostile, EveryFloatFieldRefusesNanInfinityAndHugeValues) {
  tandem::Renderer r(small_options());
  const Built b = build(r);
  const auto arg = Error::Kind::kInvalidArgument;
  for (float v : kBad) {
    const std::string value = std::to_string(v);
    const bool finite = std::isfinite(v);
    constexpr int kMaterialFields = 16;
    for (int field = 0; field < kMaterialFields; ++field) {
      tandem::MaterialDesc m;
      float* fields[kMaterialFields] = {&m.base_color[0],
                                        &m.roughness,
                                        &m.metallic,
                                        &m.emission[1],
                                        &m.emission_strength,
                                        &m.transmission,
                                        &m.ior,
                                        &m.alpha,
                                        &m.alpha_cutoff,
                                        &m.specular,
                                        &m.specular_color[2],
                                        &m.clearcoat,
                                        &m.clearcoat_roughness,
                                        &m.sheen_color[1],
                                        &m.sheen_roughness,
                                        &m.normal_scale};
      *fields[field] = v;
      if (field == 4 && v == 3e38f) continue;  // a strength alone may be large (emission is 0)
      expect_refused(r, arg, "material field " + std::to_string(field) + " = " + value,
                     [&] { r.set_material(b.material, m); });
    }
    for (int field = 0; field < 6; ++field) {
      tandem::LightDesc l;
      l.kind = tandem::LightKind::kSpot;
      float* fields[6] = {&l.position[0], &l.direction[2],     &l.color[1],
                          &l.intensity,   &l.inner_cone_angle, &l.outer_cone_angle};
      *fields[field] = v;
      expect_refused(
          r, arg, "light field " + std::to_string(field) + " = " + value,
          [&] { r.set_light(b.light, l); }, finite);
    }
    for (int field = 0; field < 6; ++field) {
      tandem::CameraDesc c;
      float* fields[6] = {&c.position[1],  &c.target[0],       &c.up[2],
                          &c.vertical_fov, &c.aperture_radius, &c.focus_distance};
      *fields[field] = v;
      expect_refused(
          r, arg, "camera field " + std::to_string(field) + " = " + value, [&] { r.set_camera(c); },
          finite);
    }
    for (int k : {0, 5, 12, 15}) {
      tandem::Transform t;
      t.m[k] = v;
      expect_refused(
          r, arg, "transform entry " + std::to_string(k) + " = " + value,
          [&] { r.set_instance_transform(b.instance, t); }, finite);
    }
    Quad q(1.0f);
    q.positions[4] = v;
    expect_refused(
        r, arg, "vertex = " + value, [&] { r.set_mesh_vertices(b.mesh, q.data()); }, finite);
    Quad n(1.0f);
    n.normals[2] = v;
    expect_refused(
        r, arg, "normal = " + value, [&] { r.add_mesh(n.data(), b.material); }, finite);
    Quad uv(1.0f);
    uv.uvs[3] = v;
    expect_refused(
        r, arg, "uv = " + value, [&] { r.add_mesh(uv.data(), b.material); }, finite);
    expect_refused(r, arg, "environment colour = " + value,
                   [&] { r.set_environment_color(1.0f, v, 1.0f); });
    expect_refused(r, arg, "sky intensity = " + value,
                   [&] { r.use_default_sky(std::isnan(v) || v < 0 ? v : -v); });
    if (!std::isfinite(v)) {
      expect_refused(r, arg, "exposure = " + value, [&] { r.image_srgb8(v); });
      expect_refused(r, arg, "sky rotation = " + value, [&] { r.use_default_sky(1.0f, v); });
    }
  }
  // Only the huge-but-finite normals and uvs were added (2 values x 2).
  EXPECT_EQ(r.mesh_count(), 2u + 4u);
}

TEST(ApiHostile, IdsThatNoLongerExistAreRefused) {
  tandem::TempDir dir("api_hostile_ids");
  const std::filesystem::path file = dir.path() / "triangle.gltf";
  write_triangle_gltf(file, "", "");
  for (int replace = 0; replace < 2; ++replace) {
    tandem::Renderer r(small_options());
    const Built b = build(r);
    r.render_frame();
    if (replace == 0) {
      r.clear_scene();
    } else {
      r.load_gltf(file.string());  // one mesh, one instance, one material, no light or texture
    }
    const auto arg = Error::Kind::kInvalidArgument;
    const std::string when = replace == 0 ? " after clear_scene" : " after load_gltf";
    const Quad q(1.0f);
    tandem::MaterialDesc textured;
    textured.base_color_texture = b.texture;
    expect_refused(r, arg, "set_material" + when, [&] { r.set_material(b.material, {}); });
    expect_refused(r, arg, "texture" + when, [&] { r.add_material(textured); });
    expect_refused(r, arg, "set_mesh_vertices" + when,
                   [&] { r.set_mesh_vertices(b.mesh, q.data()); });
    expect_refused(r, arg, "add_instance" + when,
                   [&] { r.add_instance(b.mesh, tandem::Transform::identity()); });
    expect_refused(r, arg, "set_instance_transform" + when,
                   [&] { r.set_instance_transform(b.instance, tandem::Transform::identity()); });
    expect_refused(r, arg, "set_light" + when, [&] { r.set_light(b.light, {}); });
    expect_refused(r, arg, "add_mesh" + when, [&] { r.add_mesh(q.data(), {7}); });
    expect_refused(r, arg, "huge id" + when,
                   [&] { r.set_instance_transform({0xffffffffu}, tandem::Transform::identity()); });
  }
}

}  // namespace
