#include "scenes/gltf_animation.h"

#include <algorithm>
#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "scenes/gltf_internal.h"

namespace tandem {

double GltfAnimations::duration() const {
  double d = 0.0;
  for (const GltfAnimation& a : animations)
    d = std::max(d, a.duration);
  return d;
}

void sample_gltf_channel(const GltfAnimationChannel& ch, double t, float* out) {
  const uint32_t n = ch.components();
  const size_t keys = ch.times.size();
  const bool cubic = ch.interpolation == GltfInterpolation::kCubicSpline;
  const size_t stride = cubic ? 3 * n : n;
  const size_t value_offset = cubic ? n : 0;  // skip the in-tangent
  auto value = [&](size_t k) { return &ch.values[k * stride + value_offset]; };
  if (keys == 0) return;

  // Key k with times[k] <= t < times[k + 1]; clamp outside the range.
  size_t k = 0;
  float s = 0.0f;
  if (t <= ch.times.front()) {
    k = 0;
  } else if (t >= ch.times.back()) {
    k = keys - 1;
  } else {
    k = size_t(std::upper_bound(ch.times.begin(), ch.times.end(), float(t)) - ch.times.begin()) - 1;
    const double dt = double(ch.times[k + 1]) - ch.times[k];
    s = dt > 0.0 ? float((t - ch.times[k]) / dt) : 0.0f;
  }
  const bool at_key = k + 1 >= keys || ch.interpolation == GltfInterpolation::kStep;
  if (at_key) {
    std::copy(value(k), value(k) + n, out);
  } else if (ch.interpolation == GltfInterpolation::kLinear) {
    const float *a = value(k), *b = value(k + 1);
    if (ch.path == GltfAnimatedPath::kRotation) {
      const glm::quat qa(a[3], a[0], a[1], a[2]), qb(b[3], b[0], b[1], b[2]);
      const glm::quat q = glm::slerp(qa, qb, s);  // takes the short way round
      out[0] = q.x, out[1] = q.y, out[2] = q.z, out[3] = q.w;
    } else {
      for (uint32_t c = 0; c < n; ++c)
        out[c] = a[c] + (b[c] - a[c]) * s;
    }
  } else {
    // Cubic Hermite spline (glTF spec appendix C): tangents are per second,
    // so they are scaled by the key interval.
    const float dt = ch.times[k + 1] - ch.times[k];
    const float *v0 = value(k), *b0 = v0 + n, *v1 = value(k + 1), *a1 = v1 - n;
    const float s2 = s * s, s3 = s2 * s;
    const float h00 = 2 * s3 - 3 * s2 + 1, h10 = s3 - 2 * s2 + s, h01 = -2 * s3 + 3 * s2,
                h11 = s3 - s2;
    for (uint32_t c = 0; c < n; ++c)
      out[c] = h00 * v0[c] + h10 * dt * b0[c] + h01 * v1[c] + h11 * dt * a1[c];
  }
  if (ch.path == GltfAnimatedPath::kRotation) {
    const float len =
        std::sqrt(out[0] * out[0] + out[1] * out[1] + out[2] * out[2] + out[3] * out[3]);
    if (len > 1e-12f) {
      for (int c = 0; c < 4; ++c)
        out[c] /= len;
    } else {
      out[0] = out[1] = out[2] = 0.0f, out[3] = 1.0f;
    }
  }
}

std::vector<GltfAnimNode> pose_gltf_local(const GltfAnimations& anims, double t) {
  std::vector<GltfAnimNode> local = anims.nodes;
  std::vector<float> v;
  for (const GltfAnimation& a : anims.animations) {
    const double lt = a.duration > 0.0 ? std::fmod(std::max(t, 0.0), a.duration) : 0.0;
    for (const GltfAnimationChannel& ch : a.channels) {
      GltfAnimNode& node = local[ch.node];
      v.resize(std::max<size_t>(4, ch.components()));
      sample_gltf_channel(ch, lt, v.data());
      switch (ch.path) {
        case GltfAnimatedPath::kTranslation:
          node.translation = {v[0], v[1], v[2]};
          break;
        case GltfAnimatedPath::kRotation:
          node.rotation = glm::quat(v[3], v[0], v[1], v[2]);
          break;
        case GltfAnimatedPath::kScale:
          node.scale = {v[0], v[1], v[2]};
          break;
        case GltfAnimatedPath::kWeights:
          // The loader only keeps channels whose count matches the mesh.
          if (node.weights.size() == ch.weight_count)
            std::copy(v.begin(), v.begin() + ch.weight_count, node.weights.begin());
          break;
      }
    }
  }
  return local;
}

std::vector<glm::mat4> gltf_world_transforms(const GltfAnimations& anims,
                                             const std::vector<GltfAnimNode>& local) {
  std::vector<glm::mat4> world(local.size(), glm::mat4(1.0f));
  for (uint32_t i : anims.order) {
    const GltfAnimNode& node = local[i];
    glm::mat4 m = node.matrix;
    if (!node.has_matrix) {
      m = glm::translate(glm::mat4(1.0f), node.translation) * glm::mat4_cast(node.rotation);
      m = glm::scale(m, node.scale);
    }
    world[i] = node.parent >= 0 ? world[size_t(node.parent)] * m : m;
  }
  return world;
}

std::vector<glm::mat4> pose_gltf_nodes(const GltfAnimations& anims, double t) {
  return gltf_world_transforms(anims, pose_gltf_local(anims, t));
}

size_t deform_gltf_meshes(const GltfAnimations& anims, const std::vector<GltfAnimNode>& local,
                          const std::vector<glm::mat4>& world, Scene& scene) {
  std::vector<JointMatrix> palette;
  size_t written = 0;
  for (const GltfDeformedMesh& dm : anims.deformed) {
    const MeshDeformation& d = *dm.deformation;
    palette.clear();
    if (dm.skin >= 0) {
      // The palette once per mesh and frame; per vertex only blends of it.
      const GltfSkin& skin = anims.skins[size_t(dm.skin)];
      for (size_t j = 0; j < skin.joints.size(); ++j)
        palette.push_back(joint_matrix(world[skin.joints[j]] * skin.inverse_bind[j]));
      palette.push_back(joint_matrix(world[dm.node]));  // the all-zero-weights slot
    }
    const std::vector<float>& weights = local[dm.node].weights;
    if (deform_scene_mesh(
            dm.deformation, palette.empty() ? nullptr : palette.data(),
            weights.size() == d.targets && !weights.empty() ? weights.data() : nullptr, scene,
            dm.last)) {
      ++written;
    }
  }
  return written;
}

size_t apply_gltf_animations(const GltfAnimations& anims, double t, Scene& scene) {
  if (anims.empty()) return 0;
  const std::vector<GltfAnimNode> local = pose_gltf_local(anims, t);
  const std::vector<glm::mat4> world = gltf_world_transforms(anims, local);
  size_t updated = 0;
  for (const GltfInstanceBinding& b : anims.instances) {
    if (b.skinned || !anims.nodes[b.node].animated || b.instance >= scene.instances().size())
      continue;
    const glm::mat4 m = world[b.node] * b.local;
    if (m == scene.instances()[b.instance].transform) continue;  // unchanged: no delta
    scene.set_instance_transform(b.instance, m);
    ++updated;
  }
  deform_gltf_meshes(anims, local, world, scene);
  return updated;
}

namespace gltf {

std::vector<float> gltf_default_weights(const tinygltf::Model& m, const tinygltf::Node& n) {
  if (n.mesh < 0) return {};
  const tinygltf::Mesh& mesh = m.meshes[size_t(n.mesh)];
  // The validator has checked that every primitive has this many targets
  // and that node.weights and mesh.weights, when present, match it.
  const size_t targets = mesh.primitives.front().targets.size();
  const std::vector<double>& given = !n.weights.empty() ? n.weights : mesh.weights;
  std::vector<float> w(targets, 0.0f);
  for (size_t k = 0; k < targets && k < given.size(); ++k)
    w[k] = float(given[k]);
  return w;
}

namespace {

GltfAnimNode rest_pose(const tinygltf::Model& m, const tinygltf::Node& n) {
  GltfAnimNode r;
  r.weights = gltf_default_weights(m, n);
  if (n.matrix.size() == 16) {
    r.has_matrix = true;
    for (int i = 0; i < 16; ++i)
      glm::value_ptr(r.matrix)[i] = float(n.matrix[size_t(i)]);
    return r;
  }
  if (n.translation.size() == 3)
    r.translation = {float(n.translation[0]), float(n.translation[1]), float(n.translation[2])};
  if (n.rotation.size() == 4) {
    r.rotation = glm::normalize(glm::quat(float(n.rotation[3]), float(n.rotation[0]),
                                          float(n.rotation[1]), float(n.rotation[2])));
  }
  if (n.scale.size() == 3) r.scale = {float(n.scale[0]), float(n.scale[1]), float(n.scale[2])};
  return r;
}

// Converts one channel; returns false (after warning) when it is unusable.
bool convert_channel(Context& ctx, AccessorCache& cache, const tinygltf::Animation& anim,
                     const tinygltf::AnimationChannel& gc, const std::string& who,
                     GltfAnimationChannel& out) {
  const tinygltf::Model& m = ctx.model;
  if (gc.target_node < 0 || size_t(gc.target_node) >= m.nodes.size()) {
    ctx.warn(who + " targets no valid node; it is ignored");
    return false;
  }
  uint32_t want_components = 3;
  if (gc.target_path == "weights") {
    out.path = GltfAnimatedPath::kWeights;
    const tinygltf::Node& node = m.nodes[size_t(gc.target_node)];
    const size_t targets =
        node.mesh >= 0 ? m.meshes[size_t(node.mesh)].primitives.front().targets.size() : 0;
    if (targets == 0) {
      ctx.warn(who + " animates the morph weights of a node without morph targets; it is ignored");
      return false;
    }
    out.weight_count = uint32_t(targets);
    want_components = uint32_t(targets);
  } else if (gc.target_path == "translation") {
    out.path = GltfAnimatedPath::kTranslation;
  } else if (gc.target_path == "rotation") {
    out.path = GltfAnimatedPath::kRotation;
    want_components = 4;
  } else if (gc.target_path == "scale") {
    out.path = GltfAnimatedPath::kScale;
  } else {
    ctx.warn(who + " has unknown target path '" + gc.target_path + "'; it is ignored");
    return false;
  }
  if (gc.sampler < 0 || size_t(gc.sampler) >= anim.samplers.size()) {
    ctx.warn(who + " refers to a missing sampler; it is ignored");
    return false;
  }
  const tinygltf::AnimationSampler& s = anim.samplers[size_t(gc.sampler)];
  if (s.interpolation.empty() || s.interpolation == "LINEAR") {
    out.interpolation = GltfInterpolation::kLinear;
  } else if (s.interpolation == "STEP") {
    out.interpolation = GltfInterpolation::kStep;
  } else if (s.interpolation == "CUBICSPLINE") {
    out.interpolation = GltfInterpolation::kCubicSpline;
  } else {
    ctx.warn(who + " has unknown interpolation '" + s.interpolation + "'; it is ignored");
    return false;
  }
  const auto valid_accessor = [&](int a) { return a >= 0 && size_t(a) < m.accessors.size(); };
  if (!valid_accessor(s.input) || !valid_accessor(s.output)) {
    ctx.warn(who + " has a sampler without valid input/output accessors; it is ignored");
    return false;
  }
  const tinygltf::Accessor& in = m.accessors[size_t(s.input)];
  const tinygltf::Accessor& outa = m.accessors[size_t(s.output)];
  const bool weights = out.path == GltfAnimatedPath::kWeights;
  const int want_type = weights                                   ? TINYGLTF_TYPE_SCALAR
                        : out.path == GltfAnimatedPath::kRotation ? TINYGLTF_TYPE_VEC4
                                                                  : TINYGLTF_TYPE_VEC3;
  if (in.type != TINYGLTF_TYPE_SCALAR || in.componentType != TINYGLTF_COMPONENT_TYPE_FLOAT ||
      outa.type != want_type) {
    ctx.warn(who + " has accessors of the wrong type; it is ignored");
    return false;
  }
  // A weights output holds one scalar per morph target per key.
  const size_t per_key = (out.interpolation == GltfInterpolation::kCubicSpline ? 3 : 1) *
                         (weights ? want_components : 1);
  if (in.count == 0 || outa.count / per_key != in.count || outa.count % per_key != 0) {
    ctx.warn(who + " has " + std::to_string(outa.count) + " output values for " +
             std::to_string(in.count) + " key times; it is ignored");
    return false;
  }
  out.node = uint32_t(gc.target_node);
  out.times = cache.floats(s.input, who + " input");
  out.values = cache.floats(s.output, who + " output");
  for (size_t i = 0; i < out.times.size(); ++i) {
    if (out.times[i] < 0.0f || (i > 0 && out.times[i] < out.times[i - 1])) {
      ctx.warn(who + " has key times that are negative or not increasing; it is ignored");
      return false;
    }
  }
  return true;
}

}  // namespace

void load_animations(Context& ctx, AccessorCache& cache, const std::vector<WalkedNode>& walked,
                     std::vector<GltfInstanceBinding> bindings, GltfAnimations& out,
                     bool channels) {
  const tinygltf::Model& m = ctx.model;
  out = GltfAnimations{};
  out.nodes.resize(m.nodes.size());
  for (const WalkedNode& w : walked) {
    GltfAnimNode& n = out.nodes[size_t(w.node)];
    n = rest_pose(m, m.nodes[size_t(w.node)]);
    n.parent = w.parent;
    n.visited = true;
    out.order.push_back(uint32_t(w.node));
  }
  out.instances = std::move(bindings);
  std::vector<bool> targeted(m.nodes.size(), false);
  for (size_t ai = 0; channels && ai < m.animations.size(); ++ai) {
    const tinygltf::Animation& ga = m.animations[ai];
    GltfAnimation a;
    a.name = ga.name.empty() ? "animation " + std::to_string(ai) : ga.name;
    for (size_t ci = 0; ci < ga.channels.size(); ++ci) {
      const std::string who = "animation " + std::to_string(ai) + " channel " + std::to_string(ci);
      GltfAnimationChannel ch;
      if (!convert_channel(ctx, cache, ga, ga.channels[ci], who, ch)) continue;
      const bool weights = ch.path == GltfAnimatedPath::kWeights;
      if (out.nodes[ch.node].has_matrix && !weights) {
        ctx.warn(who + " animates a node with a matrix, which glTF forbids; it is ignored");
        continue;
      }
      if (!out.nodes[ch.node].visited) continue;  // node not in the loaded scene
      if (!weights) targeted[ch.node] = true;     // weights move vertices, not the node
      a.duration = std::max(a.duration, double(ch.times.back()));
      a.channels.push_back(std::move(ch));
    }
    if (!a.channels.empty()) out.animations.push_back(std::move(a));
  }
  // Parents come first in `order`, so one pass propagates "animated".
  for (uint32_t i : out.order) {
    GltfAnimNode& n = out.nodes[i];
    n.animated = targeted[i] || (n.parent >= 0 && out.nodes[size_t(n.parent)].animated);
  }
}

}  // namespace gltf

}  // namespace tandem
