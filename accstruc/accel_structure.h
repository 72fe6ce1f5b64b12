// The host side of Tandem's own acceleration structures: Brigade's
// "UpdateAccStruc" step.
//
// Every frame, after the SceneCompiler, AccelStructure::update() brings the
// BVH kernel arrays it owns (TANDEM_BVH_ARRAYS: blas_roots, bvh_nodes,
// bvh_prim_indices, bvh_wide_nodes, bvh_wide_prim_indices) and the BVH
// constants (KernelScene::bvh: TLAS roots, layout) up to date with what the
// compiler's SceneDelta says changed; it never writes the compiler's arrays
// or its delta:
//   - BLAS of delta.meshes_rebuilt (all meshes on delta.full) are built (or
//     read from the disk cache), in parallel across and within meshes;
//   - BLAS of delta.meshes_refit are refit in place (same size, same place),
//     and rebuilt when the refit tree got too poor (refit_too_poor(), the
//     policy the TLAS follows too);
//   - the TLAS is rebuilt from scratch when instances changed (or any BLAS).
// Each concatenated array holds every BLAS (in mesh order) and then the
// TLAS, whose region is sized from the instance count alone, so a frame that
// only moves instances rewrites only the TLAS region and a refit frame only
// the refit meshes' regions. update() reports those element ranges in a
// SceneDelta of its own (AccelUpdate::delta); SceneSync records the union
// of it and the compiler's delta as one generation, so a GPU backend
// uploads just them.
#pragma once

#include <chrono>
#include <memory>
#include <mutex>
#include <vector>

#include "accstruc/blas_refit.h"
#include "accstruc/bvh_builder.h"
#include "accstruc/bvh_cache.h"
#include "accstruc/bvh_layouts.h"
#include "accstruc/partial_refit.h"
#include "core/world/kernel_scene.h"

namespace tandem {

struct AccelSettings {
  // Binned SAH, leaves of up to 4 triangles, and spatial splits
  // (build_bvh_spatial) of up to as many extra references as triangles for
  // static meshes: on slivers and triangle soups (builtin:procedural's grass
  // and soup) they cut the triangle tests per ray by 40%, for a build 3-5x
  // as long (docs/performance/log/host_traversal.md). The environment's
  // TANDEM_BVH_SPATIAL_SPLITS=budget (0 to 4; 0: none) overrides the budget.
  // A BLAS that got split references cannot be refit (BlasRefit needs every
  // triangle in one leaf): a mesh marked as deforming (kMeshDeforms) is
  // built without them, and any other mesh that deforms (delta.meshes_refit)
  // is rebuilt without them at its first refit and stays without them.
  BuildSettings blas = {.spatial_split_budget = 1.0f};
  // A BLAS of a mesh the scene marks as deforming (kMeshDeforms: skins,
  // morph targets, procedural rigs) is refit every frame, so it gets leaves
  // of up to 8 triangles, split by the SAH only where a node costs as much
  // as four triangle tests. On a million-vertex skinned grid the binary
  // nodes fall from about 1 M to 250 K and the refit takes about half the
  // time, for 1-3 % more render time (measured in
  // docs/performance/log/deforming_meshes.md, "fewer nodes, each vertex once").
  BuildSettings deforming_blas = {.max_leaf_size = 8, .traversal_cost = 4.0f};
  // TLAS: one instance per leaf; fewer bins keep per-frame rebuilds cheap.
  BuildSettings tlas = {SplitMethod::kBinnedSah, 8, true, 1, 1.0f, 1.0f};
  KBvhLayout layout = kBvhLayoutBinary;  // what BvhTracer traverses (kd.bvh.layout)
  // false: refit frames keep only the layout in use (kd.bvh.layout) current
  // in the kernel arrays. The binary nodes are refit either way (the wide
  // boxes are made from them), so this skips the wide layout's refit while
  // the binary one is in use; the wide nodes catch up at the update() after
  // set_layout() selects them, and at a relayout. For callers whose every
  // consumer of the arrays follows kd.bvh.layout (CoreTracer's backends, on
  // the host or a device, do); true (both layouts every frame) for those
  // that read the other layout directly.
  bool refit_unused_layout = true;
  // false: a mesh whose refit finds every one of its vertices moved (a
  // skinned or morphed mesh: SceneDelta::positions covers its whole range)
  // drops its leaf records (kBlasNoLeafRecords) from then on: its triangles
  // are tested through their indices, and the refit neither writes nor
  // reports the records (48 bytes a triangle a frame, half of a skinned
  // mesh's delta). true: every mesh keeps them (the hits are the same).
  bool deforming_leaf_records = false;
  // true (for arrays that only the host's loops trace, as CoreTracer's host
  // backends do): in the wide layout, a mesh that deforms (kMeshDeforms, or
  // refit once) keeps only its binary layout current and is flagged
  // kBlasBinaryOnly, which the host's wide loop traverses in binary. The
  // wide nodes' re-quantisation was three quarters of a million skinned
  // vertices' refit; the static meshes keep the faster wide traversal.
  bool deforming_binary_only = false;
  BvhCacheSettings cache;
};

// What one update() did.
struct AccelUpdate {
  // The BVH arrays' changes (only TANDEM_BVH_ARRAYS and bvh_constants are
  // ever marked), to be united with the compiler's delta for the backends.
  SceneDelta delta;
  uint32_t blas_built = 0, blas_loaded = 0, blas_refit = 0;
  // Of delta.meshes_refit, the BLAS whose refit tree got too poor (or whose
  // set of valid triangles changed) and were rebuilt instead (counted in
  // blas_built too, not in blas_refit).
  uint32_t blas_refit_rebuilt = 0;
  bool tlas_rebuilt = false;
  // Instances only moved: the TLAS kept its topology and had its boxes refit
  // (far cheaper than a rebuild), until its quality drops too far.
  bool tlas_refit = false;
  double blas_seconds = 0.0, refit_seconds = 0.0, tlas_seconds = 0.0;
};

class AccelStructure {
 public:
  explicit AccelStructure(AccelSettings settings = {});
  ~AccelStructure();
  AccelStructure(const AccelStructure&) = delete;
  AccelStructure& operator=(const AccelStructure&) = delete;

  // Updates ks's BVH arrays for `delta` (as returned by SceneCompiler) and
  // reports what it changed in AccelUpdate::delta.
  AccelUpdate update(KernelScene& ks, const SceneDelta& delta);

  // Takes effect (kd.bvh.layout) at the next update().
  void set_layout(KBvhLayout layout) { settings_.layout = layout; }
  const AccelSettings& settings() const { return settings_; }

  // Per-mesh BLAS and the TLAS with indices relative to themselves. A BLAS
  // refit by BlasRefit keeps its current boxes only in the kernel arrays;
  // this copies them into the host copy first (once per refit), from the
  // KernelScene of the last update(), which must still exist.
  const BvhLayouts& blas(uint32_t mesh) const;
  size_t blas_count() const { return blas_.size(); }
  const BvhLayouts& tlas() const { return tlas_; }
  // The directory in use, or nullptr when the disk cache is off.
  const BvhCache* cache() const { return cache_.get(); }

 private:
  void build_blas(const KernelScene& ks, const std::vector<uint32_t>& meshes, AccelUpdate& up,
                  bool allow_cache);
  // Refits the meshes' BLAS; returns those (ascending) to rebuild instead.
  // Meshes BlasRefit handles are written into ks's BVH arrays too (their
  // spans in refit_spans_); the others are left to emit_refit_nodes().
  // `positions`: the vertices the compiler rewrote (SceneDelta::positions);
  // a mesh it covers whole has its leaf records written without a compare.
  std::vector<uint32_t> refit_blas(KernelScene& ks, const std::vector<uint32_t>& meshes,
                                   const ArrayChange& positions);
  void layout_arrays(KernelScene& ks, AccelUpdate& up);
  // Brings a BLAS's host copy up to date from `ks`'s arrays if a refit
  // left it stale.
  void sync_host_copy(const KernelScene& ks, uint32_t mesh) const;
  void emit_blas(KernelScene& ks, uint32_t mesh) const;
  // Whether mesh m is marked as deforming (kMeshDeforms) or was refit once.
  bool mesh_deforms(const KernelScene& ks, uint32_t m) const;
  // Whether mesh m keeps only its binary layout current (kBlasBinaryOnly).
  bool binary_only(const KernelScene& ks, uint32_t m) const;
  // ks.blas_roots[mesh].flags from no_records_, marked in up.delta when changed.
  void emit_blas_flags(KernelScene& ks, uint32_t mesh, AccelUpdate& up) const;
  void rebuild_tlas(KernelScene& ks, AccelUpdate& up);
  // Refits the TLAS to moved instances (`moved`, or every instance when
  // null); false when the set of instances in it changed or the refit tree
  // got much worse than a rebuild (then the TLAS is left for a rebuild).
  bool refit_tlas(KernelScene& ks, AccelUpdate& up, const std::vector<uint32_t>* moved);
  void compute_tlas_boxes(const KernelScene& ks);
  // An instance's world box in the TLAS; invalid (out of it) when hidden or
  // without triangles.
  Aabb tlas_box(const KInstance& inst) const;
  void emit_tlas(KernelScene& ks, AccelUpdate& up, bool prims_changed);

  AccelSettings settings_;
  std::unique_ptr<BvhCache> cache_;
  // mutable: blas() brings a stale host copy up to date (host_stale_).
  mutable std::vector<BvhLayouts> blas_;
  mutable std::vector<uint8_t> host_stale_;  // per BLAS: boxes only in the kernel arrays
  mutable std::mutex host_sync_mutex_;
  const KernelScene* arrays_ = nullptr;     // the KernelScene of the last update()
  std::vector<double> blas_built_quality_;  // refit_quality() right after each BLAS's build
  std::vector<LayoutBases> blas_bases_;
  // Per BLAS: its BlasRefit index (built at its first refit), whether that
  // refit wrote the kernel arrays itself, and the nodes it rewrote there.
  enum class FastRefit : uint8_t { kNotTried, kIndexed, kRefused };
  std::vector<BlasRefit> blas_refit_;
  std::vector<FastRefit> blas_refit_state_;
  std::vector<NodeSpans> refit_spans_;
  std::vector<std::vector<NodeSpan>> refit_leaf_spans_;  // leaf records it rewrote
  // Per BLAS: its wide nodes in the kernel arrays lag its binary ones (a
  // refit left them out: refit_unused_layout false).
  std::vector<uint8_t> wide_stale_;
  std::vector<uint8_t> refit_emitted_;
  // Per BLAS: built with spatial splits (no refit possible), and whether the
  // mesh has deformed (then built without them); the latter survives
  // full updates while the mesh count stays.
  std::vector<uint8_t> blas_split_;
  std::vector<uint8_t> deforms_;
  // Per BLAS: its leaf records are not kept (kBlasNoLeafRecords in its
  // KBlasRoot); set at a refit that found all of its vertices moved.
  std::vector<uint8_t> no_records_;
  // Per BLAS: its wide-order records (bvh_wide_leaf_triangles) are not
  // current (kBlasNoWideRecords): refit since the arrays were laid out,
  // which rewrites only the binary layout's records.
  std::vector<uint8_t> wide_records_stale_;
  BvhLayouts tlas_;
  LayoutBases tlas_base_;
  uint32_t tlas_capacity_instances_ = 0;
  bool laid_out_ = false;
  std::vector<Aabb> tlas_boxes_;       // reused every frame
  std::vector<uint8_t> tlas_members_;  // per instance: in the TLAS (valid box) at its last build
  double tlas_built_quality_ = 0.0;    // tlas_quality() right after the last rebuild
  PartialRefit tlas_partial_;          // refits just the paths of moved instances
};

// The boxes a mesh's BLAS is built from: one per triangle, invalid (and so
// skipped) for triangles with out-of-range indices.
std::vector<Aabb> triangle_boxes(const MeshGeometry& mesh);
MeshGeometry mesh_geometry(const KernelScene& ks, uint32_t mesh);

// World box of an object-space box under an affine transform, padded by a
// few ulps so rounding can never make it tighter than the transformed
// geometry.
Aabb transform_box(const Mat34& m, const Aabb& b);

}  // namespace tandem
