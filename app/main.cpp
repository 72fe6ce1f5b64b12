// The `tandem` command-line tool. Exit codes: 0 success, 1 bad input (the
// message names the file and the reason), 2 bad usage.
#include <cstdio>
#include <exception>
#include <new>
#include <string>
#include <vector>

#include "app/cli_options.h"
#include "app/commands.h"
#include "core/util/activity.h"
#include "core/util/errors.h"
#include "core/util/interrupt.h"

namespace {

void print_usage() {
  std::printf(
      "usage: tandem <command> [options]\n\n"
      "commands:\n"
      "  render SCENE   render a .gltf/.glb file or builtin:NAME to an image\n"
      "  info SCENE     print what a scene contains\n"
      "  export SCENE   write a scene (a file or builtin:NAME) as one self-contained .gltf\n"
      "  compare A B    check that two linear renders agree up to Monte Carlo noise\n"
      "  bench [SCENE]  measure throughput against a plain Embree loop in the same run\n\n"
      "Run 'tandem <command> --help' (or -h) for the options of a command; 'tandem --version'\n"
      "prints the version.\n"
      "Built-in scenes: builtin:cornell, builtin:cornell-spheres, builtin:furnace, "
      "builtin:sky-plane,\n"
      "builtin:arena, builtin:procedural, builtin:many-lights\n");
}

bool is_subcommand(const std::string& name) {
  return name == "render" || name == "info" || name == "export" || name == "compare" ||
         name == "bench";
}

}  // namespace

int main(int argc, char** argv) {
  const std::vector<std::string> args(argv + 1, argv + argc);
  tandem::install_interrupt_handlers();
  try {
    if (args.empty() || args[0] == "--help" || args[0] == "-h" || args[0] == "help") {
      print_usage();
      return args.empty() ? 2 : 0;
    }
    if (args[0] == "--version" || args[0] == "version") {
      std::printf("tandem %s\n", tandem::tandem_version());
      return 0;
    }
    const std::vector<std::string> rest(args.begin() + 1, args.end());
    if (args[0] == "render") return tandem::run_render(rest);
    if (args[0] == "info") return tandem::run_info(rest);
    if (args[0] == "export") return tandem::run_export(rest);
    if (args[0] == "compare") return tandem::run_compare(rest);
    if (args[0] == "bench") return tandem::run_bench(rest);
    throw tandem::UsageError("unknown command '" + args[0] + "'");
  } catch (const tandem::UsageError& e) {
    // A subcommand's mistake points at that subcommand's options.
    const bool subcommand = !args.empty() && is_subcommand(args[0]);
    std::fprintf(stderr, "tandem: error: %s\nsee 'tandem %s--help'\n", e.what(),
                 subcommand ? (args[0] + " ").c_str() : "");
    return 2;
  } catch (const tandem::InputError& e) {
    std::fprintf(stderr, "tandem: error: %s\n", e.what());
    return 1;
  } catch (const std::bad_alloc&) {
    // Loaders name the file themselves; this is whatever else ran short,
    // named by the stage that was running (core/util/activity.h).
    const std::string activity = tandem::current_activity();
    std::fprintf(stderr,
                 "tandem: error: %s: not enough memory%s%s (try a smaller image, fewer samples per "
                 "frame or a smaller scene)\n",
                 args.empty() ? "tandem" : args[0].c_str(), activity.empty() ? "" : " while ",
                 activity.c_str());
    return 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "tandem: error: %s\n", e.what());
    return 1;
  }
}
