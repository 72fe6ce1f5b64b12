// Scene motion behind one interface: whatever makes a loaded scene move
// over time (the arena's simulation, a glTF file's node animations) poses
// it through a SceneAnimator, so the viewer, `bench --frames` and
// `tandem render --frames` play every kind of motion the same way, and none
// of them checks which scene it has.
#pragma once

#include <memory>

#include "core/world/scene.h"
#include "scenes/gltf_animation.h"

namespace tandem {

class SceneAnimator {
 public:
  virtual ~SceneAnimator() = default;
  // Whether pose() moves anything (false for static scenes).
  virtual bool animated() const = 0;
  // Poses the scene for time t (seconds, >= 0): writes the transforms of the
  // moving instances and the poses of the deforming meshes (marking only
  // those dirty; a posed mesh reaches the kernel arrays without a copy in
  // the Scene, core/world/mesh_pose.h). A pure function of t: the same t
  // gives the same scene whatever was posed before.
  virtual void pose(double t, Scene& scene) = 0;
  // Length of one loop of the motion in seconds; 0 when it has no end (a
  // simulation) or no motion at all.
  virtual double duration() const = 0;
};

// The animator for a loaded scene: the arena simulation when the scene holds
// the arena's bodies, the node animations when `animations` has any (glTF;
// see GltfOptions::animations), otherwise one that never moves anything.
// Never returns null.
std::unique_ptr<SceneAnimator> make_scene_animator(const Scene& scene,
                                                   GltfAnimations animations = {});

// The scene's bounds over one loop of its animation (64 evenly spaced
// poses), for an automatic camera that keeps a moving object in the
// picture; the bounds as they are when nothing moves or the motion has no
// fixed length. Leaves the scene posed at t = 0 when it poses it.
SceneBounds animation_bounds(SceneAnimator& animator, Scene& scene);

}  // namespace tandem
