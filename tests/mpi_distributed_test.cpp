// `tandem render/bench --distributed` under mpirun on this machine, 2 and 3
// ranks (--oversubscribe: CI has 2 cores): the image must be the
// single-process one byte for byte whatever the number of ranks and the
// split, the moving arena frame for frame, and a failing worker must end
// the run with a message naming it, exit status 1 and no output file.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <array>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "test_temp_dir.h"
#include "tests/app_run_tandem.h"

namespace tandem {
namespace {

using CommandResult = app_test::RunResult;

// The tests' ENVIRONMENT sets Open MPI's root and container variables
// (ctest); repeated here for a direct run of the binary.
CommandResult run_command(const std::string& cmd) {
  return app_test::run_command(
      "env OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 "
      "OMPI_MCA_btl_vader_single_copy_mechanism=none " +
      cmd);
}

std::string tandem() {
  return app_test::shell_quote(TANDEM_BINARY);
}

// `ranks` processes of tandem with `args`; `env` ("NAME=value ...") for all.
CommandResult mpirun(int ranks, const std::string& args, const std::string& env = "") {
  // A bounded run: a hang would fail the test instead of stalling CI.
  return run_command("timeout 100 " + std::string(TANDEM_MPIRUN) +
                     " --oversubscribe --bind-to none -np " + std::to_string(ranks) +
                     (env.empty() ? "" : " -x " + env) + " " + tandem() + " " + args);
}

CommandResult single(const std::string& args) {
  return run_command(tandem() + " " + args);
}

std::string file_bytes(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

const std::string kSmall =
    "builtin:cornell-spheres --width 48 --height 32 --spp 6 --threads 1 --quiet";

void expect_same_image(int ranks, const std::string& backend, const std::string& extra,
                       const std::string& ext) {
  TempDir dir("tandem_mpi");
  const auto ref = dir.path() / ("ref." + ext);
  const auto dist = dir.path() / ("dist." + ext);
  const CommandResult a =
      single("render " + kSmall + " --backend " + backend + " --output " + ref.string());
  ASSERT_EQ(a.exit_code, 0) << a.output;
  const CommandResult b = mpirun(ranks, "render " + kSmall + " --backend " + backend + " " + extra +
                                            " --distributed --output " + dist.string());
  ASSERT_EQ(b.exit_code, 0) << b.output;
  EXPECT_EQ(b.output, "") << "--quiet: no rank prints anything";
  const std::string x = file_bytes(ref), y = file_bytes(dist);
  ASSERT_FALSE(x.empty());
  EXPECT_TRUE(x == y) << ranks << " ranks: the image differs from the single-process one";
}

TEST(MpiDistributed, TwoRanksGiveTheSingleProcessImageByteForByte) {
  expect_same_image(2, "cpu", "--tile-size 8", "pfm");
}

TEST(MpiDistributed, ThreeRanksAndAnotherSplitGiveTheSameImage) {
  // Smaller tiles and a forced share for rank 0's backend: other owners for
  // every pixel, the same sums.
  expect_same_image(3, "cpu", "--tile-size 4 --split 0.2", "exr");
}

TEST(MpiDistributed, WorkersTracingTandemsBvhGetItFromRankZero) {
  // The host backend traces the kernel arrays' BVH: rank 0 must build it
  // and send it, although its own backend would not need it.
  expect_same_image(2, "host", "--tile-size 8", "pfm");
}

TEST(MpiDistributed, OnlyRankZeroPrints) {
  TempDir dir("tandem_mpi");
  const auto out = dir.path() / "out.pfm";
  // Without --quiet: rank 0's summary once, nothing from the worker (whose
  // `auto` falls back to the CPU without a word).
  const CommandResult r =
      mpirun(3,
             "render builtin:cornell --width 32 --height 32 --spp 2 --tile-size 8 "
             "--threads 1 --backend auto --distributed --output " +
                 out.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  size_t summaries = 0, warnings = 0;
  for (size_t at = 0; (at = r.output.find("-> " + out.string(), at)) != std::string::npos; ++at)
    ++summaries;
  for (size_t at = 0; (at = r.output.find("warning", at)) != std::string::npos; ++at)
    ++warnings;
  EXPECT_EQ(summaries, 1u) << r.output;
  EXPECT_LE(warnings, 1u) << "at most rank 0's GPU notice\n" << r.output;
  EXPECT_NE(r.output.find("rank1:"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("rank2:"), std::string::npos) << r.output;
}

TEST(MpiDistributed, ArenaFrameLoopMatchesSingleProcessFrameForFrame) {
  TempDir dir("tandem_mpi");
  const auto json = dir.path() / "frames.json";
  const CommandResult r =
      mpirun(3,
             "bench --distributed --frames 60 --width 48 --height 27 --tile-size 8 "
             "--backend cpu --threads 1 --json " +
                 json.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("identical images:  60 of 60 frames"), std::string::npos) << r.output;
  const std::string j = file_bytes(json);
  for (const char* key :
       {"\"mode\": \"distributed\"", "\"loop\": \"frames\"", "\"ranks\": 3", "\"speedup\"",
        "\"overhead_ms_per_frame\"", "\"bytes_sent_per_frame\"", "\"scene_bytes_per_frame\"",
        "\"cpu_ms_per_frame\"", "\"render_cpu_ms_per_frame\"", "\"driver_cpu_ms_per_frame\"",
        "\"tile_time_vs_rank0_alone\"", "\"rank0_alone_cpu_ms_per_frame\"",
        "\"identical_images\": 60"})
    EXPECT_NE(j.find(key), std::string::npos) << key << "\n" << j;
}

// The number after `"key": ` at its n-th occurrence in a JSON report (-1
// when missing).
double json_number(const std::string& json, const std::string& key, int nth = 0) {
  size_t at = 0;
  for (int i = 0; i <= nth; ++i, ++at) {
    at = json.find("\"" + key + "\": ", at);
    if (at == std::string::npos) return -1.0;
  }
  return std::atof(json.c_str() + at - 1 + key.size() + 4);
}

TEST(MpiDistributed, OfflineBenchReportsEveryRank) {
  TempDir dir("tandem_mpi");
  const auto json = dir.path() / "offline.json";
  const CommandResult r =
      mpirun(2,
             "bench --distributed builtin:cornell --width 64 --height 64 --spp 8 "
             "--tile-size 8 --backend cpu --threads 1 --json " +
                 json.string());
  ASSERT_EQ(r.exit_code, 0) << r.output;
  for (const char* text : {"speed-up:", "rank1:cpu", "busy", "idle", "KiB/frame",
                           "the worker's process", "rank 0's process", "per tile vs rank 0 alone",
                           "driving it on rank 0", "identical images:  1 of 1 renders"})
    EXPECT_NE(r.output.find(text), std::string::npos) << text << "\n" << r.output;
  // While rank 0 renders alone, the worker waits for its next batch: a wait
  // that spins would cost it about that much CPU time, one that sleeps a
  // small part of it (polls back off to 1 ms apart, each a few tens of us).
  const std::string j = file_bytes(json);
  const double alone_s = json_number(j, "rank0_seconds");
  const double frames = json_number(j, "frames");
  const double worker_cpu_ms = json_number(j, "cpu_ms_per_frame", 1);
  const double worker_render_ms = json_number(j, "render_cpu_ms_per_frame", 1);
  ASSERT_GT(alone_s, 0.0) << j;
  ASSERT_GT(worker_cpu_ms, 0.0) << j;
  ASSERT_GE(worker_render_ms, 0.0) << j;
  EXPECT_GT(json_number(j, "tile_cpu_vs_rank0_alone", 1), 0.0) << j;
  const double waiting_cpu_s = (worker_cpu_ms - worker_render_ms) * frames * 1e-3;
  EXPECT_LT(waiting_cpu_s, 0.2 * alone_s)
      << "the worker spent " << waiting_cpu_s << " s of CPU beyond rendering while rank 0 "
      << "rendered alone for " << alone_s << " s\n"
      << j;
}

struct FaultCase {
  const char* fault;
  int ranks;
  const char* expected;  // in the output
};

class MpiFault : public ::testing::TestWithParam<FaultCase> {};

TEST_P(MpiFault, EndsTheRunOnEveryRankWithoutAnOutputFile) {
  const FaultCase& c = GetParam();
  TempDir dir("tandem_mpi");
  const auto out = dir.path() / "out.pfm";
  const CommandResult r =
      mpirun(c.ranks,
             "render builtin:cornell --width 32 --height 32 --spp 4 --tile-size 8 "
             "--backend cpu --threads 1 --quiet --distributed --output " +
                 out.string(),
             std::string("TANDEM_MPI_TIMEOUT=3 -x TANDEM_MPI_FAULT=") + c.fault);
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find(c.expected), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out)) << "no output from a failed run";
}

INSTANTIATE_TEST_SUITE_P(
    Kinds, MpiFault,
    ::testing::Values(FaultCase{"throw@1", 2, "rank 1: injected failure in the renderer"},
                      FaultCase{"oom@2", 3, "rank 2: out of memory"},
                      FaultCase{"hang@1", 2, "rank 1: did not answer within 3 s"},
                      // The process is gone without a word: mpirun names it.
                      FaultCase{"exit@1", 3, "[[" /* the job's process name */},
                      FaultCase{"version@2", 3, "rank 2: speaks protocol version"},
                      FaultCase{"nonsense", 2, "TANDEM_MPI_FAULT must be KIND@RANK"}),
    [](const auto& info) {
      std::string name = info.param.fault;
      for (char& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return name;
    });

TEST(MpiDistributed, BadInputOnAWorkerIsReportedByRankZero) {
  // Only rank 1 gets a bad value (mpirun's MPMD form): its backend cannot
  // be made, it tells rank 0, which names it and ends the run.
  TempDir dir("tandem_mpi");
  const auto out = dir.path() / "out.pfm";
  const std::string args =
      " render builtin:cornell --width 16 --height 16 --spp 1 --quiet --distributed --output " +
      out.string();
  const CommandResult r =
      run_command("timeout 100 " + std::string(TANDEM_MPIRUN) +
                  " --oversubscribe --bind-to none -np 1 " + tandem() + args +
                  " --backend cpu : -np 1 -x TANDEM_DEVICE=sim -x TANDEM_DEVICE_FAULT=bogus " +
                  tandem() + args + " --backend cuda");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("rank 1: TANDEM_DEVICE_FAULT='bogus'"), std::string::npos) << r.output;
  EXPECT_FALSE(std::filesystem::exists(out));
}

}  // namespace
}  // namespace tandem
