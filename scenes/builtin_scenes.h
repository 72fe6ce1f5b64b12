// Scenes built in code: reference scenes with known answers for tests and
// the classic Cornell box for comparisons with other renderers.
#pragma once

#include <string>
#include <vector>

#include "core/world/scene.h"

namespace tandem {

std::vector<std::string> builtin_scene_names();

// Throws InputError for an unknown name.
Scene make_builtin_scene(const std::string& name);

// The Cornell box from the published measurements
// (https://www.graphics.cornell.edu/online/box/data.html), in metres,
// camera as measured (position (278, 273, -800) mm, 35 mm lens on a 25 mm
// film: 39.3077 degree field of view).
Scene make_cornell_box();
// The box without its blocks, with a mirror and a glass sphere on the floor
// (flat-shaded, kCornellSphereRings rings): the Cycles comparison's second
// scene, for specular reflection, refraction and caustics.
constexpr uint32_t kCornellSphereRings = 24;
Scene make_cornell_spheres();

// Camera inside a closed sphere whose inner surface is Lambertian with
// albedo `albedo` and emits `emission` on both sides: every pixel sees
// radiance emission / (1 - albedo) (with unlimited depth).
Scene make_furnace_scene(float albedo, float emission);

// A large Lambertian plane (albedo `albedo`) under a uniform sky of radiance
// `sky`, seen from above: the plane's radiance is albedo * sky.
Scene make_sky_plane_scene(float albedo, float sky);

// Mesh helpers shared by the procedural scenes.
void append_quad(Mesh& mesh, const glm::vec3& a, const glm::vec3& b, const glm::vec3& c,
                 const glm::vec3& d, uint32_t material, const glm::vec3& facing);
Mesh make_uv_sphere(float radius, uint32_t rings, uint32_t segments, uint32_t material,
                    bool inward_normals);

}  // namespace tandem
