// The public API (<tandem/tandem.h>) as an application uses it: only that
// header is on this binary's include path (no engine header, no glm), scenes
// are built from plain arrays, and every bad input is a tandem::Error of
// the documented kind, never a crash, with the renderer unchanged.
#include <tandem/tandem.h>

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "api_test_scene.h"
#include "test_temp_dir.h"

namespace {

namespace fs = std::filesystem;
using tandem::Error;
using namespace tandem_api_test;

double mean_abs_difference(const std::vector<float>& a, const std::vector<float>& b) {
  double s = 0.0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i)
    s += std::fabs(double(a[i]) - double(b[i]));
  return a.empty() ? 0.0 : s / double(a.size());
}

template <class F>
Error::Kind thrown_kind(F&& f) {
  try {
    f();
  } catch (const Error& e) {
    EXPECT_FALSE(std::string(e.what()).empty());
    return e.kind();
  }
  ADD_FAILURE() << "no tandem::Error was thrown";
  return Error::Kind::kInternal;
}

TEST(ApiRenderer, RendersALitSceneWithTheAdvertisedImageLayout) {
  tandem::Renderer r(small_options());
  build_scene(r);
  const tandem::FrameInfo f = r.render_frame();
  EXPECT_EQ(f.frame, 0u);
  EXPECT_EQ(f.accumulated_spp, 2u);
  EXPECT_GT(f.rays, 0u);
  EXPECT_EQ(r.render_frame().accumulated_spp, 4u);
  EXPECT_EQ(r.width(), 48u);
  EXPECT_EQ(r.height(), 32u);
  EXPECT_EQ(r.backend_names(), "cpu");
  const std::vector<float> linear = r.image_linear();
  ASSERT_EQ(linear.size(), 48u * 32u * 3u);
  EXPECT_GT(mean(linear), 0.01);
  for (float v : linear)
    ASSERT_TRUE(std::isfinite(v) && v >= 0.0f);
  const std::vector<uint8_t> srgb = r.image_srgb8();
  ASSERT_EQ(srgb.size(), linear.size());
  // sRGB encoding is monotonic: the brightest linear pixel is the brightest byte.
  size_t brightest = 0;
  for (size_t i = 0; i < linear.size(); ++i)
    if (linear[i] > linear[brightest]) brightest = i;
  for (uint8_t b : srgb)
    EXPECT_LE(b, srgb[brightest]);
}

TEST(ApiRenderer, MovingAnInstanceChangesTheImageAndRestartsAccumulation) {
  tandem::Renderer r(small_options());
  const tandem::InstanceId block = build_scene(r);
  r.render_frame();
  r.render_frame();
  const std::vector<float> before = r.image_linear();
  r.set_instance_transform(block, tandem::Transform::translation(1.0f, 0.5f, 0.0f));
  const tandem::FrameInfo f = r.render_frame();
  EXPECT_TRUE(f.accumulation_reset);
  EXPECT_EQ(f.accumulated_spp, 2u);
  EXPECT_GT(mean_abs_difference(before, r.image_linear()), 0.01);
}

TEST(ApiRenderer, TheOverlappedLoopGivesTheSameImageAsRenderFrame) {
  // Editing the scene between begin_frame and end_frame reaches only the
  // next frame: the same edits made after end_frame give the same pixels.
  std::vector<float> overlapped, sequential;
  {
    tandem::Renderer r(small_options());
    const tandem::InstanceId block = build_scene(r);
    for (int f = 0; f < 3; ++f) {
      r.begin_frame();
      EXPECT_TRUE(r.frame_in_flight());
      r.set_instance_transform(block, tandem::Transform::translation(0.3f * float(f), 0.5f, 0));
      r.prepare_next_frame();  // may decline on the CPU; must be harmless either way
      r.end_frame();
    }
    overlapped = r.image_linear();
  }
  {
    tandem::Renderer r(small_options());
    const tandem::InstanceId block = build_scene(r);
    for (int f = 0; f < 3; ++f) {
      r.render_frame();
      r.set_instance_transform(block, tandem::Transform::translation(0.3f * float(f), 0.5f, 0));
    }
    sequential = r.image_linear();
  }
  EXPECT_EQ(overlapped, sequential);
}

TEST(ApiRenderer, OptionsChangeResolutionAndBackend) {
  tandem::Renderer r(small_options());
  build_scene(r);
  r.render_frame();
  tandem::RendererOptions o = small_options();
  o.width = 20;
  o.height = 10;
  r.set_options(o);
  EXPECT_EQ(r.render_frame().accumulated_spp, 2u);
  EXPECT_EQ(r.width(), 20u);
  EXPECT_EQ(r.image_srgb8().size(), 20u * 10u * 3u);
  o.backend = tandem::BackendChoice::kAuto;  // falls back to the CPU without a GPU
  tandem::set_warnings_to_stderr(false);
  r.set_options(o);
  tandem::set_warnings_to_stderr(true);
  EXPECT_THROW(r.width(), Error);  // no frame from the new backends yet
  r.render_frame();
  EXPECT_FALSE(r.backend_names().empty());
}

TEST(ApiRenderer, WithoutACameraTheFirstFrameFramesTheScene) {
  tandem::Renderer r(small_options());
  const Quad floor(1.0f);
  tandem::MaterialDesc lamp;
  lamp.emission[0] = lamp.emission[1] = lamp.emission[2] = 2.0f;
  lamp.double_sided = true;
  r.add_instance(r.add_mesh(floor.data(), r.add_material(lamp)), tandem::Transform::identity());
  r.render_frame();
  // The emitter is in view: the image is not black.
  EXPECT_GT(mean(r.image_linear()), 0.1);
}

TEST(ApiRenderer, MeshVerticesCanBeReplaced) {
  tandem::Renderer r(small_options());
  build_scene(r);
  r.render_frame();
  const std::vector<float> before = r.image_linear();
  const Quad higher(0.5f, 1.5f);
  tandem::MeshData v = higher.data();
  r.set_mesh_vertices(tandem::MeshId{1}, v);
  r.render_frame();
  EXPECT_GT(mean_abs_difference(before, r.image_linear()), 0.005);
  v.vertex_count = 3;
  EXPECT_EQ(thrown_kind([&] { r.set_mesh_vertices(tandem::MeshId{1}, v); }),
            Error::Kind::kInvalidArgument);
}

// Replaced vertices go straight into the kernel arrays (a pose, as a skinned
// glTF mesh's do) and render as a mesh that held them all along: bit for bit
// the image of a renderer whose block had them before its first frame (the
// compiler's copy of a whole new scene), after an edit that restarts its
// accumulation as well.
TEST(ApiRenderer, ReplacedVerticesRenderAsAMeshThatHeldThem) {
  const Quad higher(0.5f, 1.5f);
  tandem::Renderer a(small_options()), b(small_options());
  build_scene(a);
  const tandem::InstanceId block = build_scene(b);
  b.set_mesh_vertices(tandem::MeshId{1}, higher.data());
  a.render_frame();
  b.render_frame();
  EXPECT_NE(a.image_linear(), b.image_linear());
  a.set_mesh_vertices(tandem::MeshId{1}, higher.data());
  b.set_instance_transform(block, tandem::Transform::translation(-1.0f, 0.5f, 0.0f));  // as it was
  a.render_frame();
  b.render_frame();
  EXPECT_EQ(a.image_linear(), b.image_linear());
}

TEST(ApiRenderer, TransformHelpersComposeAsMatrices) {
  const tandem::Transform t = tandem::Transform::translation(1, 2, 3) *
                              tandem::Transform::rotation(1.5707963f, 0, 1, 0) *
                              tandem::Transform::scale(2, 2, 2);
  // The x axis, scaled by 2 and turned a quarter about +y, points along -z.
  EXPECT_NEAR(t.m[0], 0.0f, 1e-6f);
  EXPECT_NEAR(t.m[2], -2.0f, 1e-6f);
  EXPECT_FLOAT_EQ(t.m[12], 1.0f);
  EXPECT_FLOAT_EQ(t.m[13], 2.0f);
  EXPECT_FLOAT_EQ(t.m[14], 3.0f);
  EXPECT_FLOAT_EQ(t.m[15], 1.0f);
  const tandem::Transform none = tandem::Transform::rotation(1.0f, 0, 0, 0);
  for (int i = 0; i < 16; ++i)
    EXPECT_EQ(none.m[i], tandem::Transform::identity().m[i]);
  EXPECT_STRNE(tandem::version(), "");
}

TEST(ApiRenderer, BadGeometryIsAnInvalidArgumentAndAddsNothing) {
  tandem::Renderer r(small_options());
  const tandem::MaterialId m = r.add_material({});
  const Quad q(1.0f);
  tandem::MeshData d = q.data();

  uint32_t out_of_range[6] = {0, 1, 2, 0, 2, 4};
  d.indices = out_of_range;
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(d, m); }), Error::Kind::kInvalidArgument);
  d = q.data();
  d.positions = nullptr;
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(d, m); }), Error::Kind::kInvalidArgument);
  d = q.data();
  d.indices = nullptr;
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(d, m); }), Error::Kind::kInvalidArgument);
  d = q.data();
  d.triangle_count = 0;
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(d, m); }), Error::Kind::kInvalidArgument);
  float nan_positions[12];
  std::copy(q.positions, q.positions + 12, nan_positions);
  nan_positions[4] = std::numeric_limits<float>::quiet_NaN();
  d = q.data();
  d.positions = nan_positions;
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(d, m); }), Error::Kind::kInvalidArgument);
  EXPECT_EQ(thrown_kind([&] { r.add_mesh(q.data(), tandem::MaterialId{5}); }),
            Error::Kind::kInvalidArgument);
  EXPECT_EQ(r.mesh_count(), 0u);

  const tandem::MeshId mesh = r.add_mesh(q.data(), m);
  EXPECT_EQ(thrown_kind([&] { r.add_instance(tandem::MeshId{9}, {}); }),
            Error::Kind::kInvalidArgument);
  EXPECT_EQ(r.instance_count(), 0u);
  const tandem::InstanceId inst = r.add_instance(mesh, {});
  EXPECT_EQ(thrown_kind([&] { r.set_instance_transform(tandem::InstanceId{3}, {}); }),
            Error::Kind::kInvalidArgument);
  EXPECT_EQ(thrown_kind([&] { r.set_material(tandem::MaterialId{3}, {}); }),
            Error::Kind::kInvalidArgument);
  EXPECT_EQ(thrown_kind([&] { r.set_light(tandem::LightId{0}, {}); }),
            Error::Kind::kInvalidArgument);
  EXPECT_EQ(thrown_kind([&] { r.set_mesh_vertices(tandem::MeshId{4}, q.data()); }),
            Error::Kind::kInvalidArgument);
  (void)inst;
}

TEST(ApiRenderer, BadTransformsAreInvalidArguments) {
  tandem::Renderer r(small_options());
  const Quad q(1.0f);
  const tandem::MeshId mesh = r.add_mesh(q.data(), r.add_material({}));
  const tandem::InstanceId inst = r.add_instance(mesh, {});
  tandem::Transform nan_t;
  nan_t.m[13] = std::numeric_limits<float>::quiet_NaN();
  tandem::Transform inf_t;
  inf_t.m[0] = std::numeric_limits<float>::infinity();
  tandem::Transform projective;
  projective.m[3] = 0.5f;
  // Beyond the range Tandem traces (Embree would abort on it).
  const tandem::Transform far = tandem::Transform::translation(0, 5e18f, 0);
  for (const tandem::Transform& t : {nan_t, inf_t, projective, far}) {
    EXPECT_EQ(thrown_kind([&] { r.add_instance(mesh, t); }), Error::Kind::kInvalidArgument);
    EXPECT_EQ(thrown_kind([&] { r.set_instance_transform(inst, t); }),
              Error::Kind::kInvalidArgument);
  }
  EXPECT_EQ(r.instance_count(), 1u);
  // The instance kept its transform: the scene still renders.
  r.set_environment_color(1, 1, 1);
  r.render_frame();
  EXPECT_GT(mean(r.image_linear()), 0.01);
}

TEST(ApiRenderer, BadMaterialsLightsAndCamerasAreInvalidArguments) {
  tandem::Renderer r(small_options());
  const float nan = std::numeric_limits<float>::quiet_NaN();
  tandem::MaterialDesc m;
  m.roughness = 1.5f;
  EXPECT_EQ(thrown_kind([&] { r.add_material(m); }), Error::Kind::kInvalidArgument);
  m = {};
  m.base_color[1] = nan;
  EXPECT_EQ(thrown_kind([&] { r.add_material(m); }), Error::Kind::kInvalidArgument);
  m = {};
  m.emission[2] = -1.0f;
  EXPECT_EQ(thrown_kind([&] { r.add_material(m); }), Error::Kind::kInvalidArgument);
  EXPECT_EQ(r.material_count(), 0u);

  tandem::LightDesc l;
  l.intensity = -1.0f;
  EXPECT_EQ(thrown_kind([&] { r.add_light(l); }), Error::Kind::kInvalidArgument);
  l = {};
  l.kind = tandem::LightKind::kDirectional;
  l.direction[0] = l.direction[1] = l.direction[2] = 0.0f;
  EXPECT_EQ(thrown_kind([&] { r.add_light(l); }), Error::Kind::kInvalidArgument);
  l = {};
  l.position[0] = nan;
  EXPECT_EQ(thrown_kind([&] { r.add_light(l); }), Error::Kind::kInvalidArgument);
  EXPECT_EQ(r.light_count(), 0u);

  tandem::CameraDesc c;
  c.target[0] = c.position[0], c.target[1] = c.position[1], c.target[2] = c.position[2];
  EXPECT_EQ(thrown_kind([&] { r.set_camera(c); }), Error::Kind::kInvalidArgument);
  c = {};
  c.up[0] = 0, c.up[1] = 0, c.up[2] = -1;  // along the view direction
  EXPECT_EQ(thrown_kind([&] { r.set_camera(c); }), Error::Kind::kInvalidArgument);
  c = {};
  c.vertical_fov = 0.0f;
  EXPECT_EQ(thrown_kind([&] { r.set_camera(c); }), Error::Kind::kInvalidArgument);
  c = {};
  c.position[2] = nan;
  EXPECT_EQ(thrown_kind([&] { r.set_camera(c); }), Error::Kind::kInvalidArgument);
  // Finite, but beyond what can be traced: refused, never an abort.
  c = {};
  c.position[0] = 5e18f;
  EXPECT_EQ(thrown_kind([&] { r.set_camera(c); }), Error::Kind::kInvalidArgument);
  l = {};
  l.position[2] = 1e20f;
  EXPECT_EQ(thrown_kind([&] { r.add_light(l); }), Error::Kind::kInvalidArgument);
  l = {};
  l.intensity = 1e20f;
  l.color[0] = 1e20f;  // each finite; the product overflows the radiance floats carry
  EXPECT_EQ(thrown_kind([&] { r.add_light(l); }), Error::Kind::kInvalidArgument);
  m = {};
  m.emission[1] = 1e20f;
  m.emission_strength = 1e20f;
  EXPECT_EQ(thrown_kind([&] { r.add_material(m); }), Error::Kind::kInvalidArgument);
  EXPECT_EQ(thrown_kind([&] { r.set_environment_color(nan, 0, 0); }),
            Error::Kind::kInvalidArgument);
}

// Both light samplers render the same scene (their estimates agree, their
// samples differ); a value outside the enum is refused.
TEST(ApiRenderer, LightSamplingChoosesTheSampler) {
  tandem::RendererOptions o = small_options();
  o.samples_per_frame = 64;
  // Two more point lights, one near the floor: the samplers then choose
  // among three lights differently.
  const auto lights = [](tandem::Renderer& r) {
    build_scene(r);
    tandem::LightDesc near, far;
    near.position[0] = -1.5f;
    near.position[1] = 0.4f;
    near.intensity = 2.0f;
    far.position[0] = 3.0f;
    far.position[1] = 6.0f;
    far.intensity = 40.0f;
    r.add_light(near);
    r.add_light(far);
  };
  tandem::Renderer tree(o);
  lights(tree);
  tree.render_frame();
  o.light_sampling = tandem::LightSampling::kPower;
  tandem::Renderer power(o);
  lights(power);
  power.render_frame();
  const std::vector<float> a = tree.image_linear(), b = power.image_linear();
  EXPECT_GT(mean_abs_difference(a, b), 0.0);
  EXPECT_NEAR(mean(a), mean(b), 0.05 * mean(a));
  // Switched on a live renderer: accumulation restarts with the other.
  tree.set_options(o);
  EXPECT_EQ(tree.render_frame().accumulated_spp, 64u);
  EXPECT_NEAR(mean(tree.image_linear()), mean(b), 0.05 * mean(b));
  o.light_sampling = static_cast<tandem::LightSampling>(7);
  EXPECT_EQ(thrown_kind([&] { tandem::Renderer bad(o); }), Error::Kind::kInvalidArgument);
}

TEST(ApiRenderer, ZeroSizeOrOversizedImagesAreRefused) {
  tandem::RendererOptions o = small_options();
  o.width = 0;
  EXPECT_EQ(thrown_kind([&] { tandem::Renderer bad(o); }), Error::Kind::kInvalidArgument);
  o = small_options();
  o.height = 20000;
  EXPECT_EQ(thrown_kind([&] { tandem::Renderer bad(o); }), Error::Kind::kInvalidArgument);
  o = small_options();
  o.samples_per_frame = 0;
  EXPECT_EQ(thrown_kind([&] { tandem::Renderer bad(o); }), Error::Kind::kInvalidArgument);

  tandem::Renderer r(small_options());
  o = small_options();
  o.height = 0;
  EXPECT_EQ(thrown_kind([&] { r.set_options(o); }), Error::Kind::kInvalidArgument);
  EXPECT_EQ(r.options().height, 32u);  // unchanged
}

TEST(ApiRenderer, CallsOutOfOrderAreInvalidState) {
  tandem::Renderer r(small_options());
  // Nothing to render yet, no image yet.
  EXPECT_EQ(thrown_kind([&] { r.begin_frame(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.image_linear(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.end_frame(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.prepare_next_frame(); }), Error::Kind::kInvalidState);
  build_scene(r);
  r.begin_frame();
  EXPECT_EQ(thrown_kind([&] { r.begin_frame(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.image_srgb8(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.clear_scene(); }), Error::Kind::kInvalidState);
  EXPECT_EQ(thrown_kind([&] { r.load_gltf("x.gltf"); }), Error::Kind::kInvalidState);
  r.end_frame();
  EXPECT_NO_THROW(r.image_srgb8());
  r.clear_scene();
  EXPECT_EQ(r.instance_count(), 0u);
  EXPECT_EQ(thrown_kind([&] { r.width(); }), Error::Kind::kInvalidState);
}

TEST(ApiRenderer, ADestroyedRendererWaitsForItsFrame) {
  tandem::Renderer r(small_options());
  build_scene(r);
  r.begin_frame();
  // Leaving the scope with a frame in flight must join the render threads.
}

TEST(ApiRenderer, LoadsGltfFilesAndNamesBadOnes) {
  const fs::path box = fs::path(TANDEM_SHARED_DIR) / "scenes/gltf/Box/glTF/Box.gltf";
  if (!fs::exists(box)) GTEST_SKIP() << "no shared scenes at " << box;
  tandem::Renderer r(small_options());
  r.load_gltf(box.string());
  EXPECT_GE(r.instance_count(), 1u);
  EXPECT_GE(r.mesh_count(), 1u);
  r.set_environment_color(1, 1, 1);  // Box.gltf has no lights
  r.render_frame();
  EXPECT_GT(mean(r.image_linear()), 0.05);

  tandem::TempDir dir("api_gltf");
  const fs::path missing = dir.path() / "missing.gltf";
  try {
    r.load_gltf(missing.string());
    ADD_FAILURE() << "a missing file loaded";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), Error::Kind::kFile);
    EXPECT_NE(std::string(e.what()).find("missing.gltf"), std::string::npos) << e.what();
  }
  const fs::path broken = dir.path() / "broken.gltf";
  std::ofstream(broken) << "{ not json";
  EXPECT_EQ(thrown_kind([&] { r.load_gltf(broken.string()); }), Error::Kind::kFile);
  // The loaded scene is still there.
  EXPECT_GE(r.instance_count(), 1u);
}

TEST(ApiRenderer, WritesImagesAtomicallyAndNamesBadPaths) {
  tandem::Renderer r(small_options());
  build_scene(r);
  r.render_frame();
  tandem::TempDir dir("api_write");
  const fs::path png = dir.path() / "out.png";
  r.write_image(png.string(), 0.5f, tandem::ToneCurve::kAces);
  EXPECT_GT(fs::file_size(png), 100u);
  r.write_image((dir.path() / "out.exr").string());
  EXPECT_EQ(thrown_kind([&] { r.write_image((dir.path() / "out.bmp").string()); }),
            Error::Kind::kFile);
  EXPECT_EQ(thrown_kind([&] { r.write_image((dir.path() / "no/such/dir.png").string()); }),
            Error::Kind::kFile);
  EXPECT_EQ(thrown_kind([&] {
              r.image_srgb8(std::numeric_limits<float>::infinity(), tandem::ToneCurve::kStandard);
            }),
            Error::Kind::kInvalidArgument);
}

TEST(ApiRenderer, CudaWithoutAGpuIsADeviceError) {
  std::string reason;
  if (tandem::cuda_available(&reason)) GTEST_SKIP() << "a CUDA device is available";
  EXPECT_FALSE(reason.empty());
  tandem::RendererOptions o = small_options();
  o.backend = tandem::BackendChoice::kCuda;
  EXPECT_EQ(thrown_kind([&] { tandem::Renderer bad(o); }), Error::Kind::kDevice);
  // Switching to it fails the same way and keeps the working CPU renderer.
  tandem::Renderer r(small_options());
  build_scene(r);
  r.render_frame();
  EXPECT_EQ(thrown_kind([&] { r.set_options(o); }), Error::Kind::kDevice);
  EXPECT_EQ(r.options().backend, tandem::BackendChoice::kCpu);
  EXPECT_EQ(r.render_frame().accumulated_spp, 4u);
  EXPECT_EQ(r.backend_names(), "cpu");
}

}  // namespace

namespace {

TEST(ApiRenderer, DegenerateAndFarAwayGeometryRendersWithoutCrashing) {
  tandem::Renderer r(small_options());
  build_scene(r);
  // A triangle collapsed to a point, one to a line, and vertices far out.
  const float positions[] = {0, 0, 0, 1, 0, 0, 2, 0, 0, 1e30f, -1e30f, 1e30f, -1e30f, 1e30f, 0};
  const uint32_t indices[] = {0, 0, 0, 0, 1, 2, 3, 4, 0};
  tandem::MeshData d;
  d.positions = positions;
  d.vertex_count = 5;
  d.indices = indices;
  d.triangle_count = 3;
  const tandem::MeshId odd = r.add_mesh(d, tandem::MaterialId{0});
  r.add_instance(odd, tandem::Transform::identity());
  r.add_instance(odd, tandem::Transform::scale(1e8f, 1e8f, 1e8f));
  r.render_frame();
  for (float v : r.image_linear())
    ASSERT_TRUE(std::isfinite(v));
}

}  // namespace

namespace {

// A scale of 0 is how games hide an object: accepted, and the image is the
// image without that instance, on the frame it happens and after.
TEST(ApiRenderer, AnInstanceScaledToZeroIsNotDrawn) {
  tandem::Renderer hidden(small_options());
  const tandem::InstanceId block = build_scene(hidden);
  hidden.set_instance_transform(block, tandem::Transform::scale(0, 0, 0));
  hidden.render_frame();
  // The same scene with no instance of the block.
  tandem::Renderer without(small_options());
  build_scene(without, false);
  without.render_frame();
  EXPECT_EQ(hidden.image_linear(), without.image_linear());
  // Scaled back, it is drawn again.
  const std::vector<float> before = hidden.image_linear();
  hidden.set_instance_transform(block, tandem::Transform::translation(-1.0f, 0.5f, 0.0f));
  hidden.render_frame();
  EXPECT_GT(mean_abs_difference(hidden.image_linear(), before), 1e-3);
}

// A file whose node lies beyond the float range the tracers take is a
// kFile error naming it, not an abort inside Embree.
TEST(ApiRenderer, GltfScenesBeyondTheTraceableRangeAreFileErrors) {
  tandem::TempDir dir("api_gltf_range");
  const fs::path file = dir.path() / "far.gltf";
  write_triangle_gltf(file, "", R"(,"translation":[1e20,0,0])");
  tandem::Renderer r(small_options());
  try {
    r.load_gltf(file.string());
    ADD_FAILURE() << "loaded";
  } catch (const Error& e) {
    EXPECT_EQ(e.kind(), Error::Kind::kFile);
    EXPECT_NE(std::string(e.what()).find("far.gltf"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("lies beyond 1e+09"), std::string::npos) << e.what();
  }
  EXPECT_EQ(r.instance_count(), 0u);
}

// The library says nothing unless its host asks: a Renderer made before
// any choice is silent, a callback receives the messages, an empty one
// silences them again, and stderr is one call away.
TEST(ApiRenderer, TheLibrarySaysNothingUnlessItsHostAsks) {
  tandem::TempDir dir("api_log");
  const fs::path file = dir.path() / "vendor.gltf";
  write_triangle_gltf(file, R"("extensionsUsed":["VENDOR_sparkles"],)", "");
  auto load = [&] {
    tandem::RendererOptions o = small_options();
    o.backend = tandem::BackendChoice::kAuto;  // without a GPU: a fallback to tell
    tandem::Renderer r(o);
    r.load_gltf(file.string());
  };
  testing::internal::CaptureStderr();
  load();
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "") << "before the host chose";

  std::vector<std::pair<tandem::LogSeverity, std::string>> got;
  tandem::set_log_callback(
      [&](tandem::LogSeverity s, const std::string& m) { got.emplace_back(s, m); });
  testing::internal::CaptureStderr();
  load();
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  ASSERT_FALSE(got.empty());
  bool named = false;
  for (const auto& [severity, message] : got) {
    EXPECT_EQ(severity, tandem::LogSeverity::kWarning);
    named |= message.find("VENDOR_sparkles") != std::string::npos;
  }
  EXPECT_TRUE(named);

  got.clear();
  tandem::set_log_callback({});
  testing::internal::CaptureStderr();
  load();
  EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
  EXPECT_TRUE(got.empty());

  tandem::set_warnings_to_stderr(true);
  testing::internal::CaptureStderr();
  load();
  EXPECT_NE(testing::internal::GetCapturedStderr().find("tandem: warning: "), std::string::npos);
}

}  // namespace
