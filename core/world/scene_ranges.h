// The numbers a scene may hold, so that every ray and instance that reaches
// a tracer is finite and inside the range it accepts. Embree (a release
// build asserts, aborting the process) and Tandem's own traversal accept ray
// coordinates up to about 1.8e18 in every instance's space; float radiance
// overflows to infinity, which renders black.
//
// Three kinds of trouble, three answers:
//   - an instance with a singular or nearly singular transform (a node
//     scaled to 0, the usual way an animation hides an object) is not drawn:
//     it is invisible, as in every engine, and the animation plays through
//     it;
//   - geometry whose world positions are not finite (a scale of 1e30, an
//     inverse bind matrix of 3e38: finite in the file, infinite after the
//     products) or beyond kMaxWorldCoordinate, a camera out of range, a
//     light or emission beyond kMaxRadiance: refused when a file is loaded
//     (check_scene_traceable, naming the file and the object), and for one
//     frame of an animation or an edit through the API not drawn, with a
//     named warning (the compiler, core/world/compile_instances.cpp);
//   - nothing else ever reaches a tracer: the compiler marks what is not
//     drawn (kInstanceHidden), and the scene's bounds leave it out.
#pragma once

#include <glm/glm.hpp>
#include <string>

#include "core/world/scene_bounds.h"

namespace tandem {

class Scene;
struct Camera;

// Every point a ray can start from (visible geometry, the camera) lies
// within this on every axis. Float positions there are already 64 units
// apart: no renderable scene comes near it.
constexpr float kMaxWorldCoordinate = 1e9f;
// An instance is drawn only while its inverse maps every point within
// kMaxWorldCoordinate inside this (the tracers' range with room to spare):
// scales below about 1e-9 are not drawn.
constexpr double kMaxInstanceCoordinate = 1e18;
// Radiance (emission times strength, light intensity times colour) beyond
// this is refused, as --env and --env-color are: paths multiply it by
// throughputs and weights, and float overflows near 3.4e38.
constexpr double kMaxRadiance = 1e30;

enum class InstanceState : uint8_t {
  kVisible,
  kSingular,    // singular or scaled below what the tracers can represent: not drawn
  kNonFinite,   // its transform or its mesh's positions are not finite
  kOutOfRange,  // its world box leaves kMaxWorldCoordinate
};

// What an instance placed by `transform` of a mesh whose object-space box
// is `mesh_box` (empty: no geometry, which is visible and draws nothing) is
// to the tracers.
InstanceState classify_instance(const glm::mat4& transform, const SceneBounds& mesh_box);
// "has a singular transform", ... for messages.
const char* instance_state_text(InstanceState state);

// Why `camera` cannot be traced (empty: it can): not finite, beyond
// kMaxWorldCoordinate, a view size beyond it, a degenerate frame.
std::string camera_problem(const Camera& camera);

// Throws InputError, naming scene.source and the object, for the first
// thing of `scene` a tracer could not take: an instance whose positions are
// not finite or leave kMaxWorldCoordinate, the camera, a light or a
// material's emission beyond kMaxRadiance or not finite. Singular instances
// are not an error (they are not drawn).
// `where` names the scene (its file) in the message.
void check_scene_traceable(const Scene& scene, const std::string& where);

}  // namespace tandem
