// What `tandem info` lists of a glTF file beyond what was loaded: its
// scenes, animations with their lengths, skins and morph targets. Runs on
// the validated model (gltf_validate.cpp has checked every index), and
// reads only accessors' declared min/max, never their data.
#include <algorithm>
#include <cmath>

#include "scenes/gltf_internal.h"

namespace tandem::gltf {

namespace {
constexpr size_t kMaxListed = 100;
}  // namespace

void describe_file_contents(const tinygltf::Model& model, GltfSummary& s) {
  for (size_t i = 0; i < model.scenes.size() && i < kMaxListed; ++i)
    s.scene_names.push_back(model.scenes[i].name);
  for (size_t i = 0; i < model.animations.size() && i < kMaxListed; ++i) {
    const tinygltf::Animation& a = model.animations[i];
    GltfSummary::Animation info;
    info.name = a.name;
    info.channels = a.channels.size();
    // A sampler's input accessor must declare its max (the glTF spec
    // requires min and max on animation inputs): the last key time.
    for (const tinygltf::AnimationSampler& sampler : a.samplers) {
      if (sampler.input < 0 || size_t(sampler.input) >= model.accessors.size()) continue;
      const tinygltf::Accessor& input = model.accessors[size_t(sampler.input)];
      if (!input.maxValues.empty() && std::isfinite(input.maxValues[0]))
        info.seconds = std::max(info.seconds, input.maxValues[0]);
    }
    s.animation_list.push_back(std::move(info));
  }
  for (size_t i = 0; i < model.skins.size() && i < kMaxListed; ++i)
    s.skin_list.push_back({model.skins[i].name, model.skins[i].joints.size()});
  for (const tinygltf::Mesh& mesh : model.meshes) {
    size_t targets = 0;
    for (const tinygltf::Primitive& p : mesh.primitives)
      targets = std::max(targets, p.targets.size());
    if (targets > 0) ++s.morph_meshes;
    s.most_morph_targets = std::max(s.most_morph_targets, targets);
  }
}

}  // namespace tandem::gltf
