// SceneCompiler::compile as SceneSync runs it, for the tests of the compiler
// itself: the compiler only reads the Scene, and whoever takes its changes
// clears the dirty flags.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include "core/kernel/lights.h"
#include "core/world/kernel_scene.h"

namespace tandem {

inline SceneDelta compile_taking_changes(SceneCompiler& compiler, Scene& scene,
                                         const RenderSettings& settings, KernelScene& out) {
  SceneDelta delta = compiler.compile(scene, settings, out);
  scene.clear_dirty();
  return delta;
}

// A scene's compiler and the arrays it keeps up to date, compiled as above.
struct Compiled {
  SceneCompiler compiler;
  KernelScene ks;
  RenderSettings settings;
  SceneDelta compile(Scene& s) { return compile_taking_changes(compiler, s, settings, ks); }
};

template <class T>
bool same_bytes(const std::vector<T>& a, const std::vector<T>& b) {
  // memcmp must not see the null data() of an empty vector.
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(T)) == 0);
}

// Where a light of a light tree is and which ways it emits, in the tree's
// space: its points (a triangle's corners), the normals of its emitting
// sides (two-sided: both), or a spot's cone.
struct LightTreeCheckLight {
  std::vector<Vec3> points, normals;
  bool two_sided = false, every_way = false;
  Vec3 spot_axis{0.0f, 0.0f, 0.0f};
  float spot_cos = 1.0f;
};

// Checks the subtree at `node` against its lights (light(i)); returns them.
template <class LightOf>
std::vector<uint32_t> check_light_subtree(const std::vector<KLightTreeNode>& nodes, uint32_t node,
                                          const LightOf& light, int step) {
  const KLightTreeNode& n = nodes[node];
  std::vector<uint32_t> below;
  if (!(n.flags & kLightTreeLeaf)) {
    below = check_light_subtree(nodes, node + 1, light, step);
    const std::vector<uint32_t> second = check_light_subtree(nodes, n.index, light, step);
    below.insert(below.end(), second.begin(), second.end());
    const float sum = nodes[node + 1].power + nodes[n.index].power;
    EXPECT_NEAR(n.power, sum, 1e-4f * sum) << "node " << node << " after edit " << step;
  } else if (n.count <= 1) {
    below.push_back(n.index);
  } else {
    float shares = 0.0f;
    for (uint32_t k = 1; k <= n.count; ++k) {
      below.push_back(nodes[node + k].index);
      shares += nodes[node + k].power;
    }
    EXPECT_NEAR(shares, 1.0f, 1e-5f) << "leaf " << node << " after edit " << step;
  }
  const float theta_o = std::acos(std::clamp(n.cos_theta_o, -1.0f, 1.0f));
  for (uint32_t i : below) {
    const LightTreeCheckLight l = light(i);
    for (const Vec3& p : l.points) {
      EXPECT_LE(length(p - n.center), n.radius * (1.0f + 1e-4f) + 1e-5f)
          << "node " << node << ", light " << i << " after edit " << step;
    }
    if (n.cos_theta_o <= -1.0f + 1e-6f) continue;
    EXPECT_FALSE(l.every_way) << "node " << node << ", light " << i << " after edit " << step;
    for (const Vec3& d : l.normals) {
      const float c = dot(d, n.axis);
      EXPECT_GE((n.flags & kLightTreeTwoSided) ? std::fabs(c) : c, n.cos_theta_o - 1e-4f)
          << "node " << node << ", light " << i << " after edit " << step;
    }
    if (l.spot_cos < 1.0f) {
      EXPECT_LE(
          std::acos(std::clamp(dot(l.spot_axis, n.axis), -1.0f, 1.0f)) + std::acos(l.spot_cos),
          theta_o + 1e-3f)
          << "node " << node << ", spot " << i << " after edit " << step;
    }
  }
  return below;
}

// Every light tree of `ks` bounds its lights (what a refit must keep, and
// a build must give): each node's sphere holds every point of each light
// below it, its cone each one's emitting side, its power the sum of its
// children's; a leaf's entries share it out. A tree refit in place keeps
// the shape its build gave, so only these, not its bytes, are a fresh
// compile's.
inline void expect_light_trees_bound_their_lights(const KernelScene& ks, int step) {
  const KernelData kd = ks.view();
  const auto triangle = [&](const KTriangleLight& t, const KInstance* inst) {
    LightTreeCheckLight l;
    l.two_sided = (kd.materials[t.material].flags & kMaterialDoubleSided) != 0;
    if (!inst) {
      l.points = {t.p0, t.p1, t.p2};
      l.normals = {t.normal};
    } else {
      const SurfacePoint sp =
          make_light_point(kd, uint32_t(inst - kd.instances), t.prim, 0.0f, 0.0f);
      l.points = {instance_point(*inst, t.p0), instance_point(*inst, t.p1),
                  instance_point(*inst, t.p2)};
      l.normals = {sp.front_normal};
    }
    return l;
  };
  for (uint32_t m = 0; m < ks.mesh_lights.size(); ++m) {
    const KMeshLights& ml = ks.mesh_lights[m];
    if (ml.count == 0 || ml.tree_root == kInvalidIndex) continue;
    const std::vector<uint32_t> lights = check_light_subtree(
        ks.light_tree_nodes, ml.tree_root,
        [&](uint32_t i) { return triangle(ks.triangle_lights[i], nullptr); }, step);
    EXPECT_EQ(lights.size(), ml.count) << "mesh " << m << " after edit " << step;
  }
  if (ks.constants.light_tree_root == kInvalidIndex) return;
  check_light_subtree(
      ks.light_tree_nodes, ks.constants.light_tree_root,
      [&](uint32_t i) {
        const KLight& k = ks.lights[i];
        LightTreeCheckLight l;
        if (k.type == kLightMeshInstance) {
          const KInstance& inst = ks.instances[k.instance];
          const KMeshLights& ml = ks.mesh_lights[inst.mesh];
          for (uint32_t t = ml.first; t < ml.first + ml.count; ++t) {
            const LightTreeCheckLight one = triangle(ks.triangle_lights[t], &inst);
            l.points.insert(l.points.end(), one.points.begin(), one.points.end());
            l.normals.insert(l.normals.end(), one.normals.begin(), one.normals.end());
          }
          return l;
        }
        l.points = {k.position};
        l.every_way = k.type == kLightPoint;
        if (k.type == kLightSpot) {
          l.spot_axis = k.direction;
          l.spot_cos = k.cos_outer;
        }
        return l;
      },
      step);
}

// What the compiler owns, compared byte for byte, after edit `step`; the
// light trees (and the root and trails that depend on their shapes) by what
// they bound.
inline void expect_same_scene_arrays(const KernelScene& a, const KernelScene& b, int step) {
#define TANDEM_EXPECT_SAME(T, name)                                                     \
  if (std::strcmp(#name, "light_tree_nodes") != 0 &&                                    \
      std::strcmp(#name, "light_tree_trails") != 0 &&                                   \
      std::strcmp(#name, "triangle_light_trails") != 0 &&                               \
      std::strcmp(#name, "mesh_lights") != 0) {                                         \
    EXPECT_TRUE(same_bytes(a.name, b.name)) << #name << " differs after edit " << step; \
  }
  TANDEM_SCENE_ARRAYS(TANDEM_EXPECT_SAME)
#undef TANDEM_EXPECT_SAME
  ASSERT_EQ(a.mesh_lights.size(), b.mesh_lights.size());
  for (size_t m = 0; m < a.mesh_lights.size(); ++m) {
    // Not the trees' roots: a refit tree keeps its build's shape.
    const KMeshLights &ma = a.mesh_lights[m], &mb = b.mesh_lights[m];
    EXPECT_TRUE(ma.first == mb.first && ma.count == mb.count && ma.power == mb.power &&
                (ma.tree_root == kInvalidIndex) == (mb.tree_root == kInvalidIndex))
        << "mesh_lights[" << m << "] differs after edit " << step;
  }
  KernelConstants ca = a.constants, cb = b.constants;
  EXPECT_EQ(ca.light_tree_root == kInvalidIndex, cb.light_tree_root == kInvalidIndex);
  ca.light_tree_root = cb.light_tree_root = 0;
  EXPECT_EQ(std::memcmp(&ca, &cb, sizeof(KernelConstants)), 0)
      << "constants differ after edit " << step;
  expect_light_trees_bound_their_lights(a, step);
  expect_light_trees_bound_their_lights(b, step);
}

}  // namespace tandem
