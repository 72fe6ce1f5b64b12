// libFuzzer entry for the glTF loader: the input is a .gltf (JSON) or, when
// it starts with the "glTF" magic, a .glb. The only acceptable outcome
// besides a scene is an InputError; anything else (a crash, a sanitizer
// report, another exception, a leak, running past the memory limit) is a bug.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>

#include "core/util/errors.h"
#include "core/util/log.h"
#include "scenes/gltf_animation.h"
#include "scenes/gltf_loader.h"

namespace {

// An empty folder for relative URIs to resolve in: nothing outside it may
// be read, and nothing inside it exists.
const std::filesystem::path& base_dir() {
  static const std::filesystem::path dir = [] {
    char name[] = "/tmp/tandem_fuzz_gltf_XXXXXX";
    const char* made = ::mkdtemp(name);
    return std::filesystem::path(made ? made : "/nonexistent");
  }();
  return dir;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  static const bool quiet = [] {
    tandem::set_log_level(tandem::LogLevel::kQuiet);
    return true;
  }();
  (void)quiet;
  tandem::GltfOptions options;
  // Budgets well inside the run's -rss_limit_mb, so that a file which gets
  // past them is a finding rather than an out-of-memory report.
  options.limits.max_accessor_bytes = uint64_t(64) << 20;
  options.limits.max_zero_filled_elements = uint64_t(1) << 20;
  options.limits.max_geometry_bytes = uint64_t(128) << 20;
  options.limits.max_instances = uint64_t(1) << 16;
  options.limits.max_texture_pixels = uint64_t(1) << 22;
  options.limits.max_texture_bytes = uint64_t(64) << 20;
  tandem::GltfAnimations animations;
  options.animations = &animations;  // animation channels are decoded too
  const bool binary = size >= 4 && std::memcmp(data, "glTF", 4) == 0;
  try {
    tandem::load_gltf_from_memory(data, size, binary ? "fuzz.glb" : "fuzz.gltf", base_dir(),
                                  options);
  } catch (const tandem::InputError&) {
  }
  return 0;
}
