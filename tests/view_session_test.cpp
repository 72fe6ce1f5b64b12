// The viewer session's frame loop, convergence and camera reset, the
// SceneAnimator every scene's motion goes through, and the SVGF denoiser in
// the display (moving frames, the toggle, the blend to the accumulated
// image, the debug views).
#include <gtest/gtest.h>

#include <chrono>
#include <cstring>
#include <filesystem>

#include "app/view/denoise_view.h"
#include "app/view/motion_quality.h"
#include "app/view/view_session.h"
#include "scenes/arena_scene.h"
#include "scenes/builtin_scenes.h"
#include "scenes/gltf_loader.h"
#include "scenes/scene_animator.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
const fs::path kGltf = fs::path(TANDEM_SHARED_DIR) / "scenes/gltf";

std::vector<glm::mat4> transforms(const Scene& s) {
  std::vector<glm::mat4> out;
  for (const Instance& i : s.instances())
    out.push_back(i.transform);
  return out;
}

ViewOptions small(const std::string& scene) {
  ViewOptions o;
  o.scene = scene;
  o.width = 32;
  o.height = 24;
  o.backend = BackendKind::kCpu;
  o.max_depth = 2;
  return o;
}

TEST(ViewSceneAnimator, StaticScenesDoNotMove) {
  Scene s = make_builtin_scene("cornell");
  auto a = make_scene_animator(s);
  ASSERT_NE(a, nullptr);
  EXPECT_FALSE(a->animated());
  EXPECT_EQ(a->duration(), 0.0);
  const auto before = transforms(s);
  s.clear_dirty();
  a->pose(2.0, s);
  EXPECT_EQ(transforms(s), before);
  EXPECT_FALSE(s.any_dirty());
}

TEST(ViewSceneAnimator, TheArenaIsFoundByItsBodiesNotItsName) {
  Scene s = make_arena_scene();
  s.source = "renamed";  // the factory must not look at the name
  auto a = make_scene_animator(s);
  EXPECT_TRUE(a->animated());
  EXPECT_EQ(a->duration(), 0.0) << "a simulation has no end";
  Scene ref = make_arena_scene();
  ArenaSimulation sim(ref);
  sim.advance_to(1.5, ref);
  a->pose(3.0, s);
  a->pose(1.5, s);  // pure function of t
  EXPECT_EQ(transforms(s), transforms(ref));
}

TEST(ViewSceneAnimator, GltfNodeAnimationsLoopOverTheirDuration) {
  GltfAnimations anims;
  GltfOptions o;
  o.animations = &anims;
  Scene s = load_gltf(kGltf / "BoxAnimated/glTF/BoxAnimated.gltf", o);
  const double duration = anims.duration();
  auto a = make_scene_animator(s, anims);
  EXPECT_TRUE(a->animated());
  EXPECT_DOUBLE_EQ(a->duration(), duration);
  a->pose(0.3 * duration, s);
  const auto at = transforms(s);
  a->pose(0.6 * duration, s);
  EXPECT_NE(transforms(s), at);
  a->pose(0.3 * duration, s);
  EXPECT_EQ(transforms(s), at);
}

TEST(ViewSession, ResetCameraGoesBackToTheSceneCamera) {
  ViewSession session(small("builtin:cornell"));
  const Camera initial = session.camera();
  Camera moved = initial;
  moved.position += glm::vec3(100.0f, 0.0f, 0.0f);
  session.set_camera(moved);
  EXPECT_NE(session.camera().position, initial.position);
  session.reset_camera();
  EXPECT_EQ(session.camera().position, initial.position);
  EXPECT_EQ(session.camera().forward, initial.forward);
  EXPECT_EQ(session.initial_camera().position, initial.position);
}

// C steps through the file's cameras (ToyCar has eight), wrapping, and
// Home/R then return to the one chosen; --camera N starts at camera N.
TEST(ViewSession, TheFilesCamerasAreSteppedThroughAndResetReturnsToTheChosenOne) {
  const std::string toy_car =
      (std::filesystem::path(TANDEM_SHARED_DIR) / "scenes/gltf/ToyCar/glTF/ToyCar.gltf").string();
  ViewSession session(small(toy_car));
  ASSERT_EQ(session.file_camera_count(), 8u);
  EXPECT_EQ(session.file_camera_index(), 0);
  const Camera first = session.camera();
  session.next_file_camera();
  EXPECT_EQ(session.file_camera_index(), 1);
  const Camera second = session.camera();
  EXPECT_NE(second.position, first.position);
  Camera moved = second;
  moved.position += glm::vec3(1.0f, 0.0f, 0.0f);
  session.set_camera(moved);
  session.reset_camera();
  EXPECT_EQ(session.camera().position, second.position);
  for (int i = 0; i < 7; ++i)
    session.next_file_camera();
  EXPECT_EQ(session.file_camera_index(), 0);
  EXPECT_EQ(session.camera().position, first.position);

  ViewOptions o = small(toy_car);
  o.scene_load.camera = 1;
  ViewSession at_one(o);
  EXPECT_EQ(at_one.file_camera_index(), 1);
  EXPECT_EQ(at_one.camera().position, second.position);
  // A scene without cameras of its own: C does nothing.
  ViewSession cornell(small("builtin:cornell"));
  const Camera c = cornell.camera();
  cornell.next_file_camera();
  EXPECT_EQ(cornell.camera().position, c.position);
}

TEST(ViewSession, StillFramesConvergeExactlyAtTheTargetAndMotionRestarts) {
  ViewOptions o = small("builtin:cornell");
  o.target_spp = 20;
  o.max_spp_per_frame = 8;
  ViewSession session(o);
  session.render_frame(true, std::nullopt);
  EXPECT_FALSE(session.converged());
  for (int i = 0; i < 40 && !session.converged(); ++i)
    session.render_frame(false, std::nullopt);
  ASSERT_TRUE(session.converged());
  EXPECT_EQ(session.accumulated_spp(), 20u) << "overshot the target";
  // A setting that restarts accumulation un-converges it before the next frame.
  session.set_max_depth(3);
  EXPECT_FALSE(session.converged());
  session.render_frame(false, std::nullopt);
  EXPECT_LT(session.accumulated_spp(), 20u);
  // Motion: never converged.
  session.render_frame(true, std::nullopt);
  EXPECT_FALSE(session.converged());
  EXPECT_TRUE(session.last_frame_moving());
}

TEST(ViewSession, TheNextFrameIsPosedWhileThisOneRenders) {
  ViewSession session(small("builtin:arena"));
  ASSERT_TRUE(session.has_motion());
  session.advance_scene(0.0);
  const auto at0 = transforms(session.scene());
  const FrameMetrics& m0 = session.render_frame(false, 0.5);
  EXPECT_TRUE(m0.accumulation_reset);
  // After the frame the scene stands at the next frame's time ...
  EXPECT_EQ(session.scene_time(), 0.5);
  EXPECT_NE(transforms(session.scene()), at0);
  // ... and the next frame is a motion frame even without camera motion.
  const FrameMetrics& m1 = session.render_frame(false, std::nullopt);
  EXPECT_TRUE(m1.accumulation_reset);
  EXPECT_GT(m1.delta_bytes, 0u);
  EXPECT_TRUE(session.last_frame_moving());
  // Paused: nothing is posed, so the frame after that accumulates.
  session.paused = true;
  session.render_frame(false, 1.0);
  EXPECT_EQ(session.scene_time(), 0.5);
  EXPECT_FALSE(session.last_frame_moving());
}

// While things move, adaptation lowers the resolution no further than the
// floor it is given.
TEST(ViewSession, MotionStaysAtOrAboveTheResolutionFloor) {
  for (const float floor : {0.15f, 0.5f}) {
    ViewOptions o = small("builtin:cornell");
    o.width = 160;
    o.height = 120;
    o.target_fps = 100000.0;  // no frame is fast enough
    o.min_scale = floor;
    ViewSession session(o);
    for (int f = 0; f < 6; ++f)
      session.render_frame(true, std::nullopt);
    EXPECT_FLOAT_EQ(session.quality().scale, floor);
    EXPECT_EQ(session.tracer().settings().render.width, uint32_t(std::lround(160 * floor)));
  }
}

// Input is read while a frame renders, every input slice; an input that
// asks for it cancels the frame after the tiles in flight, the display
// keeps the last finished frame, and the still image then converges to the
// pixels of a session that was never interrupted.
TEST(ViewSession, InputIsReadWhileAFrameRendersAndCancelsIt) {
  ViewOptions o = small("builtin:cornell");
  o.width = 160;
  o.height = 120;
  o.max_depth = 4;
  o.fixed_scale = 1.0f;
  o.fixed_samples_per_frame = 32;  // a still frame of tens of input slices
  o.target_spp = 64;
  ViewSession interrupted(o), plain(o);
  for (ViewSession* s : {&interrupted, &plain})
    s->render_frame(true, std::nullopt);  // the full build, not timed
  const std::vector<uint8_t> shown = interrupted.display();

  using Clock = std::chrono::steady_clock;
  std::vector<Clock::time_point> polls;
  const int kEventAt = 2;  // the poll that finds the injected event
  const FrameMetrics& m = interrupted.render_frame(false, std::nullopt, [&] {
    polls.push_back(Clock::now());
    return int(polls.size()) - 1 == kEventAt;
  });
  const Clock::time_point returned = Clock::now();
  ASSERT_GT(polls.size(), size_t(kEventAt)) << "the frame ended before the event";
  EXPECT_TRUE(m.cancelled);
  EXPECT_LT(m.backends[0].tiles, 20u) << "tiles were taken after the cancel";
  EXPECT_EQ(interrupted.accumulated_spp(), 0u);
  EXPECT_FALSE(interrupted.converged());
  EXPECT_EQ(interrupted.display(), shown) << "a cancelled frame is not shown";
  // Polled every slice (a generous bound: sanitizer builds share two cores
  // with the render threads), and the cancel ended the frame soon after.
  for (size_t i = 1; i < polls.size(); ++i) {
    EXPECT_LT(std::chrono::duration<double>(polls[i] - polls[i - 1]).count(), 0.1)
        << "between polls " << i - 1 << " and " << i;
  }
  EXPECT_LT(std::chrono::duration<double>(returned - polls[kEventAt]).count(), 1.0);

  for (ViewSession* s : {&interrupted, &plain}) {
    for (int i = 0; i < 10 && !s->converged(); ++i)
      s->render_frame(false, std::nullopt, [] { return false; });
    ASSERT_TRUE(s->converged());
  }
  const ImageRGB a = interrupted.tracer().image(), b = plain.tracer().image();
  ASSERT_EQ(a.rgb.size(), b.rgb.size());
  EXPECT_EQ(std::memcmp(a.rgb.data(), b.rgb.data(), a.rgb.size() * sizeof(float)), 0);
}

// The motion-quality figure (the image shown, resampled to the window,
// against a reference of the same frame) falls as the shown image
// converges, and compares at the output size what was rendered at half.
TEST(ViewMotionQuality, FallsAsTheShownImageConverges) {
  ViewOptions o = small("builtin:cornell");
  o.width = 64;
  o.height = 48;
  o.fixed_scale = 0.5f;
  o.fixed_samples_per_frame = 1;
  o.denoise = false;
  ViewSession session(o);
  session.render_frame(true, std::nullopt);
  ASSERT_EQ(session.shown_linear().width, 32u);
  const Scene frame = session.scene();
  const double one = motion_relmse(frame, session, 64);
  for (int i = 0; i < 63; ++i)
    session.render_frame(false, std::nullopt);
  const double converged = motion_relmse(frame, session, 64);
  EXPECT_GT(one, 0.0);
  EXPECT_LT(converged, 0.5 * one) << one << " at 1 spp, " << converged << " at 64";
}

// --- the denoiser in the display -------------------------------------------

ViewOptions denoise_options(const std::string& scene, uint32_t spp_per_frame) {
  ViewOptions o = small(scene);
  o.fixed_scale = 1.0f;  // no adaptation: every frame at 32x24
  o.fixed_samples_per_frame = spp_per_frame;
  return o;
}

Camera nudged(const Camera& c, int frame) {
  Camera m = c;
  m.position += glm::vec3(0.002f * float(frame), 0.0f, 0.0f);
  return m;
}

double mean_abs_difference(const std::vector<uint8_t>& a, const std::vector<uint8_t>& b) {
  EXPECT_EQ(a.size(), b.size());
  double d = 0.0;
  for (size_t i = 0; i < a.size() && i < b.size(); ++i)
    d += std::abs(int(a[i]) - int(b[i]));
  return a.empty() ? 0.0 : d / double(a.size());
}

// Input read while the frame's features and filter run (after the
// backends are done) gives the frame up at the first point the filter
// asks: nothing of it is shown, and the next frame is filtered from a fresh
// history.
TEST(ViewSession, InputReadWhileAFrameIsFilteredGivesItUp) {
  ViewOptions o = denoise_options("builtin:cornell", 1);
  o.width = 160;
  o.height = 120;
  ViewSession session(o), plain(o);
  for (ViewSession* s : {&session, &plain})
    s->render_frame(true, std::nullopt);
  const std::vector<uint8_t> shown = session.display();
  int asked = 0;
  const FrameMetrics& m = session.render_frame(true, std::nullopt, [&] {
    if (session.tracer().frame_in_flight()) return false;
    ++asked;
    return true;
  });
  EXPECT_EQ(asked, 1) << "the filter went on after the stop";
  EXPECT_TRUE(m.cancelled);
  EXPECT_EQ(session.frames(), 1u);
  EXPECT_EQ(session.display(), shown) << "a frame given up is not shown";
  EXPECT_FALSE(session.denoiser().has_history());

  // The next frame starts the history afresh (one frame long everywhere),
  // where an uninterrupted session's has grown.
  for (ViewSession* s : {&session, &plain})
    s->render_frame(true, std::nullopt, [] { return false; });
  ASSERT_TRUE(session.showing_denoised());
  float longest = 0.0f, plain_longest = 0.0f;
  for (const Vec4& h : session.denoiser().moments())
    longest = std::max(longest, h.z);
  for (const Vec4& h : plain.denoiser().moments())
    plain_longest = std::max(plain_longest, h.z);
  EXPECT_EQ(longest, 1.0f);
  EXPECT_GT(plain_longest, 1.0f);
}

TEST(ViewDenoise, MovingFramesShowTheFilteredFrame) {
  ViewSession session(denoise_options("builtin:cornell", 1));
  ASSERT_TRUE(session.denoise()) << "on by default";
  for (int f = 0; f < 4; ++f) {
    session.set_camera(nudged(session.initial_camera(), f));
    session.render_frame(true, std::nullopt);
  }
  ASSERT_TRUE(session.showing_denoised());
  EXPECT_EQ(session.accumulated_weight(), 0.0f) << "a 1-spp motion frame is all filter";
  const ImageRGB& d = session.denoised_image();
  ASSERT_EQ(d.width, 32u);
  ASSERT_EQ(d.height, 24u);
  // The display is the tone-mapped filter output, not the raw samples.
  EXPECT_EQ(session.display(), tone_map_to_srgb8(d, 0.0f, ToneMap::kAces));
  EXPECT_GT(mean_abs_difference(session.display(),
                                tone_map_to_srgb8(session.frame_radiance(), 0.0f, ToneMap::kAces)),
            1.0);
  // The history followed the camera: most pixels have more than one frame.
  const std::vector<Vec4>& m = session.denoiser().moments();
  ASSERT_EQ(m.size(), 32u * 24u);
  size_t long_history = 0;
  for (const Vec4& v : m)
    long_history += v.z >= 4.0f;
  EXPECT_GT(long_history, m.size() / 2);
  EXPECT_GT(session.last_denoise_seconds(), 0.0);
}

TEST(ViewDenoise, ToggleSwitchesBetweenRawAndFilteredAndRestartsTheHistory) {
  ViewSession session(denoise_options("builtin:cornell", 1));
  for (int f = 0; f < 3; ++f) {
    session.set_camera(nudged(session.initial_camera(), f));
    session.render_frame(true, std::nullopt);
  }
  ASSERT_TRUE(session.showing_denoised());
  const std::vector<uint8_t> filtered = session.display();
  session.set_denoise(false);
  EXPECT_FALSE(session.showing_denoised());
  // Off: the same frame, unfiltered, at once (no new frame needed).
  EXPECT_EQ(session.display(), tone_map_to_srgb8(session.tracer().image(), 0.0f, ToneMap::kAces));
  EXPECT_NE(session.display(), filtered);
  session.set_camera(nudged(session.initial_camera(), 3));
  session.render_frame(true, std::nullopt);
  EXPECT_FALSE(session.showing_denoised());
  EXPECT_EQ(session.display(), tone_map_to_srgb8(session.tracer().image(), 0.0f, ToneMap::kAces));
  // On again: filtered from the next frame, with a fresh history.
  session.set_denoise(true);
  session.set_camera(nudged(session.initial_camera(), 4));
  session.render_frame(true, std::nullopt);
  ASSERT_TRUE(session.showing_denoised());
  for (const Vec4& v : session.denoiser().moments())
    ASSERT_EQ(v.z, 1.0f) << "the history from before the toggle was dropped";
}

TEST(ViewDenoise, StillFramesBlendIntoTheAccumulatedImage) {
  ViewSession session(denoise_options("builtin:cornell", 8));
  session.render_frame(true, std::nullopt);  // 8 spp: the filter alone
  EXPECT_TRUE(session.showing_denoised());
  EXPECT_EQ(session.accumulated_weight(), 0.0f);
  session.render_frame(false, std::nullopt);  // 16 spp
  EXPECT_TRUE(session.showing_denoised());
  EXPECT_NEAR(session.accumulated_weight(), 1.0f / 3.0f, 1e-6f);
  // The filter saw this frame's own 8 samples, not the 16 accumulated ones.
  const ImageRGB& own = session.frame_radiance();
  const ImageRGB acc = session.tracer().image();
  double d_own = 0.0;
  for (size_t i = 0; i < acc.rgb.size(); ++i)
    d_own += std::abs(own.rgb[i] - acc.rgb[i]);
  EXPECT_GT(d_own, 0.0);
  EXPECT_EQ(session.display(),
            tone_map_to_srgb8(blend_images(session.denoised_image(), acc, 1.0f / 3.0f), 0.0f,
                              ToneMap::kAces));
  for (int f = 0; f < 6; ++f)
    session.render_frame(false, std::nullopt);  // 64 spp
  EXPECT_EQ(session.accumulated_spp(), 64u);
  EXPECT_FALSE(session.showing_denoised()) << "the accumulated image has taken over";
  EXPECT_EQ(session.display(), tone_map_to_srgb8(session.tracer().image(), 0.0f, ToneMap::kAces));
}

TEST(ViewDenoise, FrameSamplesAndBlendWeightsAreExact) {
  ImageRGB before(2, 1), now(2, 1);
  before.rgb = {1, 2, 3, 4, 5, 6};
  // 4 samples averaging `before`, then 4 more averaging 3 everywhere.
  for (size_t i = 0; i < 6; ++i)
    now.rgb[i] = (before.rgb[i] * 4.0f + 3.0f * 4.0f) / 8.0f;
  const ImageRGB own = frame_samples(now, 8, before, 4);
  for (float v : own.rgb)
    EXPECT_NEAR(v, 3.0f, 1e-5f);
  EXPECT_EQ(frame_samples(now, 8, before, 0).rgb, now.rgb) << "restart: the frame is all there is";
  EXPECT_EQ(accumulated_blend_weight(1), 0.0f);
  EXPECT_EQ(accumulated_blend_weight(kDenoiseBlendStartSpp), 0.0f);
  EXPECT_NEAR(accumulated_blend_weight(2 * kDenoiseBlendStartSpp), 1.0f / 3.0f, 1e-6f);
  EXPECT_EQ(accumulated_blend_weight(kDenoiseBlendEndSpp), 1.0f);
  EXPECT_EQ(accumulated_blend_weight(100000), 1.0f);
}

TEST(ViewDenoise, DebugViewsEncodeTheirBuffer) {
  // Three synthetic pixels: a near and a far hit and a miss.
  std::vector<PixelFeatures> f(3);
  for (PixelFeatures& p : f) {
    p = PixelFeatures{};
    p.instance = p.prim = p.material = 0;
  }
  f[0].albedo = make_vec3(1.0f, 0.0f, 0.5f);
  f[0].normal = make_vec3(0.0f, 0.0f, 1.0f);
  f[0].depth = 2.0f;
  f[0].motion = make_vec2(16.0f, -16.0f);
  f[1].albedo = make_vec3(0.2f);
  f[1].normal = make_vec3(-1.0f, 0.0f, 0.0f);
  f[1].depth = 8.0f;
  f[2].albedo = make_vec3(1.0f);
  f[2].instance = f[2].prim = f[2].material = kInvalidIndex;
  const std::vector<Vec4> moments = {make_vec4(1.0f, 5.0f, 12.0f, 0.0f),
                                     make_vec4(0.5f, 0.25f, 6.0f, 0.0f),
                                     make_vec4(0.0f, 0.0f, 1.0f, 0.0f)};
  auto view = [&](ViewBuffer b) { return feature_view_rgb8(b, f, moments, 12, 3, 1); };
  const auto albedo = view(ViewBuffer::kAlbedo);
  EXPECT_EQ(albedo[0], 255);
  EXPECT_EQ(albedo[1], 0);
  EXPECT_NEAR(albedo[2], 188, 1) << "sRGB-encoded 0.5";
  const auto normal = view(ViewBuffer::kNormal);
  EXPECT_EQ(std::vector<uint8_t>(normal.begin(), normal.begin() + 6),
            (std::vector<uint8_t>{128, 128, 255, 0, 128, 128}));
  EXPECT_EQ(normal[6] + normal[7] + normal[8], 0) << "a miss has no normal";
  const auto depth = view(ViewBuffer::kDepth);
  EXPECT_GT(depth[0], depth[3]) << "near is brighter";
  EXPECT_EQ(depth[3], 26) << "the farthest hit at 10%";
  EXPECT_EQ(depth[6], 0);
  const auto motion = view(ViewBuffer::kMotion);
  EXPECT_EQ(std::vector<uint8_t>(motion.begin(), motion.begin() + 6),
            (std::vector<uint8_t>{255, 0, 128, 128, 128, 128}));
  const auto variance = view(ViewBuffer::kVariance);
  EXPECT_GT(variance[0], variance[3]) << "std dev 2 against 0";
  EXPECT_EQ(variance[3], 0);
  const auto history = view(ViewBuffer::kHistory);
  EXPECT_EQ(std::vector<uint8_t>(history.begin(), history.end()),
            (std::vector<uint8_t>{255, 255, 255, 128, 128, 128, 255, 0, 0}))
      << "full, half, and rejected (red)";
  EXPECT_EQ(parse_view_buffer("history"), ViewBuffer::kHistory);
  EXPECT_EQ(parse_view_buffer("normal"), ViewBuffer::kNormal);
  EXPECT_FALSE(parse_view_buffer("nonsense"));
}

TEST(ViewDenoise, TheSessionShowsTheSelectedBufferOfItsFrame) {
  ViewSession session(denoise_options("builtin:cornell", 1));
  for (int f = 0; f < 3; ++f)
    session.render_frame(false, std::nullopt);  // still: no motion anywhere
  for (int i = 1; i < int(ViewBuffer::kCount); ++i) {
    const ViewBuffer b = ViewBuffer(i);
    session.set_view_buffer(b);
    ASSERT_EQ(session.display_width(), 32u);
    ASSERT_EQ(session.features().size(), 32u * 24u);
    EXPECT_EQ(session.display(),
              feature_view_rgb8(b, session.features(), session.denoiser().moments(),
                                session.denoiser().params().max_history, 32, 24))
        << view_buffer_name(b);
  }
  // Nothing moved: the motion view is uniform grey.
  session.set_view_buffer(ViewBuffer::kMotion);
  for (size_t i = 0; i < session.display().size(); i += 3)
    ASSERT_NEAR(session.display()[i], 128, 1) << "pixel " << i / 3;
  // A camera turn (about 3 degrees, some 2.4 pixels at this size) shows up
  // in the next frame's motion view, in every pixel.
  Camera turned = session.initial_camera();
  turned.forward = glm::normalize(turned.forward + 0.05f * glm::cross(turned.forward, turned.up));
  session.set_camera(turned);
  session.render_frame(true, std::nullopt);
  size_t moved = 0;
  for (size_t i = 0; i < session.display().size(); i += 3)
    moved += std::abs(int(session.display()[i]) - 128) > 8;
  EXPECT_EQ(moved, session.display().size() / 3);
  session.set_view_buffer(ViewBuffer::kImage);
  EXPECT_EQ(session.display(), tone_map_to_srgb8(session.denoised_image(), 0.0f, ToneMap::kAces));
  // Without the denoiser no frame computes features; choosing a buffer
  // computes them for the frame on screen (a converged view renders no
  // more frames).
  session.set_denoise(false);
  session.render_frame(false, std::nullopt);
  session.set_view_buffer(ViewBuffer::kNormal);
  EXPECT_EQ(session.display(),
            feature_view_rgb8(ViewBuffer::kNormal, session.features(), {}, 12, 32, 24));
  size_t lit = 0;
  for (uint8_t v : session.display())
    lit += v != 0;
  EXPECT_GT(lit, session.display().size() / 2);
}

}  // namespace
}  // namespace tandem
