#include "scenes/scene_animator.h"

#include <algorithm>

#include "scenes/arena_scene.h"
#include "scenes/procedural_rigs.h"

namespace tandem {

namespace {

class StaticAnimator final : public SceneAnimator {
 public:
  bool animated() const override { return false; }
  void pose(double, Scene&) override {}
  double duration() const override { return 0.0; }
};

// The arena's bodies and its walking figures.
class ArenaAnimator final : public SceneAnimator {
 public:
  explicit ArenaAnimator(const Scene& scene) : simulation_(scene), rigs_(scene) {}
  bool animated() const override { return true; }
  void pose(double t, Scene& scene) override {
    simulation_.advance_to(std::max(t, 0.0), scene);
    rigs_.pose(std::max(t, 0.0), scene);
  }
  double duration() const override { return 0.0; }

 private:
  ArenaSimulation simulation_;
  ProceduralRigPlayer rigs_;
};

// Skinned meshes built in code (builtin:skinned-grid).
class ProceduralRigAnimator final : public SceneAnimator {
 public:
  explicit ProceduralRigAnimator(ProceduralRigPlayer rigs) : rigs_(std::move(rigs)) {}
  bool animated() const override { return true; }
  void pose(double t, Scene& scene) override { rigs_.pose(std::max(t, 0.0), scene); }
  double duration() const override { return 0.0; }

 private:
  ProceduralRigPlayer rigs_;
};

class GltfNodeAnimator final : public SceneAnimator {
 public:
  explicit GltfNodeAnimator(GltfAnimations animations) : animations_(std::move(animations)) {}
  bool animated() const override { return true; }
  void pose(double t, Scene& scene) override {
    apply_gltf_animations(animations_, std::max(t, 0.0), scene);
  }
  double duration() const override { return animations_.duration(); }

 private:
  GltfAnimations animations_;
};

// The arena's moving bodies are the instances named "arena.body.<i>"; a
// scene holds the arena when all of them are there.
bool holds_arena_bodies(const Scene& scene) {
  const size_t bodies = arena_bodies().size();
  size_t found = 0;
  for (const Instance& inst : scene.instances()) {
    if (inst.name.rfind("arena.body.", 0) == 0) ++found;
  }
  return bodies > 0 && found >= bodies;
}

}  // namespace

std::unique_ptr<SceneAnimator> make_scene_animator(const Scene& scene, GltfAnimations animations) {
  if (holds_arena_bodies(scene)) return std::make_unique<ArenaAnimator>(scene);
  if (!animations.empty()) return std::make_unique<GltfNodeAnimator>(std::move(animations));
  ProceduralRigPlayer rigs(scene);
  if (!rigs.empty()) return std::make_unique<ProceduralRigAnimator>(std::move(rigs));
  return std::make_unique<StaticAnimator>();
}

SceneBounds animation_bounds(SceneAnimator& animator, Scene& scene) {
  const double duration = animator.duration();
  if (!animator.animated() || !(duration > 0.0)) return scene.bounds();
  constexpr int kPoses = 64;
  SceneBounds bounds;
  for (int i = 0; i < kPoses; ++i) {
    animator.pose(duration * double(i) / double(kPoses - 1), scene);
    bounds.extend(scene.bounds());
  }
  animator.pose(0.0, scene);
  return bounds;
}

}  // namespace tandem
