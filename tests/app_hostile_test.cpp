// The `tandem` executable on hostile or mistaken input: answers that used
// to be silently wrong, work that used to be lost, messages that used to
// mislead, and Ctrl-C during a render.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "app_run_tandem.h"
#include "core/image/image.h"
#include "tests/test_temp_dir.h"

namespace fs = std::filesystem;
using tandem::TempDir;

namespace {

using tandem::app_test::RunResult;
using Result = RunResult;

Result tandem_cli(const std::string& args) {
  return tandem::app_test::run_tandem(args);
}

std::string quote(const std::string& s) {
  return tandem::app_test::shell_quote(s);
}

size_t count(const std::string& text, const std::string& what) {
  size_t n = 0;
  for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1))
    ++n;
  return n;
}

const std::string kQuick = "render builtin:cornell --width 8 --height 8 --spp 1 --quiet ";

TEST(CliHostile, MalformedListsAreUsageErrors) {
  for (const char* backend : {"cpu+", "+cpu", "cpu++host", "''"}) {
    const Result r = tandem_cli(kQuick + "--backend " + backend + " --output /tmp/x.png");
    EXPECT_EQ(r.exit_code, 2) << backend << "\n" << r.output;
  }
  for (const char* color : {"1,2,3,", ",1", "1,,2", "1,2"}) {
    const Result r = tandem_cli(kQuick + "--env-color " + color + " --output /tmp/x.png");
    EXPECT_EQ(r.exit_code, 2) << color << "\n" << r.output;
  }
  // bench --hetero "" must not blame --backend.
  const Result r = tandem_cli("bench --hetero ''");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_EQ(r.output.find("--backend"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("backend list is empty"), std::string::npos) << r.output;
}

TEST(CliHostile, EnvironmentRadianceThatOverflowsIsRefused) {
  const Result r =
      tandem_cli(kQuick + "--env-color 1e30 --env-intensity 1e9 --output /tmp/never.png");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("beyond the largest radiance"), std::string::npos) << r.output;
  // An environment map whose brightest texel overflows likewise (exit 1: the file's fault).
  TempDir dir("tandem_hostile_cli");
  tandem::ImageRGB env(4, 2);
  env.rgb[0] = 1e30f;
  tandem::write_image(dir.path() / "env.pfm", env);
  const Result m =
      tandem_cli(kQuick + "--env " + quote((dir.path() / "env.pfm").string()) +
                 " --env-intensity 1e9 --output " + quote((dir.path() / "o.png").string()));
  EXPECT_EQ(m.exit_code, 1) << m.output;
  EXPECT_NE(m.output.find("env.pfm: the brightest texel"), std::string::npos) << m.output;
}

TEST(CliHostile, NumbersInMessagesAndRangesAreReadable) {
  TempDir dir("tandem_hostile_cli");
  const std::string out = " --output " + quote((dir.path() / "o.png").string());
  // A tiny exposure underflows float, but it is inside [-50, 50].
  EXPECT_EQ(tandem_cli(kQuick + "--exposure 1e-50" + out).exit_code, 0);
  const Result r = tandem_cli(kQuick + "--clamp abc" + out);
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("[0, 1e+30]"), std::string::npos) << r.output;
}

TEST(CliHostile, OutputProblemsAreFoundBeforeRendering) {
  TempDir dir("tandem_hostile_cli");
  std::ofstream(dir.path() / "file") << "x";
  fs::create_directory(dir.path() / "d.png");
  const std::string big = "render builtin:cornell --width 2000 --height 2000 --spp 100000 ";
  const std::pair<std::string, std::string> cases[] = {
      {(dir.path() / "d.png").string(), "is a directory"},
      {(dir.path() / "missing" / "o.png").string(), "does not exist"},
      {(dir.path() / "file" / "o.png").string(), "is a file, not a directory"},
  };
  for (const auto& [output, reason] : cases) {
    const auto start = std::chrono::steady_clock::now();
    const Result r = tandem_cli(big + "--output " + quote(output));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(reason), std::string::npos) << r.output;
    EXPECT_LT(seconds, 20.0);  // the hours-long render never started
  }
}

// Every output of the run is checked before the scene is loaded: the name
// with the temporary file's suffix, every frame's folder where the '#'
// pattern is in a folder name, and that no output is an input.
TEST(CliHostile, EveryOutputOfTheRunIsCheckedBeforeLoading) {
  TempDir dir("tandem_hostile_cli");
  const std::string quick = "render builtin:cornell --width 8 --height 8 --spp 1 --quiet ";
  Result r = tandem_cli(quick + "--output " +
                        quote((dir.path() / (std::string(240, 'a') + ".png")).string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("bytes of the temporary file written first"), std::string::npos)
      << r.output;
  // Frame 0's folder exists, frame 1's does not: nothing is rendered.
  fs::create_directory(dir.path() / "shot_00");
  r = tandem_cli(quick + "--frames 0..3 --output " +
                 quote((dir.path() / "shot_##" / "img.png").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("shot_01/img.png: cannot write: directory"), std::string::npos)
      << r.output;
  EXPECT_FALSE(fs::exists(dir.path() / "shot_00" / "img.png"));
  // The output is the environment map, or a frame of the sequence is.
  tandem::ImageRGB sky(4, 2);
  sky.rgb.assign(sky.rgb.size(), 0.5f);
  const fs::path env = dir.path() / "sky_0002.pfm";
  tandem::write_image(env, sky);
  const std::string before = [&] {
    std::ifstream in(env, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  }();
  for (const std::string& frames_and_output :
       {"--output " + quote(env.string()),
        "--frames 0..3 --output " + quote((dir.path() / "sky_####.pfm").string())}) {
    r = tandem_cli(quick + "--env " + quote(env.string()) + " " + frames_and_output);
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("sky_0002.pfm: is an input of this render"), std::string::npos)
        << r.output;
  }
  std::ifstream in(env, std::ios::binary);
  EXPECT_EQ(std::string(std::istreambuf_iterator<char>(in), {}), before);
}

// A camera's aspect ratio (a file's value) sets one side of the image: it is
// held to the limit --width and --height have before anything is allocated.
TEST(CliHostile, CameraAspectRatiosCannotAskForHugeImages) {
  TempDir dir("tandem_hostile_cli");
  for (const char* aspect : {"1e-6", "100"}) {
    const fs::path file = dir.path() / (std::string("aspect_") + aspect + ".gltf");
    std::ofstream(file)
        << R"({"asset":{"version":"2.0"},"cameras":[{"type":"perspective","perspective":)"
        << R"({"yfov":0.8,"znear":0.1,"aspectRatio":)" << aspect
        << R"(}}],"nodes":[{"camera":0}],"scenes":[{"nodes":[0]}]})";
    const std::string size = std::string(aspect) == "100" ? "" : "--width 16 ";
    const Result r = tandem_cli("render " + quote(file.string()) + " --spp 1 --quiet " + size +
                                "--output " + quote((dir.path() / "o.png").string()));
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find(file.string() + ": the camera's aspect ratio"), std::string::npos)
        << r.output;
    EXPECT_NE(
        r.output.find(std::string(aspect) == "100" ? "asks for an image 72000 pixels wide"
                                                   : "asks for an image 16000000 pixels high"),
        std::string::npos)
        << r.output;
  }
}

// An environment map is held to 8192x4096 pixels from its header, before
// anything is decoded: a 400 KB PNG of 16384x8192 took 3.6 GB.
TEST(CliHostile, EnvironmentMapsAreSizedFromTheirHeader) {
  TempDir dir("tandem_hostile_cli");
  const fs::path png = dir.path() / "huge.png";
  tandem::write_png_rgb8(png, 1, 1, {0, 0, 0});
  std::string bytes;
  {
    std::ifstream in(png, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), {});
  }
  // IHDR width 16384, height 8192 (big-endian) and its CRC.
  const unsigned char size[8] = {0, 0, 0x40, 0, 0, 0, 0x20, 0};
  bytes.replace(16, 8, reinterpret_cast<const char*>(size), 8);
  uint32_t c = 0xffffffffu;
  for (size_t i = 12; i < 29; ++i) {
    c ^= uint8_t(bytes[i]);
    for (int k = 0; k < 8; ++k)
      c = (c >> 1) ^ (0xedb88320u & (0u - (c & 1u)));
  }
  c = ~c;
  for (int k = 0; k < 4; ++k)
    bytes[size_t(29 + k)] = char(c >> (24 - 8 * k));
  std::ofstream(png, std::ios::binary) << bytes;
  const Result r = tandem_cli(kQuick + "--env " + quote(png.string()) + " --output " +
                              quote((dir.path() / "o.png").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("huge.png: PNG header claims 16384x8192 pixels, over the limit of "
                          "33554432 pixels for an environment map (it would take about 5.0 GiB "
                          "of memory); scale it down to 8192x4096 or less"),
            std::string::npos)
      << r.output;
}

TEST(CliHostile, NonFileEnvironmentMapsSayWhatTheyAre) {
  TempDir dir("tandem_hostile_cli");
  const std::string out = " --output " + quote((dir.path() / "o.png").string());
  Result r = tandem_cli(kQuick + "--env /dev/null" + out);
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.output.find("/dev/null: not a regular file"), std::string::npos) << r.output;
  r = tandem_cli(kQuick + "--env " + quote(dir.path().string()) + out);
  EXPECT_NE(r.output.find("is a directory"), std::string::npos) << r.output;
}

TEST(CliHostile, EmptySceneIsReportedOnce) {
  TempDir dir("tandem_hostile_cli");
  std::ofstream(dir.path() / "empty.gltf") << R"({"asset":{"version":"2.0"}})";
  const Result r = tandem_cli("render " + quote((dir.path() / "empty.gltf").string()) +
                              " --width 4 --height 4 --spp 1 --quiet --output " +
                              quote((dir.path() / "o.png").string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(count(r.output, "no triangles"), 1u) << r.output;
}

TEST(CliHostile, CompareRefusesToJudgeWhatItCannotTest) {
  TempDir dir("tandem_hostile_cli");
  const fs::path a = dir.path() / "a.pfm", b = dir.path() / "b.pfm";
  tandem::write_image(a, tandem::ImageRGB(1, 1));
  tandem::write_image(b, tandem::ImageRGB(1, 1));
  Result r = tandem_cli("compare " + quote(a.string()) + " " + quote(b.string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_EQ(r.output.find("AGREE"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("too small"), std::string::npos) << r.output;
  // PNGs are compared, with a warning that they are not linear.
  const fs::path pa = dir.path() / "a.png", pb = dir.path() / "b.png";
  tandem::write_image(pa, tandem::ImageRGB(16, 16));
  tandem::write_image(pb, tandem::ImageRGB(16, 16));
  r = tandem_cli("compare " + quote(pa.string()) + " " + quote(pb.string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("a.png is an 8-bit (tone-mapped) image"), std::string::npos) << r.output;
}

// Starts a long render, sends `sig` once it runs, and returns its exit
// status and stderr.
// Runs `tandem ARGS`, sends it `sig` after `delay_ms`; *seconds_after
// (when given) is how long it then took to end.
Result signal_run(const std::string& args, const fs::path& log, int sig, int delay_ms,
                  double* seconds_after = nullptr) {
  const pid_t child = ::fork();
  if (child == 0) {
    const int fd = ::open(log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    ::dup2(fd, 2);
    ::dup2(fd, 1);
    const std::string cmd = quote(TANDEM_BINARY) + " " + args;
    ::execl("/bin/sh", "sh", "-c", ("exec " + cmd).c_str(), static_cast<char*>(nullptr));
    ::_exit(127);
  }
  std::this_thread::sleep_for(std::chrono::milliseconds(delay_ms));
  ::kill(child, sig);
  const auto sent = std::chrono::steady_clock::now();
  int status = 0;
  ::waitpid(child, &status, 0);
  if (seconds_after)
    *seconds_after = std::chrono::duration<double>(std::chrono::steady_clock::now() - sent).count();
  std::ifstream in(log);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status),
          std::string(std::istreambuf_iterator<char>(in), {})};
}

// A long render of the Cornell box (plus `extra` options), signalled once
// it has begun (the scene is tiny, loading is quick).
Result interrupt_render(const std::string& extra, const fs::path& log, int sig) {
  return signal_run(
      "render builtin:cornell --width 8 --height 8 --spp 1048576 --backend cpu "
      "--threads 1 " +
          extra,
      log, sig, 3000);
}

TEST(CliHostile, InterruptedRenderStopsCleanlyAndCanKeepTheImage) {
  TempDir dir("tandem_hostile_cli");
  const fs::path out = dir.path() / "o.pfm";
  Result r = interrupt_render("--output " + quote(out.string()), dir.path() / "log1", SIGINT);
  EXPECT_EQ(r.exit_code, 130) << r.output;
  EXPECT_NE(r.output.find("interrupted by SIGINT"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("no image written"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(out));

  r = interrupt_render("--save-on-interrupt --output " + quote(out.string()), dir.path() / "log2",
                       SIGTERM);
  EXPECT_EQ(r.exit_code, 128 + SIGTERM) << r.output;
  EXPECT_NE(r.output.find("wrote the image so far"), std::string::npos) << r.output;
  ASSERT_TRUE(fs::exists(out));
  EXPECT_EQ(tandem::read_image(out).width, 8u);
  for (const auto& e : fs::directory_iterator(dir.path()))
    EXPECT_EQ(e.path().filename().string().find(".tmp."), std::string::npos) << e.path();
}

// SIGTERM while the set-up runs (here the sampling tables of an 8192x4096
// environment map, seconds of work) ends the run at once: it used to wait
// for the set-up and the first frame, more than 5 s.
TEST(CliHostile, SignalDuringTheSetUpEndsTheRunAtOnce) {
  TempDir dir("tandem_hostile_cli");
  const fs::path env = dir.path() / "sky.png";
  std::vector<uint8_t> sky(size_t(8192) * 4096 * 3, 90);
  tandem::write_png_rgb8(env, 8192, 4096, sky);
  sky = {};
  // With one thread the release build loads the map for about 3.5 s and
  // builds the tables for a few seconds more (2-core EPYC VM); a faster or
  // slower build may be loading or rendering at either time. Every phase
  // must end promptly: the frames here (one sample of 8x8 pixels each) do.
  for (const int delay_ms : {4000, 6000}) {
    double seconds = 0.0;
    const Result r = signal_run(
        "render builtin:cornell --width 8 --height 8 --spp 1 --backend cpu "
        "--threads 1 --quiet --frames 0..999999 --env " +
            quote(env.string()) + " --output " + quote((dir.path() / "o_######.pfm").string()),
        dir.path() / "log", SIGTERM, delay_ms, &seconds);
    EXPECT_EQ(r.exit_code, 128 + SIGTERM) << r.output;
    EXPECT_LT(seconds, 1.5) << "signalled after " << delay_ms << " ms: " << r.output;
  }
}

}  // namespace
