// builtin:arena, a game-style dynamic scene: a walled courtyard with pillars,
// emissive orbs orbiting the centre, glossy balls bouncing off the floor and
// walls, and a spinning mirror cube. Every frame every moving body gets a new
// instance transform, so the TLAS changes and deltas are committed every
// frame, as in a game.
//
// The motion is a pure function of time: ArenaSimulation integrates the
// bouncing bodies with a fixed timestep from t = 0 (so the same t gives the
// same transforms bit for bit, whatever the frame rate or the order of
// queries), and the orbiting/spinning bodies are closed-form. Both
// tandem-view and `tandem bench` drive the scene through it.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "core/world/scene.h"

namespace tandem {

// The arena at t = 0 (instances of moving bodies already posed).
Scene make_arena_scene();

enum class ArenaMotion : uint8_t { kOrbit, kBounce, kSpin };

// One moving body. Instances of the arena are named "arena.body.<i>" for
// body i, so a simulation can find them in any copy of the scene.
struct ArenaBody {
  ArenaMotion motion = ArenaMotion::kOrbit;
  float radius = 0.3f;  // bounding radius (sphere radius, cube half-diagonal)
  // kOrbit: circle of `orbit_radius` at `height` around the centre with
  // angular speed `speed` (rad/s) starting at `phase`, bobbing by `bob`.
  // kBounce: initial position `start` and velocity `velocity`.
  // kSpin: fixed position `start`, spinning about y at `speed` rad/s.
  float orbit_radius = 0.0f, height = 0.0f, speed = 0.0f, phase = 0.0f, bob = 0.0f;
  glm::vec3 start{0.0f}, velocity{0.0f};
};

// The arena's bodies, in instance order (body i is "arena.body.<i>").
const std::vector<ArenaBody>& arena_bodies();

// Half extent of the courtyard floor in x and z (walls stand there).
inline constexpr float kArenaHalfSize = 6.0f;

class ArenaSimulation {
 public:
  static constexpr double kStepHz = 120.0;
  static constexpr float kGravity = 9.81f;

  // Finds the bodies' instances in `scene`; throws InputError when the scene
  // is not an arena (some "arena.body.<i>" instance missing).
  explicit ArenaSimulation(const Scene& scene);

  // Poses every body for time t (seconds, >= 0) and writes the instance
  // transforms into `scene` (marking only those instances dirty). Going back
  // in time replays from t = 0, so results never depend on call history.
  void advance_to(double t, Scene& scene);

  // The world transform of body i at the time of the last advance_to().
  glm::mat4 body_transform(size_t i) const;
  size_t body_count() const { return bodies_.size(); }
  uint64_t steps_taken() const { return step_; }

 private:
  struct BounceState {
    glm::vec3 position, velocity;
  };
  void reset_bounce_state();
  void step_once();
  glm::mat4 pose(size_t i, double t) const;

  std::vector<ArenaBody> bodies_;
  std::vector<uint32_t> instances_;
  std::vector<BounceState> state_, previous_;  // at step_ and step_ - 1
  uint64_t step_ = 0;
  double time_ = 0.0;
};

}  // namespace tandem
