// End-to-end tests of the `tandem` executable: exit codes, messages, output
// files. Each test runs the real binary the way a user would.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>

#include "core/image/image.h"
#include "tests/app_run_tandem.h"
#include "tests/test_temp_dir.h"

namespace fs = std::filesystem;
using tandem::TempDir;
using tandem::app_test::run_tandem;
using tandem::app_test::RunResult;
using tandem::app_test::shell_quote;

namespace {

const fs::path kShared = fs::path(TANDEM_SHARED_DIR) / "scenes";

TEST(CliTest, NoArgumentsIsUsageError) {
  const RunResult r = run_tandem("");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("usage"), std::string::npos);
}

TEST(CliTest, BadUsageExitsTwo) {
  for (const char* args :
       {"frobnicate", "render", "render builtin:cornell --spp", "render builtin:cornell --spp abc",
        "render builtin:cornell --spp -3", "render builtin:cornell --width 0",
        "render builtin:cornell --bogus", "render builtin:cornell --backend quantum",
        "render builtin:cornell --output out.bmp", "render a b",
        "render builtin:cornell --tonemap sepia", "render builtin:cornell --spp 4 --spp 5"}) {
    const RunResult r = run_tandem(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("error"), std::string::npos) << args;
  }
}

TEST(CliTest, MissingOrUnknownSceneExitsOneNamingIt) {
  RunResult r = run_tandem("info /nonexistent/scene.gltf");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("/nonexistent/scene.gltf"), std::string::npos) << r.output;
  r = run_tandem("info builtin:nope");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("builtin:nope"), std::string::npos) << r.output;
  r = run_tandem("info scene.obj");
  EXPECT_EQ(r.exit_code, 1) << r.output;
}

TEST(CliTest, EveryBadGltfFileIsRejectedByTheCli) {
  // The output must be writable: render checks it before loading the scene.
  TempDir dir("tandem_cli");
  const std::string output = shell_quote((dir.path() / "x.png").string());
  size_t files = 0;
  for (const auto& entry : fs::recursive_directory_iterator(kShared / "bad")) {
    const std::string ext = entry.path().extension().string();
    if (ext != ".gltf" && ext != ".glb") continue;
    ++files;
    const RunResult r = run_tandem("render " + shell_quote(entry.path().string()) +
                                   " --width 8 --height 8 --spp 1 --quiet --output " + output);
    EXPECT_EQ(r.exit_code, 1) << entry.path() << "\n" << r.output;
    EXPECT_FALSE(fs::exists(dir.path() / "x.png")) << entry.path();
    EXPECT_NE(r.output.find(entry.path().filename().string()), std::string::npos) << r.output;
    EXPECT_EQ(r.output.find("Segmentation"), std::string::npos);
  }
  EXPECT_EQ(files, 38u);
}

TEST(CliTest, RendersPngExrAndPfm) {
  TempDir dir("tandem_cli");
  for (const char* ext : {"png", "exr", "pfm"}) {
    const fs::path out = dir.path() / (std::string("cornell.") + ext);
    const RunResult r =
        run_tandem("render builtin:cornell --width 24 --height 16 --spp 2 --backend cpu --output " +
                   shell_quote(out.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    ASSERT_TRUE(fs::exists(out));
    EXPECT_NE(r.output.find("Mrays/s"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find(" threads): loaded in "), std::string::npos) << r.output;
    const tandem::ImageRGB img = tandem::read_image(out);
    EXPECT_EQ(img.width, 24u);
    EXPECT_EQ(img.height, 16u);
    double sum = 0.0;
    for (float v : img.rgb)
      sum += v;
    EXPECT_GT(sum, 0.0) << "image is black";
  }
  // Atomic writes leave no temporary files behind.
  size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path()))
    ++entries;
  EXPECT_EQ(entries, 3u);
}

TEST(CliTest, UnwritableOutputFailsCleanly) {
  const RunResult r = run_tandem(
      "render builtin:cornell --width 8 --height 8 --spp 1 --output /nonexistent_dir/x.png");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("/nonexistent_dir/x.png"), std::string::npos) << r.output;
}

TEST(CliTest, FailedRenderKeepsPreviousOutput) {
  TempDir dir("tandem_cli");
  const fs::path out = dir.path() / "keep.png";
  { std::ofstream(out) << "previous"; }
  const RunResult r = run_tandem("render /nonexistent.gltf --output " + shell_quote(out.string()));
  EXPECT_EQ(r.exit_code, 1);
  std::ifstream in(out);
  std::string content((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(content, "previous");
}

TEST(CliTest, InfoPrintsCounts) {
  const RunResult r = run_tandem("info builtin:cornell");
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("triangles:  38"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("2 emissive triangles"), std::string::npos) << r.output;
  // The many-light scene's bulbs: four meshes of two triangles, instanced.
  const RunResult many = run_tandem("info builtin:many-lights");
  ASSERT_EQ(many.exit_code, 0) << many.output;
  EXPECT_NE(many.output.find("triangle lights in the meshes, 1537 emissive instances"),
            std::string::npos)
      << many.output;
}

TEST(CliTest, InfoListsTheFilesExtensionsAndWhatBecomesOfThem) {
  const RunResult r = run_tandem(
      "info " +
      shell_quote((kShared / "gltf/EmissiveStrengthTest/glTF/EmissiveStrengthTest.gltf").string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("extensions: KHR_materials_emissive_strength (supported)"),
            std::string::npos)
      << r.output;
}

// Scenes, animations with the frames `--frames all` renders, skins and
// morph targets, as the samples declare them.
TEST(CliTest, InfoListsScenesAnimationsSkinsAndMorphs) {
  const auto info = [](const std::string& file) {
    const RunResult r = run_tandem("info " + shell_quote((kShared / file).string()));
    EXPECT_EQ(r.exit_code, 0) << r.output;
    return r.output;
  };
  const std::string box = info("gltf/BoxAnimated/glTF/BoxAnimated.gltf");
  EXPECT_NE(box.find("animations: 1 "), std::string::npos) << box;
  EXPECT_NE(box.find("  0: (unnamed), 3.708 s (frames 0..88 at 24 fps), 2 channels"),
            std::string::npos)
      << box;
  const std::string figure = info("skinned/RiggedFigure/glTF-Embedded/RiggedFigure.gltf");
  EXPECT_NE(figure.find("skins:      1\n  0: Armature, 19 joints"), std::string::npos) << figure;
  const std::string morph = info("skinned/SimpleMorph/glTF-Embedded/SimpleMorph.gltf");
  EXPECT_NE(morph.find("morphs:     1 meshes with morph targets (up to 2 targets)"),
            std::string::npos)
      << morph;
  const std::string scenes = info("gltf/MultipleScenes/glTF/MultipleScenes.gltf");
  EXPECT_NE(scenes.find("scenes:     2, scene 1 loaded (choose with --gltf-scene N)"),
            std::string::npos)
      << scenes;
  EXPECT_EQ(info("gltf/Box/glTF/Box.gltf").find("animations:"), std::string::npos);
}

// The file's cameras are listed and chosen by index; one beyond them is a
// clear error before anything renders.
TEST(CliTest, InfoListsTheCamerasAndCameraChoosesOne) {
  const std::string toy_car = shell_quote((kShared / "gltf/ToyCar/glTF/ToyCar.gltf").string());
  const RunResult info = run_tandem("info " + toy_car);
  ASSERT_EQ(info.exit_code, 0) << info.output;
  EXPECT_NE(info.output.find("cameras:    8 in the scene, chosen with --camera N"),
            std::string::npos)
      << info.output;
  EXPECT_NE(info.output.find("  1: Camera002, perspective, 23.5 degrees vertical"),
            std::string::npos)
      << info.output;
  const RunResult second = run_tandem("info " + toy_car + " --camera 1");
  EXPECT_NE(second.output.find("camera:     perspective at (-0.04333, 0.0236, 0.0761)"),
            std::string::npos)
      << second.output;
  const RunResult beyond = run_tandem("render " + toy_car + " --camera 8 --output x.png");
  EXPECT_EQ(beyond.exit_code, 1) << beyond.output;
  EXPECT_NE(beyond.output.find("camera 8 was asked for, but the scene has 8 cameras (0 to 7)"),
            std::string::npos)
      << beyond.output;
}

// Without a GPU, auto says so once (however many backend lists the run
// makes), and not at all under --quiet or with --backend cpu.
TEST(CliTest, AutoBackendFallsBackToCpuWithNotice) {
  TempDir dir("tandem_cli");
  const std::string out =
      " --width 8 --height 8 --spp 1 --output " + shell_quote((dir.path() / "x.pfm").string());
  const RunResult r = run_tandem("render builtin:cornell" + out);
  if (r.output.find("rendering on the CPU") == std::string::npos) {
    GTEST_SKIP() << "a GPU is available here";
  }
  EXPECT_EQ(r.exit_code, 0) << r.output;
  const size_t first = r.output.find("no usable GPU");
  EXPECT_EQ(r.output.find("no usable GPU", first + 1), std::string::npos) << r.output;
  for (const char* quiet : {" --quiet", " --backend cpu"}) {
    const RunResult q = run_tandem("render builtin:cornell" + out + quiet);
    EXPECT_EQ(q.exit_code, 0) << q.output;
    EXPECT_EQ(q.output.find("GPU"), std::string::npos) << quiet << ": " << q.output;
  }
}

TEST(CliTest, CudaBackendWithoutDeviceExitsOne) {
  TempDir dir("tandem_cli");
  const RunResult r =
      run_tandem("render builtin:cornell --width 8 --height 8 --spp 1 --backend cuda --output " +
                 shell_quote((dir.path() / "x.png").string()));
  if (r.exit_code == 0) GTEST_SKIP() << "a CUDA device is available here";
  EXPECT_EQ(r.exit_code, 1) << r.output;
  // One clear line: which option failed and why (no driver, no device, a
  // driver too old, or a build without CUDA), not a CUDA error dump.
  EXPECT_NE(r.output.find("tandem: error: the cuda backend cannot run: "), std::string::npos)
      << r.output;
  const bool explained = r.output.find("driver") != std::string::npos ||
                         r.output.find("no CUDA device") != std::string::npos ||
                         r.output.find("no CUDA backend") != std::string::npos ||
                         r.output.find("GPU") != std::string::npos;
  EXPECT_TRUE(explained) << r.output;
  EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << r.output;
}

// The host backend (our BVH + the shared kernels) end to end: the CLI must
// build the BVH before syncing it, and trace the same paths as the Embree
// backend (same seed, so almost every value is identical or within 1e-4; see
// render_backends_test for the exact bounds).
TEST(CliTest, HostBackendRendersLikeCpuBackend) {
  TempDir dir("tandem_cli");
  // Any BVH cache file goes to the temporary directory, never to ~/.cache.
  ::setenv("TANDEM_BVH_CACHE", dir.path().c_str(), 1);
  tandem::ImageRGB images[2];
  const char* backends[2] = {"host", "cpu"};
  for (int i = 0; i < 2; ++i) {
    const fs::path out = dir.path() / (std::string(backends[i]) + ".pfm");
    const RunResult r =
        run_tandem("render builtin:cornell --width 32 --height 24 --spp 2 --seed 3 --backend " +
                   std::string(backends[i]) + " --output " + shell_quote(out.string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    EXPECT_NE(r.output.find(std::string(" on ") + backends[i]), std::string::npos) << r.output;
    images[i] = tandem::read_image(out);
  }
  ::unsetenv("TANDEM_BVH_CACHE");
  ASSERT_EQ(images[0].rgb.size(), images[1].rgb.size());
  size_t same = 0;
  double sum = 0.0;
  for (size_t i = 0; i < images[0].rgb.size(); ++i) {
    const float a = images[0].rgb[i], b = images[1].rgb[i];
    same += a == b || std::abs(a - b) <= 1e-4f * std::max(std::abs(a), std::abs(b));
    sum += images[0].rgb[i];
  }
  EXPECT_GT(sum, 0.0) << "host image is black";
  EXPECT_GE(double(same), 0.95 * double(images[0].rgb.size()));
}

}  // namespace

namespace {

TEST(CliTest, RendersWithEnvironmentMapAndDepthOfField) {
  TempDir dir("tandem_cli");
  // A small sky: bright down to 22.5 degrees below the horizon, dark below.
  tandem::ImageRGB env(16, 8);
  for (uint32_t y = 0; y < env.height; ++y) {
    for (uint32_t x = 0; x < env.width; ++x) {
      float* p = env.pixel(x, y);
      p[0] = p[1] = p[2] = y < 5 ? 2.0f : 0.1f;
    }
  }
  const fs::path env_path = dir.path() / "sky.pfm";
  tandem::write_image(env_path, env);
  const fs::path out = dir.path() / "lit.pfm";
  const RunResult r = run_tandem(
      "render builtin:sky-plane --width 16 --height 16 --spp 4 --aperture 0.05 "
      "--focus-distance 2 --env " +
      shell_quote(env_path.string()) + " --output " + shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const tandem::ImageRGB img = tandem::read_image(out);
  // The top row looks at the bright part of the sky (radiance 2).
  EXPECT_NEAR(img.pixel(8, 0)[1], 2.0f, 1e-3f);
}

TEST(CliTest, BadEnvironmentMapExitsOneNamingIt) {
  TempDir dir("tandem_cli");
  const fs::path bad = dir.path() / "broken.hdr";
  { std::ofstream(bad) << "#?RADIANCE\nthis is not an image"; }
  const RunResult r = run_tandem("render builtin:cornell --width 8 --height 8 --spp 1 --env " +
                                 shell_quote(bad.string()) + " --output " +
                                 shell_quote((dir.path() / "x.png").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("broken.hdr"), std::string::npos) << r.output;
}

}  // namespace
