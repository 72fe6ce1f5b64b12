// Every file of the bad-input corpus (../shared/scenes/bad, see its
// README.md) must be rejected with an InputError naming the file and the
// reason: no crash, no hang, no partial scene.
#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <string>
#include <vector>

#include "core/util/errors.h"
#include "scenes/gltf_loader.h"

namespace tandem {
namespace {

namespace fs = std::filesystem;

fs::path bad_dir() {
  return fs::path(TANDEM_SHARED_DIR) / "scenes/bad";
}

// .report.json, .bin and .png files are sidecars, not cases.
std::vector<fs::path> bad_files() {
  std::vector<fs::path> files;
  for (const auto& e : fs::recursive_directory_iterator(bad_dir())) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".gltf" || ext == ".glb")) files.push_back(e.path());
  }
  std::sort(files.begin(), files.end());
  return files;
}

TEST(GltfBadInput, CorpusHas38Cases) {
  EXPECT_EQ(bad_files().size(), 38u);
}

class GltfBadFile : public testing::TestWithParam<fs::path> {};

TEST_P(GltfBadFile, IsRejectedWithFileAndReason) {
  const fs::path file = GetParam();
  const std::string prefix = file.string() + ": ";
  try {
    load_gltf(file);
    FAIL() << file << " loaded without an error";
  } catch (const InputError& e) {
    const std::string msg = e.what();
    EXPECT_EQ(msg.rfind(prefix, 0), 0u) << msg;  // starts with "<path>: "
    ASSERT_GT(msg.size(), prefix.size() + 5) << msg;
    const std::string reason = msg.substr(prefix.size());
    EXPECT_EQ(reason.find('\n'), std::string::npos) << msg;  // one line
    EXPECT_NE(reason.find_first_not_of(' '), std::string::npos) << msg;
  }
}

TEST_P(GltfBadFile, IsRejectedForEverySceneIndex) {
  // The scene choice must not let a broken file through.
  for (int scene : {-1, 0, 1}) {
    GltfOptions options;
    options.scene_index = scene;
    EXPECT_THROW(load_gltf(GetParam(), options), InputError) << scene;
  }
}

std::string case_name(const testing::TestParamInfo<fs::path>& info) {
  std::string name = fs::relative(info.param, bad_dir()).string();
  for (char& c : name) {
    if (!std::isalnum(static_cast<unsigned char>(c))) c = '_';
  }
  return name;
}

INSTANTIATE_TEST_SUITE_P(Corpus, GltfBadFile, testing::ValuesIn(bad_files()), case_name);

// The specific reasons for the files tinygltf accepts (README: ok=1), so a
// regression that rejects them for some other reason is noticed.
TEST(GltfBadInput, ReasonsForFilesTinygltfAccepts) {
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"glTF-Validator/json/bom.gltf", "byte order mark"},
      {"glTF-Validator/buffer_view/invalid_length.gltf",
       "bufferView 0 (byteOffset 0, byteLength 5) runs past the end of buffer 0 (4 bytes)"},
      {"glTF-Validator/buffer_view/unresolved_buffer.gltf",
       "bufferView 0 refers to buffer 1, but the file has 1 buffer"},
      {"glTF-Validator/mesh/position_accessor_invalid_format.gltf",
       "POSITION must be VEC3 FLOAT, but is VEC4 FLOAT"},
      {"glTF-Validator/mesh/accessor_unequal_count.gltf",
       "COLOR_0 has 4 elements but POSITION has 3"},
      {"glTF-Validator/mesh_data/index_buffer_oob.gltf",
       "mesh 0 primitive 0: index 5 at position 5 is out of range (4 vertices)"},
      {"glTF-Validator/node/node_loop.gltf", "cycle"},
      {"assimp/IndexOutOfRange/IndexOutOfRange.gltf",
       "mesh 0 primitive 0: index 255 at position 0 is out of range (24 vertices)"},
      {"assimp/IndexOutOfRange/AllIndicesOutOfRange.gltf",
       "index 65535 at position 0 is out of range"},
      {"assimp/RecursiveNodes/RecursiveNodes.gltf", "cycle"},
      {"assimp/TestNoRootNode/NoScene.gltf", "no \"scenes\""},
      {"assimp/wrongTypes/badArray.gltf", "mesh 0 has no primitives"},
      {"assimp/wrongTypes/badUint.gltf",
       "materials[0].pbrMetallicRoughness.baseColorTexture.index is -1; the glTF schema requires "
       "an integer >= 0"},
      {"assimp/BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
       "POSITION (accessor 2) has a non-finite value"},
  };
  for (const auto& [file, reason] : cases) {
    try {
      load_gltf(bad_dir() / file);
      ADD_FAILURE() << file << " loaded";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(reason), std::string::npos) << e.what();
    }
  }
}

}  // namespace
}  // namespace tandem
