// `tandem bench` end to end: every mode writes its figures as JSON with
// --json, a bad --json path fails before anything is measured, --kernel is
// accepted where it applies and refused where it does not (render too), and
// `bench --gpu` without a device says why. Every run is a tiny
// configuration: these tests check the plumbing, not the figures.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "backends/backend_factory.h"
#include "tests/app_run_tandem.h"
#include "tests/json_test_parser.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem;
using app_test::RunResult;
using app_test::shell_quote;
using json_test::Node;

Node read_json(const fs::path& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << path;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  return json_test::parse(text);
}

void expect_keys(const Node& n, std::initializer_list<const char*> keys, const std::string& what) {
  for (const char* k : keys)
    EXPECT_TRUE(n.has(k)) << what << ": no \"" << k << "\"";
}

void expect_run_facts(const Node& n, const char* mode) {
  expect_keys(n,
              {"tool", "mode", "date_utc", "threads", "cpu", "scene", "width", "height", "spp",
               "max_depth"},
              mode);
  EXPECT_EQ(n["mode"].string, mode);
}

class BenchJson : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = std::make_unique<TempDir>("tandem_bench");
    // Any BVH cache goes to the temporary directory, never to ~/.cache.
    ::setenv("TANDEM_BVH_CACHE", dir_->path().c_str(), 1);
  }
  void TearDown() override { ::unsetenv("TANDEM_BVH_CACHE"); }
  fs::path file(const char* name) const { return dir_->path() / name; }
  std::unique_ptr<TempDir> dir_;
};

TEST_F(BenchJson, DefaultModeWithAccstrucAndHetero) {
  const fs::path out = file("path.json");
  const RunResult r = run_tandem(
      "bench --width 16 --height 12 --spp 1 --max-depth 2 --threads 2 --accstruc --hetero "
      "cpu+host --hetero-frames 1 --kernel mega --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Node n = read_json(out);
  expect_run_facts(n, "path");
  EXPECT_EQ(n["threads"].number, 2.0);
  EXPECT_EQ(n["width"].number, 16.0);
  EXPECT_EQ(n["spp"].number, 1.0);
  expect_keys(
      n,
      {"triangles", "embree_build_seconds", "bench_rays", "plain_embree_mrays_per_second",
       "path_tracing_cpu", "ratio_path_over_plain", "accstruc", "path_tracing_host", "hetero"},
      "path");
  EXPECT_GT(n["plain_embree_mrays_per_second"].number, 0.0);
  expect_keys(n["path_tracing_cpu"], {"mrays_per_second", "samples_per_second", "rays", "seconds"},
              "cpu");
  // The second peer replays the path tracer's own rays of one sample per
  // pixel: at --spp 1 exactly as many as the path tracing run cast, one
  // camera ray per pixel, and every bounce and shadow ray besides.
  const Node& replay = n["plain_embree_path_rays"];
  expect_keys(replay, {"rays", "camera", "bounce", "shadow", "mrays_per_second"}, "path rays");
  EXPECT_EQ(replay["rays"].number, n["path_tracing_cpu"]["rays"].number);
  EXPECT_EQ(replay["camera"].number, 16.0 * 12.0);
  EXPECT_GT(replay["bounce"].number, 0.0);
  EXPECT_GT(replay["shadow"].number, 0.0);
  EXPECT_EQ(replay["camera"].number + replay["bounce"].number + replay["shadow"].number,
            replay["rays"].number);
  EXPECT_GT(replay["mrays_per_second"].number, 0.0);
  EXPECT_TRUE(n.has("ratio_path_over_plain_path_rays"));
  expect_keys(n["accstruc"], {"blas_build", "sah_cost", "traversal"}, "accstruc");
  const Node& kinds = n["accstruc"]["traversal"][0]["kinds"];
  ASSERT_EQ(kinds.items.size(), 3u);
  expect_keys(kinds[2],
              {"kind", "rays", "embree_mrays_per_second", "binary_mrays_per_second",
               "wide_mrays_per_second", "binary_vs_embree", "wide_vs_embree"},
              "traversal");
  const Node& hetero = n["hetero"];
  ASSERT_EQ(hetero["alone"].items.size(), 2u);
  EXPECT_EQ(hetero["alone"][1]["backend"].string, "host");
  EXPECT_EQ(hetero["together"]["list"].string, "cpu+host");
  EXPECT_EQ(hetero["together"]["backends"].items.size(), 2u);
  // The printed table and the file carry the same figure.
  char printed[32];
  std::snprintf(printed, sizeof(printed), "%8.2f Mrays/s",
                n["plain_embree_mrays_per_second"].number);
  EXPECT_NE(r.output.find(printed), std::string::npos) << printed << "\n" << r.output;
}

// --repeat N: the three measurements N times, interleaved; the reported
// figures are the medians of the runs, which the report lists too.
TEST_F(BenchJson, RepeatReportsTheMediansOfItsRuns) {
  const fs::path out = file("repeat.json");
  const RunResult r = run_tandem(
      "bench --width 16 --height 12 --spp 1 --max-depth 2 --threads 1 --repeat 3 --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("medians of 3 interleaved runs"), std::string::npos) << r.output;
  const Node n = read_json(out);
  EXPECT_EQ(n["repeat"].number, 3.0);
  const Node& runs = n["runs_mrays_per_second"];
  auto median_of = [](const Node& list) {
    std::vector<double> v;
    for (const Node& x : list.items)
      v.push_back(x.number);
    std::sort(v.begin(), v.end());
    return v.size() == 3 ? v[1] : -1.0;
  };
  for (const char* key : {"plain_embree", "plain_embree_path_rays", "path_tracing_cpu"})
    ASSERT_EQ(runs[key].items.size(), 3u) << key;
  EXPECT_EQ(n["plain_embree_mrays_per_second"].number, median_of(runs["plain_embree"]));
  EXPECT_EQ(n["plain_embree_path_rays"]["mrays_per_second"].number,
            median_of(runs["plain_embree_path_rays"]));
  EXPECT_EQ(n["path_tracing_cpu"]["mrays_per_second"].number, median_of(runs["path_tracing_cpu"]));
  EXPECT_EQ(n["ratio_path_over_plain_path_rays"].number,
            median_of(runs["path_tracing_cpu"]) / median_of(runs["plain_embree_path_rays"]));
}

TEST_F(BenchJson, FrameLoopMode) {
  const fs::path out = file("frames.json");
  const RunResult r = run_tandem(
      "bench --frames 3 --scene builtin:cornell --width 16 --height 16 --backend host --kernel "
      "megakernel --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Node n = read_json(out);
  expect_run_facts(n, "frames");
  expect_keys(
      n,
      {"backend", "kernel", "first_frame_ms", "frames_measured", "frame_ms_p50", "frame_ms_p99",
       "fps", "scene_delta_kib_per_frame", "pose_ms_p50", "sync_scene_ms_p50",
       "update_accstruc_ms_p50", "sync_accstruc_ms_p50", "mrays_per_second", "backends"},
      "frames");
  EXPECT_EQ(n["frames_measured"].number, 2.0);
  EXPECT_EQ(n["backend"].string, "host");
  EXPECT_EQ(n["kernel"].string, "megakernel");
  ASSERT_EQ(n["backends"].items.size(), 1u);
  EXPECT_EQ(n["backends"][0]["name"].string, "host");
}

// The two light samplers at equal time on the many-light scene: both
// figures, the speed-up, the tree's cost; the reference is cached and read
// back on the second run; a bad sampler name is a usage error.
TEST_F(BenchJson, LightSamplingMode) {
  const fs::path out = file("lights.json");
  const std::string args =
      "bench --light-sampling --width 24 --height 16 --seconds 0.05 "
      "--reference-spp 4 --max-depth 2 --reference-cache " +
      shell_quote(dir_->path().string()) + " --json " + shell_quote(out.string());
  RunResult r = run_tandem(args);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("(rendered"), std::string::npos) << r.output;
  const Node n = read_json(out);
  expect_run_facts(n, "light_sampling");
  EXPECT_EQ(n["scene"].string, "builtin:many-lights");
  expect_keys(n,
              {"seconds_per_sampler", "reference_spp", "lights", "power", "tree",
               "speedup_time_to_equal_noise", "tables"},
              "light_sampling");
  for (const char* s : {"power", "tree"}) {
    expect_keys(n[s], {"spp", "seconds", "samples_per_second", "relmse"}, s);
    EXPECT_GT(n[s]["spp"].number, 0.0) << s;
    EXPECT_GT(n[s]["relmse"].number, 0.0) << s;
  }
  EXPECT_GT(n["lights"]["triangles"].number, 1000.0);
  EXPECT_GT(n["tables"]["tree_nodes"].number, 2000.0);
  EXPECT_GT(n["tables"]["tree_bytes"].number, 0.0);
  r = run_tandem(args);
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("(cached"), std::string::npos) << r.output;
  r = run_tandem(
      "render builtin:cornell --width 8 --height 8 --spp 1 --light-sampler nearest "
      "--output " +
      shell_quote(file("x.png").string()));
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("--light-sampler must be power or tree"), std::string::npos) << r.output;
}

// A moving scene's own work per frame is reported stage by stage: the
// arena's walkers are skinned (pose) and the host backend's BVH refit.
TEST_F(BenchJson, FrameLoopReportsTheSceneWorkOfAMovingScene) {
  const fs::path out = file("arena.json");
  const RunResult r = run_tandem(
      "bench --frames 4 --scene builtin:arena --width 16 --height 16 --backend host --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("scene work per frame p50:  pose "), std::string::npos) << r.output;
  const Node n = read_json(out);
  EXPECT_GT(n["pose_ms_p50"].number, 0.0);
  EXPECT_GT(n["sync_scene_ms_p50"].number, 0.0);
  EXPECT_GT(n["update_accstruc_ms_p50"].number, 0.0);
}

// What was shown and how close it came to a converged frame: the figures
// the viewer's resolution floor is chosen from.
TEST_F(BenchJson, FrameLoopReportsWhatWasShownAndItsMotionQuality) {
  const fs::path out = file("quality.json");
  const RunResult r = run_tandem(
      "bench --frames 6 --scene builtin:cornell --width 24 --height 16 --backend cpu "
      "--motion-reference-spp 4 --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("motion relMSE:"), std::string::npos) << r.output;
  const Node n = read_json(out);
  EXPECT_EQ(n["shown_width"].number, 24.0);
  EXPECT_EQ(n["shown_height"].number, 16.0);
  EXPECT_EQ(n["spp_per_frame"].number, 1.0);
  EXPECT_GT(n["motion_relmse"].number, 0.0);
  EXPECT_EQ(n["motion_relmse_frames"].items.size(), 4u);
  EXPECT_EQ(n["motion_reference_spp"].number, 4.0);
  const RunResult few = run_tandem(
      "bench --frames 4 --scene builtin:cornell --width 8 --height 8 --motion-reference-spp 4");
  EXPECT_EQ(few.exit_code, 2) << few.output;
}

TEST_F(BenchJson, GpuModeWritesJsonOrSaysWhyNot) {
  const fs::path out = file("gpu.json");
  const RunResult r = run_tandem("bench --gpu --width 16 --height 16 --gpu-frames 1 --json " +
                                 shell_quote(out.string()));
  std::string reason;
  if (!cuda_device_available(&reason)) {
    // No device (or no CUDA backend in this build): one line with the
    // reason, before anything is measured or written.
    EXPECT_EQ(r.exit_code, 1) << r.output;
    EXPECT_NE(r.output.find("tandem: error: bench --gpu: " + reason), std::string::npos)
        << r.output;
    EXPECT_EQ(r.output.find("embree"), std::string::npos) << r.output;
    EXPECT_FALSE(fs::exists(out));
    return;
  }
  ASSERT_EQ(r.exit_code, 0) << r.output;
  const Node n = read_json(out);
  expect_run_facts(n, "gpu");
  EXPECT_EQ(n["width"].number, 1920.0);
  EXPECT_EQ(n["height"].number, 1080.0);
  ASSERT_EQ(n["ray_sets"].items.size(), 3u);
  ASSERT_EQ(n["path_tracing"].items.size(), 4u);  // 2 kernels x 2 layouts
  for (const Node& run : n["path_tracing"].items)
    EXPECT_GT(run["samples_per_second"].number, 0.0);
}

TEST_F(BenchJson, BadJsonPathFailsBeforeMeasuring) {
  const std::string missing = (dir_->path() / "no" / "such" / "dir" / "r.json").string();
  for (const std::string& args :
       {"bench --width 8 --height 8 --spp 1 --json " + shell_quote(dir_->path().string()),
        "bench --width 8 --height 8 --spp 1 --json " + shell_quote(missing),
        "bench --frames 2 --width 8 --height 8 --backend cpu --json " + shell_quote(missing),
        "bench --gpu --json " + shell_quote(missing)}) {
    const RunResult r = run_tandem(args);
    EXPECT_EQ(r.exit_code, 1) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("tandem: error: --json "), std::string::npos) << args << r.output;
    // Nothing measured: no figures printed.
    EXPECT_EQ(r.output.find("Mrays/s"), std::string::npos) << args << r.output;
    EXPECT_EQ(r.output.find("embree build"), std::string::npos) << args << r.output;
    EXPECT_EQ(std::count(r.output.begin(), r.output.end(), '\n'), 1) << args << r.output;
  }
  EXPECT_NE(run_tandem("bench --json " + shell_quote(missing)).output.find("does not exist"),
            std::string::npos);
  EXPECT_NE(run_tandem("bench --json " + shell_quote(dir_->path().string()))
                .output.find("is a directory"),
            std::string::npos);
}

TEST(KernelOption, RenderAcceptsItForCudaAndHostBackends) {
  TempDir dir("tandem_kernel");
  const std::string out = " --output " + shell_quote((dir.path() / "x.pfm").string());
  const std::string tiny = "render builtin:cornell --width 8 --height 8 --spp 1 --quiet";
  for (const char* ok : {"--backend host --kernel mega", "--backend host --kernel megakernel",
                         "--backend cpu+host --kernel megakernel", "--kernel wave",
                         "--backend host --kernel wavefront", "--backend cpu+host --kernel wave",
                         "--backend cpu --kernel wavefront", "--backend auto --kernel wavefront",
                         "--backend hetero --kernel mega"}) {
    const RunResult r = run_tandem(tiny + " " + ok + out);
    EXPECT_EQ(r.exit_code, 0) << ok << "\n" << r.output;
  }
  // --backend cuda --kernel wave is valid usage; without a device it fails
  // for the device (1), not the option (2).
  const RunResult cuda = run_tandem(tiny + " --backend cuda --kernel wave" + out);
  EXPECT_NE(cuda.exit_code, 2) << cuda.output;
}

TEST(KernelOption, RefusedWhereItDoesNotApply) {
  struct Case {
    const char* args;
    const char* message;
  };
  const Case cases[] = {
      {"render builtin:cornell --kernel quantum", "--kernel: unknown kernel 'quantum'"},
      {"bench --gpu --kernel quantum", "unknown kernel"},
      {"bench --gpu --accstruc", "cannot be combined"},
      {"bench --gpu --spp 4", "do not apply"},
      {"bench --gpu --repeat 3", "--repeat does not apply"},
      {"bench --repeat 0", "--repeat"},
      {"bench --gpu-frames 3", "needs --gpu"},
      {"bench --gpu --width 0", "--width"},
      {"bench --gpu --gpu-frames 0", "--gpu-frames"},
  };
  for (const Case& c : cases) {
    const RunResult r = run_tandem(c.args);
    EXPECT_EQ(r.exit_code, 2) << c.args << "\n" << r.output;
    EXPECT_NE(r.output.find(c.message), std::string::npos) << c.args << "\n" << r.output;
  }
}

TEST(KernelOption, HelpDescribesTheNewOptions) {
  const RunResult bench = run_tandem("bench --help");
  EXPECT_EQ(bench.exit_code, 0);
  for (const char* o : {"--gpu", "--gpu-frames", "--kernel", "--json", "megakernel"})
    EXPECT_NE(bench.output.find(o), std::string::npos) << o;
  const RunResult frames = run_tandem("bench --frames 1 --help");
  EXPECT_NE(frames.output.find("--json"), std::string::npos);
  EXPECT_NE(frames.output.find("--kernel"), std::string::npos);
  const RunResult render = run_tandem("render --help");
  EXPECT_NE(render.output.find("--kernel"), std::string::npos);
}

}  // namespace
}  // namespace tandem
