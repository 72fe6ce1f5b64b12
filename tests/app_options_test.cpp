// The command-line surface: option tables composed from shared groups and
// one parser, help and version everywhere, usage errors that point at the
// right help, and options checked before any work.
#include <gtest/gtest.h>
#include <sys/wait.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "app/cli_args.h"
#include "app/cli_options.h"
#include "core/util/errors.h"
#include "core/world/kernel_scene.h"
#include "tests/app_run_tandem.h"
#include "tests/test_temp_dir.h"

namespace fs = std::filesystem;
using tandem::TempDir;
using tandem::app_test::run_tandem;
using tandem::app_test::RunResult;
using tandem::app_test::shell_quote;

namespace {

// "NAME 1.2.3\n" (no std::regex: GCC 12 warns inside it under -O1 + ASan).
bool is_version_line(const std::string& text, const std::string& name) {
  if (text.rfind(name + " ", 0) != 0 || text.empty() || text.back() != '\n') return false;
  const std::string v = text.substr(name.size() + 1, text.size() - name.size() - 2);
  int dots = 0;
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] == '.') {
      if (i == 0 || i + 1 == v.size() || v[i - 1] == '.') return false;
      ++dots;
    } else if (v[i] < '0' || v[i] > '9') {
      return false;
    }
  }
  return dots == 2;
}

// --- the parser and the tables ---------------------------------------------

TEST(OptionTables, ComposeReplacesASpecInPlaceAndDefaultsComeFromTheTable) {
  const std::vector<tandem::OptionSpec> specs = tandem::compose_options({
      tandem::image_size_options("512", "256"),
      {{"width", true, "window width", "W", "64"}},
      tandem::help_options(),
  });
  ASSERT_EQ(specs.size(), 3u);
  EXPECT_EQ(specs[0].name, "width");
  EXPECT_EQ(specs[0].default_value, "64");
  EXPECT_EQ(specs[1].name, "height");
  const tandem::ParsedArgs none("t", specs, {});
  EXPECT_EQ(none.get_u32("width", 1, 100), 64u);
  EXPECT_EQ(none.get_u32("height", 1, 1000), 256u);
  EXPECT_FALSE(none.has("width"));  // a default is not "given"
  const tandem::ParsedArgs given("t", specs, {"--height", "9", "-h"});
  EXPECT_EQ(given.get_u32("height", 1, 1000), 9u);
  EXPECT_TRUE(given.has("help"));
  // The help shows the defaults the parser uses.
  const std::string help = tandem::format_options_help(specs);
  EXPECT_NE(help.find("window width (default 64)"), std::string::npos) << help;
  EXPECT_NE(help.find("(default 256)"), std::string::npos) << help;
  // A declared default is range-checked like a given value.
  EXPECT_THROW(none.get_u32("width", 100, 200), tandem::UsageError);
}

TEST(OptionTables, MinusHIsOnlyHelpWhereThereIsHelp) {
  const std::vector<tandem::OptionSpec> no_help = tandem::image_size_options("1", "1");
  EXPECT_THROW(tandem::ParsedArgs("t", no_help, {"-h"}), tandem::UsageError);
}

// The shared groups read the same in every command's help: the same line
// for --env-intensity in render, bench, the frame bench and (where built)
// tandem-view, not four copies drifting apart.
TEST(OptionTables, SharedOptionsReadTheSameInEveryCommand) {
  auto line_of = [](const std::string& help, const std::string& option) {
    const size_t at = help.find("  " + option + " ");
    if (at == std::string::npos) return std::string("(missing)");
    return help.substr(at, help.find('\n', at) - at);
  };
  const std::string render = run_tandem("render --help").output;
  const std::string bench = run_tandem("bench --help").output;
  const std::string frames = run_tandem("bench --frames 1 --help").output;
  for (const char* option :
       {"--env", "--env-color", "--env-intensity", "--env-rotation", "--gltf-scene",
        "--allow-outside-uris", "--threads", "--light-sampler"}) {
    const std::string expected = line_of(render, option);
    EXPECT_NE(expected, "(missing)") << option;
    EXPECT_EQ(line_of(bench, option), expected) << option;
    EXPECT_EQ(line_of(frames, option), expected) << option;
#ifdef TANDEM_VIEW_BINARY
    const std::string view =
        tandem::app_test::run_command(shell_quote(TANDEM_VIEW_BINARY) + " --help").output;
    EXPECT_EQ(line_of(view, option), expected) << option;
#endif
  }
  // --backend and --kernel come from one group too (bench's own --kernel
  // aside, which explains what it applies to there).
  EXPECT_EQ(line_of(frames, "--kernel"), line_of(render, "--kernel"));
}

TEST(OptionTables, RenderSettingsCompareEveryField) {
  const tandem::RenderSettings base;
  EXPECT_TRUE(base == tandem::RenderSettings{});
  tandem::RenderSettings s = base;
  s.rr_start_depth += 1;
  EXPECT_FALSE(s == base);
  s = base;
  s.radiance_clamp = 2.0f;
  EXPECT_FALSE(s == base);
  s = base;
  s.seed = 7;
  EXPECT_TRUE(s != base);
}

// --- help, version, usage errors ---------------------------------------------

TEST(CliSurface, EverySubcommandHasHelpWithDashHAndDashDashHelp) {
  EXPECT_EQ(run_tandem("--help").exit_code, 0);
  EXPECT_NE(run_tandem("render --help").output.find("--spp"), std::string::npos);
  for (const char* command : {"render", "info", "export", "compare", "bench"}) {
    for (const char* flag : {"-h", "--help"}) {
      const RunResult r = run_tandem(std::string(command) + " " + flag);
      EXPECT_EQ(r.exit_code, 0) << command << " " << flag << "\n" << r.output;
      EXPECT_NE(r.output.find(std::string("usage: tandem ") + command), std::string::npos)
          << command << " " << flag << "\n"
          << r.output;
    }
  }
}

TEST(CliSurface, VersionOfTandem) {
  const RunResult r = run_tandem("--version");
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_TRUE(is_version_line(r.output, "tandem")) << r.output;
}

TEST(CliSurface, UsageErrorPointsAtTheSubcommandsHelp) {
  RunResult r = run_tandem("render builtin:cornell --bogus");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("see 'tandem render --help'"), std::string::npos) << r.output;
  r = run_tandem("bench --spp x");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("see 'tandem bench --help'"), std::string::npos) << r.output;
  r = run_tandem("info");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("see 'tandem info --help'"), std::string::npos) << r.output;
  r = run_tandem("frobnicate");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.output.find("see 'tandem --help'"), std::string::npos) << r.output;
}

TEST(CliSurface, BenchHelpListsTheFrameLoopModeAndItTakesAPositionalScene) {
  const RunResult help = run_tandem("bench --help");
  ASSERT_EQ(help.exit_code, 0);
  EXPECT_NE(help.output.find("--frames N"), std::string::npos) << help.output;
  EXPECT_NE(help.output.find("Frame-loop mode"), std::string::npos) << help.output;
  EXPECT_NE(help.output.find("--scene SCENE"), std::string::npos) << help.output;
  const RunResult r =
      run_tandem("bench builtin:arena --frames 3 --width 32 --height 16 --backend cpu --threads 1");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("scene builtin:arena"), std::string::npos) << r.output;
  EXPECT_EQ(run_tandem("bench builtin:arena --scene builtin:cornell --frames 3").exit_code, 2);
  const RunResult inline_value =
      run_tandem("bench builtin:arena --frames=2 --width 16 --height 16 --backend cpu --threads 1");
  EXPECT_EQ(inline_value.exit_code, 0) << inline_value.output;
  const RunResult both = run_tandem(
      "render builtin:cornell --env-color 1 --env x.hdr --output /tmp/never_written.png");
  EXPECT_EQ(both.exit_code, 2) << both.output;
  EXPECT_NE(both.output.find("either --env or --env-color"), std::string::npos) << both.output;
}

// --- checks before work --------------------------------------------------------

TEST(CliSurface, MissingOrBadOutputDirectoryIsReportedBeforeRendering) {
  TempDir dir("tandem_options");
  const fs::path file = dir.path() / "a_file";
  { std::ofstream(file) << "x"; }
  // Hours of work if it started rendering: the check must come first.
  for (const std::string& out :
       {std::string("/nonexistent_dir/x.png"), (file / "x.exr").string()}) {
    const auto start = std::chrono::steady_clock::now();
    const RunResult r = run_tandem(
        "render builtin:cornell --width 4096 --height 4096 --spp 100000 --backend cpu --output " +
        shell_quote(out));
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_EQ(r.exit_code, 1) << out << "\n" << r.output;
    EXPECT_NE(r.output.find(out), std::string::npos) << r.output;
    EXPECT_LT(seconds, 30.0) << "it rendered before checking " << out;
  }
}

TEST(CliSurface, ExposureAndTonemapWithLinearOutputWarn) {
  TempDir dir("tandem_options");
  const std::string quick = "render builtin:cornell --width 8 --height 8 --spp 1 --backend cpu ";
  RunResult r = run_tandem(quick + "--exposure 1 --tonemap aces --output " +
                           shell_quote((dir.path() / "x.exr").string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("warning: --exposure and --tonemap apply only to PNG output"),
            std::string::npos)
      << r.output;
  r = run_tandem(quick + "--tonemap aces --output " + shell_quote((dir.path() / "x.pfm").string()));
  EXPECT_NE(r.output.find("warning: --tonemap applies only to PNG output"), std::string::npos)
      << r.output;
  r = run_tandem(quick + "--exposure 1 --output " + shell_quote((dir.path() / "x.png").string()));
  EXPECT_EQ(r.output.find("warning"), std::string::npos) << r.output;
}

// --split F plans F of the pixels (so of the samples) for the first
// backend; without stealing that is what each backend renders, to the
// nearest tile (here 35 tiles of up to 1024 of 30000 pixels: 1.7% at most).
// A split by learned cost gave 43% / 57% here.
TEST(CliSurface, SplitWithoutStealingIsTheShareOfSamplesAsked) {
  TempDir dir("tandem_options");
  for (const char* split : {"0.5", "0.25"}) {
    const RunResult r =
        run_tandem("render builtin:cornell --backend cpu+host --split " + std::string(split) +
                   " --no-stealing --width 200 --height 150 --spp 8 --threads 2 --output " +
                   shell_quote((dir.path() / "x.pfm").string()));
    ASSERT_EQ(r.exit_code, 0) << r.output;
    // "tandem:   cpu  ... (0 stolen), 50.0% of samples, ..."
    const size_t line = r.output.find("tandem:   cpu ");
    ASSERT_NE(line, std::string::npos) << r.output;
    const size_t percent = r.output.find("% of samples", line);
    ASSERT_NE(percent, std::string::npos) << r.output;
    const size_t start = r.output.rfind(' ', percent) + 1;
    const double share = std::stod(r.output.substr(start, percent - start));
    EXPECT_NEAR(share, 100.0 * std::stod(split), 2.0) << r.output;
  }
}

}  // namespace

namespace {

#ifdef TANDEM_VIEW_BINARY
RunResult run_view(const std::string& args) {
  return tandem::app_test::run_command(shell_quote(TANDEM_VIEW_BINARY) + " " + args);
}
#endif

TEST(ViewOptions, NoWindowWithoutFramesIsAUsageError) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  for (const char* args : {"--no-window", "--no-window --backend cpu"}) {
    const RunResult r = run_view(args);
    EXPECT_EQ(r.exit_code, 2) << args << "\n" << r.output;
    EXPECT_NE(r.output.find("--no-window"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("--frames N"), std::string::npos) << r.output;
    EXPECT_NE(r.output.find("see 'tandem-view --help'"), std::string::npos) << r.output;
  }
#endif
}

TEST(ViewOptions, VersionHelpAndTheSceneOptionsOfRender) {
#ifndef TANDEM_VIEW_BINARY
  GTEST_SKIP() << "tandem-view was not built";
#else
  RunResult r = run_view("--version");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_TRUE(is_version_line(r.output, "tandem-view")) << r.output;
  EXPECT_EQ(run_view("-h").exit_code, 0);
  TempDir dir("tandem_view_options");
  const fs::path box =
      fs::path(TANDEM_SHARED_DIR) / "scenes" / "gltf" / "Box" / "glTF" / "Box.gltf";
  const std::string quick = " --no-window --frames 1 --width 16 --height 16 --backend cpu ";
  // A glTF file: the same default sky as render, announced once.
  r = run_view(shell_quote(box.string()) + quick);
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_NE(r.output.find("tandem-view: lighting"), std::string::npos) << r.output;
  // --env-color, --env and --gltf-scene as in render.
  r = run_view(shell_quote(box.string()) + quick + "--env-color 0.2,0.3,0.4 --gltf-scene 0");
  EXPECT_EQ(r.exit_code, 0) << r.output;
  EXPECT_EQ(r.output.find("built-in sky"), std::string::npos) << r.output;
  r = run_view(shell_quote(box.string()) + quick + "--env " +
               shell_quote((fs::path(TANDEM_SOURCE_DIR) / "data" / "env" / "sky.hdr").string()));
  EXPECT_EQ(r.exit_code, 0) << r.output;
  r = run_view(shell_quote(box.string()) + quick + "--gltf-scene 5");
  EXPECT_EQ(r.exit_code, 1) << r.output;
  r = run_view(shell_quote(box.string()) + quick + "--env-color purple");
  EXPECT_EQ(r.exit_code, 2) << r.output;
  r = run_view(quick + "--env " + shell_quote((dir.path() / "missing.hdr").string()));
  EXPECT_EQ(r.exit_code, 1) << r.output;
  EXPECT_NE(r.output.find("missing.hdr"), std::string::npos) << r.output;
#endif
}

}  // namespace
