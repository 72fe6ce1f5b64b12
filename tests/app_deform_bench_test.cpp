// `tandem bench SCENE... --deform --json FILE`: one entry per scene with
// the per-frame figures, and the machine facts. Tiny runs: the plumbing,
// not the figures.
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

TEST(BenchDeform, JsonHasTheFiguresOfEveryScene) {
  TempDir dir("tandem_deform_bench");
  const fs::path out = dir.path() / "deform.json";
  const std::string figure =
      (fs::path(TANDEM_SHARED_DIR) / "scenes/skinned/RiggedFigure/glTF-Embedded/RiggedFigure.gltf")
          .string();
  const RunResult r = run_tandem("bench " + shell_quote(figure) +
                                 " builtin:arena --deform --frames 3 --threads 2 --json " +
                                 shell_quote(out.string()));
  ASSERT_EQ(r.exit_code, 0) << r.output;
  std::ifstream in(out);
  ASSERT_TRUE(in.good()) << out;
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const json_test::Node n = json_test::parse(text);
  EXPECT_EQ(n["mode"].string, "deform");
  EXPECT_EQ(n["frames"].number, 3.0);
  const json_test::Node& scenes = n["scenes"];
  ASSERT_EQ(scenes.items.size(), 2u);
  EXPECT_EQ(scenes[0]["scene"].string, figure);
  EXPECT_EQ(scenes[1]["scene"].string, "builtin:arena");
  // RiggedFigure's one skinned mesh; the arena's walkers.
  EXPECT_EQ(scenes[0]["deformed_vertices"].number, 370.0);
  EXPECT_GT(scenes[1]["deformed_vertices"].number, 0.0);
  for (size_t i = 0; i < 2; ++i) {
    for (const char* key :
         {"pose_ms", "update_ms", "sync_scene_ms", "update_accstruc_ms", "total_ms", "delta_bytes",
          "pose_cpu_ms", "update_cpu_ms", "sync_scene_cpu_ms", "update_accstruc_cpu_ms"}) {
      ASSERT_TRUE(scenes[i][key].is_number()) << i << " " << key;
      EXPECT_GE(scenes[i][key].number, 0.0) << i << " " << key;
    }
    // Moved vertices are committed every frame.
    EXPECT_GT(scenes[i]["delta_bytes"].number, 0.0) << i;
    // Every configuration of backends, honestly: only those with a device
    // upload anything, only those with Embree commit to it.
    EXPECT_EQ(scenes[i]["backends"].string, "host") << i;
    const json_test::Node& configs = scenes[i]["configurations"];
    ASSERT_EQ(configs.items.size(), 4u) << i;
    const char* names[4] = {"host", "cpu+cuda", "embree", "both-layouts"};
    for (size_t c = 0; c < 4; ++c) {
      EXPECT_EQ(configs[c]["backends"].string, names[c]) << i;
      EXPECT_GT(configs[c]["delta_bytes"].number, 0.0) << i << " " << names[c];
      const bool device = c == 1 || c == 3;
      EXPECT_EQ(configs[c]["upload_bytes"].number > 0.0, device) << i << " " << names[c];
      EXPECT_EQ(configs[c]["upload_bytes"].number, device ? configs[c]["delta_bytes"].number : 0.0)
          << i << " " << names[c];
    }
    // Without Tandem's BVH the delta holds the compiler's arrays alone.
    EXPECT_LT(configs[2]["delta_bytes"].number, configs[0]["delta_bytes"].number) << i;
  }
}

TEST(BenchDeform, SceneWithoutMotionIsAnInputError) {
  const RunResult r = run_tandem("bench builtin:cornell --deform --frames 1");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("builtin:cornell: nothing in the scene moves"), std::string::npos)
      << r.output;
}

TEST(BenchDeform, UnknownBackendConfigurationIsAUsageError) {
  const RunResult r = run_tandem("bench --deform --frames 1 --backends host,gpu");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  EXPECT_NE(r.output.find("unknown configuration 'gpu'"), std::string::npos) << r.output;
}

TEST(BenchDeform, BadFramesIsAUsageError) {
  const RunResult r = run_tandem("bench --deform --frames 0");
  EXPECT_EQ(r.exit_code, 2) << r.output;
}

}  // namespace
}  // namespace tandem
