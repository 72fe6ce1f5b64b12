// `tandem bench --scene-update --json FILE`: the file is a list with one
// {scene, case, median_ms} object per scene and case, and a bad option
// fails as a usage error. Tiny runs: the plumbing, not the figures.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "tests/app_run_tandem.h"
#include "tests/json_test_parser.h"
#include "tests/test_temp_dir.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;
using app_test::run_tandem;
using app_test::RunResult;
using app_test::shell_quote;

TEST(BenchSceneUpdate, JsonListsEveryCaseOfEveryScene) {
  TempDir dir("tandem_scene_update");
  const fs::path out = dir.path() / "update.json";
  const RunResult r = run_tandem(
      "bench builtin:cornell builtin:arena --scene-update --repeats 3 --threads 2 --json " +
      shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(out);
  ASSERT_TRUE(in.good()) << out;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const json_test::Node n = json_test::parse(text);
  ASSERT_EQ(n.type, json_test::Node::Type::kArray);
  // Both scenes have emissive instances: the moving-light cases too.
  const char* cases[] = {"move_1",  "move_100",     "material_1",
                         "light_1", "move_light_1", "move_light_100"};
  const char* scenes[] = {"builtin:cornell", "builtin:arena"};
  ASSERT_EQ(n.items.size(), 12u);
  for (size_t i = 0; i < n.items.size(); ++i) {
    const json_test::Node& e = n[i];
    ASSERT_EQ(e.members.size(), 3u) << i;
    EXPECT_EQ(e["scene"].string, scenes[i / 6]) << i;
    EXPECT_EQ(e["case"].string, cases[i % 6]) << i;
    ASSERT_TRUE(e["median_ms"].is_number()) << i;
    EXPECT_GE(e["median_ms"].number, 0.0) << i;
  }
  // The printed table names every case too.
  for (const char* c : cases)
    EXPECT_NE(r.output.find(c), std::string::npos) << c << "\n" << r.output;
}

TEST(BenchSceneUpdate, BadRepeatsIsAUsageError) {
  const RunResult r = run_tandem("bench --scene-update --repeats 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

}  // namespace
}  // namespace tandem
