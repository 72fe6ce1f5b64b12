// The benchmarks' reports without running a benchmark: the JSON writer read
// back by an independent parser, the output-path checks, the median of
// repeated runs, and the table and JSON of `bench --gpu` from made-up
// figures (no GPU needed).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <limits>

#include "app/bench/bench_gpu_report.h"
#include "app/bench/bench_report.h"
#include "app/json_writer.h"
#include "core/util/errors.h"
#include "tests/json_test_parser.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using json_test::Node;

TEST(JsonWriter, EscapesStringsSoTheyReadBackExactly) {
  std::string nasty = "quote \" backslash \\ newline \n tab \t cr \r bell \a nul-free \x01 end";
  nasty += " utf-8 \xc3\xa9";
  JsonValue v = JsonValue::object();
  v.set(nasty, nasty);
  const Node n = json_test::parse(v.dump());
  ASSERT_EQ(n.members.size(), 1u);
  EXPECT_EQ(n.members[0].first, nasty);
  EXPECT_EQ(n.members[0].second.string, nasty);
}

TEST(JsonWriter, NumbersRoundTripAndNonFiniteBecomesNull) {
  JsonValue a = JsonValue::array();
  const double values[] = {0.0, -1.5, 1e-300, 123456789.125, 1.0 / 3.0, 6.02214076e23};
  for (double d : values)
    a.push(d);
  a.push(std::numeric_limits<double>::quiet_NaN());
  a.push(std::numeric_limits<double>::infinity());
  a.push(uint64_t(18446744073709551615ull));
  a.push(int64_t(-42));
  a.push(true).push(JsonValue());
  const Node n = json_test::parse(a.dump());
  ASSERT_EQ(n.items.size(), 12u);
  for (size_t i = 0; i < 6; ++i)
    EXPECT_EQ(n[i].number, values[i]) << i;
  EXPECT_EQ(n[6].type, Node::Type::kNull);
  EXPECT_EQ(n[7].type, Node::Type::kNull);
  EXPECT_EQ(n[8].number, 18446744073709551615.0);
  EXPECT_EQ(n[9].number, -42.0);
  EXPECT_TRUE(n[10].boolean);
  EXPECT_EQ(n[11].type, Node::Type::kNull);
}

TEST(JsonWriter, ObjectsKeepInsertionOrderAndReplaceKeys) {
  JsonValue v = JsonValue::object();
  v.set("z", 1).set("a", JsonValue::object()).set("m", JsonValue::array()).set("z", 2);
  const Node n = json_test::parse(v.dump());
  ASSERT_EQ(n.members.size(), 3u);
  EXPECT_EQ(n.members[0].first, "z");
  EXPECT_EQ(n["z"].number, 2.0);
  EXPECT_EQ(n.members[1].first, "a");
  EXPECT_EQ(n.members[2].first, "m");
  EXPECT_THROW(JsonValue(1).set("x", 1), std::logic_error);
  EXPECT_THROW(JsonValue::object().push(1), std::logic_error);
}

TEST(BenchReport, RunFactsAreThere) {
  JsonValue r = bench_report("path", 3);
  set_render_facts(r, "builtin:cornell", 64, 32, 2, 4);
  const Node n = json_test::parse(r.dump());
  EXPECT_EQ(n["tool"].string, "tandem bench");
  EXPECT_EQ(n["mode"].string, "path");
  EXPECT_EQ(n["threads"].number, 3.0);
  EXPECT_GE(n["hardware_threads"].number, 1.0);
  EXPECT_EQ(n["date_utc"].string.size(), 20u);  // 2026-01-31T12:34:56Z
  EXPECT_EQ(n["date_utc"].string.back(), 'Z');
  EXPECT_TRUE(n["cpu"].is_string());
  EXPECT_EQ(n["scene"].string, "builtin:cornell");
  EXPECT_EQ(n["width"].number, 64.0);
  EXPECT_EQ(n["height"].number, 32.0);
  EXPECT_EQ(n["spp"].number, 2.0);
  EXPECT_EQ(n["max_depth"].number, 4.0);
}

TEST(BenchReport, OutputPathIsCheckedAndWrittenAtomically) {
  TempDir dir("tandem_report");
  const fs::path file = dir.path() / "r.json";
  EXPECT_NO_THROW(check_json_output_path(file.string()));
  EXPECT_THROW(check_json_output_path(dir.path().string()), InputError);
  EXPECT_THROW(check_json_output_path((dir.path() / "missing" / "r.json").string()), InputError);
  EXPECT_THROW(check_json_output_path(""), InputError);
  try {
    check_json_output_path(dir.path().string());
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(dir.path().string()), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("directory"), std::string::npos) << e.what();
  }
  if (::geteuid() != 0) {  // root writes anywhere
    const fs::path locked = dir.path() / "locked";
    fs::create_directory(locked);
    ::chmod(locked.c_str(), 0500);
    EXPECT_THROW(check_json_output_path((locked / "r.json").string()), InputError);
    ::chmod(locked.c_str(), 0700);
  }
  write_json_report(file.string(), JsonValue::object().set("k", "v"));
  write_json_report(std::nullopt, JsonValue::object());  // no path: nothing
  std::ifstream in(file);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_EQ(json_test::parse(text)["k"].string, "v");
  size_t entries = 0;
  for ([[maybe_unused]] const auto& e : fs::directory_iterator(dir.path()))
    ++entries;
  EXPECT_EQ(entries, ::geteuid() != 0 ? 2u : 1u);  // r.json (and locked/), no temporary
}

GpuBenchFigures fake_gpu_figures() {
  GpuBenchFigures f;
  f.device = "Fake GPU 9000";
  f.scene = "builtin:cornell";
  f.embree_threads = 16;
  f.ray_width = f.ray_height = 512;
  f.frame_width = 1920;
  f.frame_height = 1080;
  f.spp = 1;
  f.max_depth = 4;
  f.warmup_frames = 2;
  f.timed_frames = 10;
  f.rays = {{"camera", false, 262144, 50.0, 1000.0, 1250.0},
            {"shadow", true, 200000, 80.0, 2000.0, 2400.0},
            {"diffuse", false, 250000, 20.0, 500.0, 600.0}};
  f.frames = {{"megakernel", "binary", 12.5, 165.0e6, 700.0},
              {"megakernel", "wide", 10.0, 207.0e6, 880.0},
              {"wavefront", "binary", 14.0, 148.0e6, 620.0},
              {"wavefront", "wide", 11.0, 188.0e6, 790.0}};
  return f;
}

// The one median every repeating bench mode reports: the middle value, the
// mean of the middle two, 0 for no runs; and its runs as a JSON list.
TEST(BenchReport, MedianAndRunList) {
  EXPECT_EQ(median({3.0, 1.0, 2.0}), 2.0);
  EXPECT_EQ(median({4.0, 1.0, 3.0, 2.0}), 2.5);
  EXPECT_EQ(median({7.0}), 7.0);
  EXPECT_EQ(median({}), 0.0);
  const Node n = json_test::parse(json_number_list({1.5, -2.0, 3.0}).dump());
  ASSERT_EQ(n.items.size(), 3u);
  EXPECT_EQ(n[0].number, 1.5);
  EXPECT_EQ(n[1].number, -2.0);
  EXPECT_EQ(n[2].number, 3.0);
}

TEST(GpuBenchReport, TableShowsEveryFigure) {
  const std::string t = format_gpu_bench_table(fake_gpu_figures());
  for (const char* expected : {"Fake GPU 9000",
                               "builtin:cornell",
                               "512x512",
                               "1920x1080",
                               "1 spp",
                               "max depth 4",
                               "median of 10 frames",
                               "camera rays (262144)",
                               "shadow rays, any hit (200000)",
                               "diffuse rays (250000)",
                               "1000.00",
                               "20.00",  // camera binary: 1000 / 50 Embree
                               "25.00",  // camera wide: 1250 / 50
                               "2400.00",
                               "30.00",  // shadow wide, 2400 / 80
                               "megakernel",
                               "wavefront",
                               "165.00",
                               "12.50",
                               "207.00",
                               "10.00",
                               "11.00"}) {
    EXPECT_NE(t.find(expected), std::string::npos) << expected << "\n" << t;
  }
  // One row per ray set and layout (embree, binary, wide), one per run.
  EXPECT_EQ(std::count(t.begin(), t.end(), '\n'), 4 + 9 + 4) << t;
}

TEST(GpuBenchReport, JsonHasEveryFigure) {
  JsonValue r = bench_report("gpu", 16);
  add_gpu_bench_json(r, fake_gpu_figures());
  const Node n = json_test::parse(r.dump());
  EXPECT_EQ(n["mode"].string, "gpu");
  EXPECT_EQ(n["device"].string, "Fake GPU 9000");
  EXPECT_EQ(n["width"].number, 1920.0);
  EXPECT_EQ(n["height"].number, 1080.0);
  EXPECT_EQ(n["spp"].number, 1.0);
  EXPECT_EQ(n["max_depth"].number, 4.0);
  EXPECT_EQ(n["ray_set_width"].number, 512.0);
  EXPECT_EQ(n["timed_frames"].number, 10.0);
  const Node& sets = n["ray_sets"];
  ASSERT_EQ(sets.items.size(), 3u);
  EXPECT_EQ(sets[0]["kind"].string, "camera");
  EXPECT_FALSE(sets[0]["any_hit"].boolean);
  EXPECT_TRUE(sets[1]["any_hit"].boolean);
  EXPECT_EQ(sets[1]["rays"].number, 200000.0);
  EXPECT_EQ(sets[1]["embree_mrays_per_second"].number, 80.0);
  EXPECT_EQ(sets[1]["gpu_binary_mrays_per_second"].number, 2000.0);
  EXPECT_EQ(sets[1]["gpu_wide_mrays_per_second"].number, 2400.0);
  EXPECT_EQ(sets[1]["gpu_binary_vs_embree"].number, 25.0);
  EXPECT_EQ(sets[1]["gpu_wide_vs_embree"].number, 30.0);
  const Node& runs = n["path_tracing"];
  ASSERT_EQ(runs.items.size(), 4u);
  EXPECT_EQ(runs[3]["kernel"].string, "wavefront");
  EXPECT_EQ(runs[3]["layout"].string, "wide");
  EXPECT_EQ(runs[3]["ms_per_frame_median"].number, 11.0);
  EXPECT_EQ(runs[3]["samples_per_second"].number, 188.0e6);
  EXPECT_EQ(runs[3]["mrays_per_second"].number, 790.0);
}

}  // namespace
}  // namespace tandem
