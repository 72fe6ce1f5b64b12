#include "scenes/arena_scene.h"

#include <algorithm>
#include <cmath>
#include <unordered_map>

#include <glm/gtc/matrix_transform.hpp>

#include "core/util/errors.h"
#include "scenes/builtin_scenes.h"
#include "scenes/procedural_rigs.h"

namespace tandem {

namespace {

constexpr float kWallThickness = 0.3f;
constexpr float kWallHeight = 1.2f;

// Vertical cylinders the bouncing balls collide with: four pillars and an
// invisible column around the spinning cube (so balls never pass through it).
struct Column {
  glm::vec2 center;
  float radius;
};
constexpr Column kColumns[] = {
    {{-3.6f, -3.6f}, 0.35f}, {{3.6f, -3.6f}, 0.35f}, {{-3.6f, 3.6f}, 0.35f},
    {{3.6f, 3.6f}, 0.35f},   {{0.0f, 0.0f}, 1.0f},
};
constexpr float kPillarHeight = 3.0f;
constexpr glm::vec3 kCubeCenter{0.0f, 1.5f, 0.0f};
constexpr float kCubeHalf = 0.5f;
constexpr float kPedestalHalf = 0.45f;

Material make_material(const std::string& name, glm::vec3 color, float metallic, float roughness) {
  Material m;
  m.name = name;
  m.base_color = glm::vec4(color, 1.0f);
  m.metallic = metallic;
  m.roughness = roughness;
  return m;
}

Material make_emitter(const std::string& name, glm::vec3 color, float strength) {
  Material m = make_material(name, glm::vec3(0.0f), 0.0f, 1.0f);
  m.specular = 0.0f;
  m.emissive = color;
  m.emissive_strength = strength;
  return m;
}

// Axis-aligned box [lo, hi] with outward-facing quads.
void append_box(Mesh& mesh, glm::vec3 lo, glm::vec3 hi, uint32_t material) {
  const glm::vec3 c = (lo + hi) * 0.5f;
  auto P = [&](int x, int y, int z) {
    return glm::vec3(x ? hi.x : lo.x, y ? hi.y : lo.y, z ? hi.z : lo.z);
  };
  const glm::vec3 faces[6][4] = {
      {P(1, 0, 0), P(1, 1, 0), P(1, 1, 1), P(1, 0, 1)},
      {P(0, 0, 0), P(0, 0, 1), P(0, 1, 1), P(0, 1, 0)},
      {P(0, 1, 0), P(0, 1, 1), P(1, 1, 1), P(1, 1, 0)},
      {P(0, 0, 0), P(1, 0, 0), P(1, 0, 1), P(0, 0, 1)},
      {P(0, 0, 1), P(1, 0, 1), P(1, 1, 1), P(0, 1, 1)},
      {P(0, 0, 0), P(0, 1, 0), P(1, 1, 0), P(1, 0, 0)},
  };
  for (const auto& f : faces) {
    const glm::vec3 mid = (f[0] + f[1] + f[2] + f[3]) * 0.25f;
    append_quad(mesh, f[0], f[1], f[2], f[3], material, mid - c);
  }
}

std::string body_name(size_t i) {
  return "arena.body." + std::to_string(i);
}

}  // namespace

const std::vector<ArenaBody>& arena_bodies() {
  static const std::vector<ArenaBody> bodies = [] {
    std::vector<ArenaBody> b;
    // Three emissive orbs on orbits of different radius, speed and sense.
    const float orbit_r[3] = {2.2f, 3.0f, 4.3f}, orbit_h[3] = {2.2f, 1.4f, 2.8f};
    const float orbit_w[3] = {0.9f, -0.6f, 0.45f}, orbit_phase[3] = {0.0f, 2.1f, 4.2f};
    for (int i = 0; i < 3; ++i) {
      ArenaBody o;
      o.motion = ArenaMotion::kOrbit;
      o.radius = 0.28f;
      o.orbit_radius = orbit_r[i];
      o.height = orbit_h[i];
      o.speed = orbit_w[i];
      o.phase = orbit_phase[i];
      o.bob = 0.3f;
      b.push_back(o);
    }
    // Four glossy balls bouncing around the courtyard.
    const glm::vec3 starts[4] = {
        {-2.0f, 2.5f, 1.8f}, {2.5f, 1.5f, -1.9f}, {-4.2f, 3.0f, -1.0f}, {1.8f, 2.0f, 4.0f}};
    const glm::vec3 velocities[4] = {
        {1.7f, 0.0f, 1.1f}, {-1.2f, 1.5f, 1.9f}, {0.9f, -0.5f, -2.1f}, {-2.2f, 0.8f, -0.7f}};
    const float radii[4] = {0.45f, 0.35f, 0.55f, 0.4f};
    for (int i = 0; i < 4; ++i) {
      ArenaBody ball;
      ball.motion = ArenaMotion::kBounce;
      ball.radius = radii[i];
      ball.start = starts[i];
      ball.velocity = velocities[i];
      b.push_back(ball);
    }
    ArenaBody cube;
    cube.motion = ArenaMotion::kSpin;
    cube.radius = kCubeHalf * std::sqrt(3.0f);
    cube.start = kCubeCenter;
    cube.speed = 0.7f;
    b.push_back(cube);
    return b;
  }();
  return bodies;
}

Scene make_arena_scene() {
  Scene scene;
  scene.source = "builtin:arena";
  const uint32_t floor_mat =
      scene.add_material(make_material("floor", {0.45f, 0.45f, 0.48f}, 0.0f, 0.3f));
  const uint32_t wall_mat =
      scene.add_material(make_material("wall", {0.75f, 0.62f, 0.48f}, 0.0f, 0.9f));
  const uint32_t pillar_mat =
      scene.add_material(make_material("pillar", {0.85f, 0.85f, 0.82f}, 0.0f, 0.6f));
  const uint32_t orb_mat[3] = {
      scene.add_material(make_emitter("orb.orange", {1.0f, 0.55f, 0.2f}, 12.0f)),
      scene.add_material(make_emitter("orb.cyan", {0.2f, 0.8f, 1.0f}, 12.0f)),
      scene.add_material(make_emitter("orb.magenta", {1.0f, 0.25f, 0.8f}, 12.0f)),
  };
  const uint32_t ball_mat[4] = {
      scene.add_material(make_material("ball.gold", {1.0f, 0.78f, 0.34f}, 1.0f, 0.15f)),
      scene.add_material(make_material("ball.red", {0.8f, 0.08f, 0.06f}, 0.0f, 0.05f)),
      scene.add_material(make_material("ball.chrome", {0.95f, 0.95f, 0.95f}, 1.0f, 0.03f)),
      scene.add_material(make_material("ball.green", {0.1f, 0.6f, 0.2f}, 0.0f, 0.25f)),
  };
  const uint32_t cube_mat =
      scene.add_material(make_material("cube.mirror", {0.9f, 0.9f, 0.95f}, 1.0f, 0.02f));

  // Static courtyard: floor, four low walls, pillars, the cube's pedestal.
  Mesh yard;
  yard.name = "arena.courtyard";
  const float h = kArenaHalfSize, t = kWallThickness;
  append_quad(yard, {-h - t, 0, -h - t}, {h + t, 0, -h - t}, {h + t, 0, h + t}, {-h - t, 0, h + t},
              floor_mat, {0, 1, 0});
  append_box(yard, {-h - t, 0, -h - t}, {h + t, kWallHeight, -h}, wall_mat);
  append_box(yard, {-h - t, 0, h}, {h + t, kWallHeight, h + t}, wall_mat);
  append_box(yard, {-h - t, 0, -h}, {-h, kWallHeight, h}, wall_mat);
  append_box(yard, {h, 0, -h}, {h + t, kWallHeight, h}, wall_mat);
  for (size_t i = 0; i < 4; ++i) {
    const Column& c = kColumns[i];
    const float r = c.radius * 0.85f;  // square pillar inscribed in its collision column
    append_box(yard, {c.center.x - r, 0, c.center.y - r},
               {c.center.x + r, kPillarHeight, c.center.y + r}, pillar_mat);
  }
  const float ph = kCubeCenter.y - kCubeHalf * std::sqrt(3.0f) - 0.05f;
  append_box(yard, {-kPedestalHalf, 0, -kPedestalHalf}, {kPedestalHalf, ph, kPedestalHalf},
             pillar_mat);
  scene.add_instance({"arena.courtyard", scene.add_mesh(std::move(yard)), glm::mat4(1.0f)});

  // Moving bodies: unit meshes scaled by their instance transforms.
  const std::vector<ArenaBody>& bodies = arena_bodies();
  int orb = 0, ball = 0;
  for (size_t i = 0; i < bodies.size(); ++i) {
    Mesh mesh;
    if (bodies[i].motion == ArenaMotion::kSpin) {
      mesh.name = "arena.cube";
      append_box(mesh, glm::vec3(-1.0f), glm::vec3(1.0f), cube_mat);
    } else {
      const uint32_t mat =
          bodies[i].motion == ArenaMotion::kOrbit ? orb_mat[orb++ % 3] : ball_mat[ball++ % 4];
      mesh = make_uv_sphere(1.0f, 12, 24, mat, false);
      mesh.name = "arena.sphere." + std::to_string(i);
    }
    scene.add_instance({body_name(i), scene.add_mesh(std::move(mesh)), glm::mat4(1.0f)});
  }

  // Figures walking round the pedestal, each its own skinned mesh (posed
  // into world space by its joints, so the instance stays at identity).
  const uint32_t walker_mat =
      scene.add_material(make_material("walker", {0.2f, 0.35f, 0.75f}, 0.0f, 0.45f));
  const std::vector<WalkerPath>& walkers = arena_walker_paths();
  for (size_t i = 0; i < walkers.size(); ++i) {
    ProceduralRig rig = make_walker_rig(walker_mat);
    rig.mesh.name = "rig.walker." + std::to_string(i);
    JointMatrix palette[kWalkerJoints];
    walker_palette(0.0, walkers[i], palette);
    deform_mesh(rig.deformation, palette, nullptr, rig.mesh);
    const uint32_t mesh = scene.add_mesh(std::move(rig.mesh));
    scene.set_mesh_deforms(mesh);
    scene.add_instance({"arena.walker." + std::to_string(i), mesh, glm::mat4(1.0f)});
  }

  // A low sun and a pale sky; the orbs add moving coloured light.
  Light sun;
  sun.name = "sun";
  sun.type = LightType::kDirectional;
  sun.color = {1.0f, 0.93f, 0.8f};
  sun.intensity = 2.5f;
  sun.direction = glm::normalize(glm::vec3(-0.45f, -0.8f, -0.35f));
  scene.add_light(sun);
  Environment env;
  env.color = {0.35f, 0.45f, 0.6f};
  scene.set_environment(env);

  Camera cam;
  cam.position = {0.0f, 4.2f, 9.0f};
  cam.forward = glm::normalize(glm::vec3(0.0f, 0.8f, 0.0f) - cam.position);
  cam.up = glm::normalize(glm::cross(glm::cross(cam.forward, glm::vec3(0, 1, 0)), cam.forward));
  cam.yfov = 0.9f;
  cam.aspect_ratio = 16.0f / 9.0f;
  cam.focus_distance = glm::length(cam.position - glm::vec3(0.0f, 0.8f, 0.0f));
  scene.set_camera(cam);

  ArenaSimulation sim(scene);
  sim.advance_to(0.0, scene);
  return scene;
}

ArenaSimulation::ArenaSimulation(const Scene& scene) : bodies_(arena_bodies()) {
  std::unordered_map<std::string, uint32_t> by_name;
  for (size_t i = 0; i < scene.instances().size(); ++i)
    by_name.emplace(scene.instances()[i].name, uint32_t(i));
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const auto it = by_name.find(body_name(i));
    if (it == by_name.end()) {
      throw InputError(scene.source + ": not an arena scene (no instance " + body_name(i) + ")");
    }
    instances_.push_back(it->second);
  }
  reset_bounce_state();
}

void ArenaSimulation::reset_bounce_state() {
  state_.clear();
  for (const ArenaBody& b : bodies_)
    state_.push_back({b.start, b.velocity});
  previous_ = state_;
  step_ = 0;
}

// One fixed step of semi-implicit Euler for the bouncing balls. Floor
// contacts restore the ball's initial bounce speed, so the motion is
// periodic-ish and never gains or loses energy over a long session.
void ArenaSimulation::step_once() {
  const float dt = float(1.0 / kStepHz);
  previous_ = state_;
  for (size_t i = 0; i < bodies_.size(); ++i) {
    const ArenaBody& b = bodies_[i];
    if (b.motion != ArenaMotion::kBounce) continue;
    BounceState& s = state_[i];
    s.velocity.y -= kGravity * dt;
    s.position += s.velocity * dt;
    const float r = b.radius;
    if (s.position.y < r) {
      s.position.y = 2.0f * r - s.position.y;
      s.velocity.y =
          std::sqrt(b.velocity.y * b.velocity.y + 2.0f * kGravity * std::max(0.0f, b.start.y - r));
    }
    const float limit = kArenaHalfSize - r;
    for (int axis : {0, 2}) {
      if (s.position[axis] > limit) {
        s.position[axis] = 2.0f * limit - s.position[axis];
        s.velocity[axis] = -std::abs(s.velocity[axis]);
      } else if (s.position[axis] < -limit) {
        s.position[axis] = -2.0f * limit - s.position[axis];
        s.velocity[axis] = std::abs(s.velocity[axis]);
      }
    }
    for (const Column& c : kColumns) {
      glm::vec2 d(s.position.x - c.center.x, s.position.z - c.center.y);
      const float dist = glm::length(d), reach = c.radius + r;
      if (dist >= reach || dist < 1e-6f) continue;
      const glm::vec2 n = d / dist;
      const glm::vec2 p = c.center + n * reach;
      s.position.x = p.x;
      s.position.z = p.y;
      glm::vec2 v(s.velocity.x, s.velocity.z);
      const float vn = glm::dot(v, n);
      if (vn < 0.0f) v -= 2.0f * vn * n;
      s.velocity.x = v.x;
      s.velocity.z = v.y;
    }
  }
  ++step_;
}

glm::mat4 ArenaSimulation::pose(size_t i, double t) const {
  const ArenaBody& b = bodies_[i];
  switch (b.motion) {
    case ArenaMotion::kOrbit: {
      const double a = double(b.phase) + double(b.speed) * t;
      const glm::vec3 p(float(b.orbit_radius * std::cos(a)),
                        float(b.height + b.bob * std::sin(2.0 * a)),
                        float(b.orbit_radius * std::sin(a)));
      return glm::scale(glm::translate(glm::mat4(1.0f), p), glm::vec3(b.radius));
    }
    case ArenaMotion::kBounce: {
      // Between fixed steps the pose is interpolated, so rendering at any
      // frame rate shows smooth motion of the same deterministic path.
      const double x = t * kStepHz;
      const float alpha = float(x - std::floor(x));
      const glm::vec3 p = glm::mix(previous_[i].position, state_[i].position, alpha);
      return glm::scale(glm::translate(glm::mat4(1.0f), p), glm::vec3(b.radius));
    }
    case ArenaMotion::kSpin: {
      const float a = float(std::fmod(double(b.speed) * t, 2.0 * M_PI));
      glm::mat4 m = glm::translate(glm::mat4(1.0f), b.start);
      m = glm::rotate(m, a, glm::vec3(0.0f, 1.0f, 0.0f));
      m = glm::rotate(m, 0.6154797f, glm::normalize(glm::vec3(1.0f, 0.0f, 1.0f)));  // on a corner
      return glm::scale(m, glm::vec3(kCubeHalf));
    }
  }
  return glm::mat4(1.0f);
}

void ArenaSimulation::advance_to(double t, Scene& scene) {
  if (!(t >= 0.0)) t = 0.0;
  // State at step n and n + 1 brackets t; interpolation uses both.
  const uint64_t n = uint64_t(std::floor(t * kStepHz));
  if (step_ > n + 1) reset_bounce_state();
  while (step_ < n + 1)
    step_once();
  time_ = t;
  for (size_t i = 0; i < bodies_.size(); ++i)
    scene.set_instance_transform(instances_[i], pose(i, t));
}

glm::mat4 ArenaSimulation::body_transform(size_t i) const {
  return pose(i, time_);
}

}  // namespace tandem
