#include "accstruc/accel_structure.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_reduce.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <iterator>
#include <limits>
#include <stdexcept>

#include "core/util/log.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

// Wide leaf slots hold up to three triangles, or one instance.
constexpr uint32_t kBlasWideLeafPrims = kWideMaxLeafPrims;
constexpr uint32_t kTlasWideLeafPrims = 1;

// A BLAS's refit_quality() as built, before its first refit measures it.
constexpr double kQualityUnknown = std::numeric_limits<double>::quiet_NaN();

void mark_all(ArrayChange& c) {
  c.reallocated = true;
}

KLeafTriangle make_leaf_triangle(const MeshGeometry& g, uint32_t prim) {
  const KTriangle& t = g.triangles[prim];
  const Vec3 a = g.positions[t.v0], b = g.positions[t.v1], c = g.positions[t.v2];
  KLeafTriangle lt;
  lt.p0 = {a.x, a.y, a.z, uint_as_float(prim)};
  lt.p1 = {b.x, b.y, b.z, 0.0f};
  lt.p2 = {c.x, c.y, c.z, 0.0f};
  return lt;
}

// Rewrites a BLAS's leaf records (bvh_leaf_triangles, in the binary leaf
// order `prims`, placed at entry `base`) from the mesh's current vertices,
// writing only those that differ, and marks them in `change` block by block,
// so that a small deformation uploads a few small ranges.
void emit_changed_leaf_triangles(const std::vector<uint32_t>& prims, const MeshGeometry& g,
                                 uint32_t base, KLeafTriangle* out, ArrayChange& change) {
  constexpr uint32_t kBlock = 4096;
  const uint32_t n = uint32_t(prims.size());
  const uint32_t blocks = (n + kBlock - 1) / kBlock;
  std::vector<NodeSpan> spans(blocks);
  tbb::parallel_for(0u, blocks, [&](uint32_t blk) {
    NodeSpan span{~0u, 0u};
    for (uint32_t i = blk * kBlock, e = std::min(n, i + kBlock); i < e; ++i) {
      const KLeafTriangle lt = make_leaf_triangle(g, prims[i]);
      if (std::memcmp(&lt, out + i, sizeof lt) == 0) continue;
      out[i] = lt;
      span.begin = std::min(span.begin, i);
      span.end = i + 1;
    }
    spans[blk] = span;
  });
  for (const NodeSpan& span : spans) {
    if (span.end > span.begin) change.mark(base + span.begin, base + span.end);
  }
}

// A BLAS built with spatial splits lists some triangle in two leaves.
bool lists_a_triangle_twice(const std::vector<uint32_t>& prims, uint32_t triangle_count) {
  std::vector<uint8_t> seen(triangle_count, 0);
  for (uint32_t p : prims) {
    if (p >= triangle_count) continue;
    if (seen[p]) return true;
    seen[p] = 1;
  }
  return false;
}

}  // namespace

MeshGeometry mesh_geometry(const KernelScene& ks, uint32_t mesh) {
  const KMesh& km = ks.meshes[mesh];
  MeshGeometry g;
  g.positions = ks.positions.data() + km.vertex_offset;
  g.vertex_count = km.vertex_count;
  g.triangles = ks.triangles.data() + km.triangle_offset;
  g.triangle_count = km.triangle_count;
  return g;
}

std::vector<Aabb> triangle_boxes(const MeshGeometry& mesh) {
  std::vector<Aabb> boxes(mesh.triangle_count);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, mesh.triangle_count, 16384), [&](auto r) {
    for (uint32_t i = r.begin(); i < r.end(); ++i) {
      const KTriangle& t = mesh.triangles[i];
      Aabb b;
      if (t.v0 < mesh.vertex_count && t.v1 < mesh.vertex_count && t.v2 < mesh.vertex_count) {
        b.grow(mesh.positions[t.v0]);
        b.grow(mesh.positions[t.v1]);
        b.grow(mesh.positions[t.v2]);
        // min/max drop NaNs depending on argument order; make sure a
        // non-finite vertex always invalidates the box.
        if (!is_finite(mesh.positions[t.v0]) || !is_finite(mesh.positions[t.v1]) ||
            !is_finite(mesh.positions[t.v2])) {
          b = Aabb{};
        }
      }
      boxes[i] = b;
    }
  });
  return boxes;
}

Aabb transform_box(const Mat34& m, const Aabb& b) {
  Aabb out;
  if (b.empty()) return out;
  const float lo[3] = {b.lo.x, b.lo.y, b.lo.z}, hi[3] = {b.hi.x, b.hi.y, b.hi.z};
  float olo[3], ohi[3];
  for (int i = 0; i < 3; ++i) {
    const Vec4& row = m.rows[i];
    const float r[3] = {row.x, row.y, row.z};
    float mn = row.w, mx = row.w, mag = std::fabs(row.w);
    for (int j = 0; j < 3; ++j) {
      const float a = r[j] * lo[j], c = r[j] * hi[j];
      mn += std::min(a, c);
      mx += std::max(a, c);
      mag += std::fabs(r[j]) * std::max(std::fabs(lo[j]), std::fabs(hi[j]));
    }
    // The sums above round; 1e-6 relative to the largest term is ~8 ulps.
    const float pad = mag * 1e-6f;
    olo[i] = mn - pad;
    ohi[i] = mx + pad;
  }
  out.lo = {olo[0], olo[1], olo[2]};
  out.hi = {ohi[0], ohi[1], ohi[2]};
  return out;
}

AccelStructure::AccelStructure(AccelSettings settings) : settings_(std::move(settings)) {
  // A wide leaf slot holds at most 3 triangles and a wide node 8 slots.
  settings_.blas.max_leaf_size = std::clamp<uint32_t>(settings_.blas.max_leaf_size, 1u, 16u);
  settings_.deforming_blas.max_leaf_size =
      std::clamp<uint32_t>(settings_.deforming_blas.max_leaf_size, 1u, 16u);
  settings_.deforming_blas.spatial_split_budget = 0.0f;  // refit every frame
  settings_.tlas.max_leaf_size = 1;
  if (const char* v = std::getenv("TANDEM_BVH_SPATIAL_SPLITS")) {
    const float budget = std::strtof(v, nullptr);
    settings_.blas.spatial_split_budget = budget > 0.0f && budget <= 4.0f ? budget : 0.0f;
  }
  if (settings_.cache.enabled) {
    std::filesystem::path dir = settings_.cache.directory.empty()
                                    ? BvhCache::default_directory()
                                    : std::filesystem::path(settings_.cache.directory);
    if (!dir.empty()) cache_ = std::make_unique<BvhCache>(dir);
  }
}

AccelStructure::~AccelStructure() = default;

void AccelStructure::build_blas(const KernelScene& ks, const std::vector<uint32_t>& meshes,
                                AccelUpdate& up, bool allow_cache) {
  std::atomic<uint32_t> built{0}, loaded{0};
  BuildSettings refittable = settings_.blas;
  refittable.spatial_split_budget = 0.0f;
  tbb::parallel_for(size_t(0), meshes.size(), [&](size_t i) {
    const uint32_t m = meshes[i];
    const MeshGeometry g = mesh_geometry(ks, m);
    const bool split = settings_.blas.spatial_split_budget > 0.0f && !mesh_deforms(ks, m);
    // Only a mesh the scene marks as deforming gets the deforming meshes'
    // leaves: its tree then depends on the scene alone, not on whether it
    // was edited before, so a fresh compile of the same scene builds it too.
    const bool marked = (ks.meshes[m].flags & kMeshDeforms) != 0u;
    const BuildSettings& bs =
        split ? settings_.blas : (marked ? settings_.deforming_blas : refittable);
    blas_split_[m] = 0;
    // Measured before the first refit of the new tree (refit_blas).
    blas_built_quality_[m] = kQualityUnknown;
    blas_refit_[m].clear();
    blas_refit_state_[m] = FastRefit::kNotTried;
    host_stale_[m] = 0;
    wide_stale_[m] = 0;
    const bool use_cache =
        allow_cache && cache_ && g.triangle_count >= settings_.cache.min_triangles;
    uint64_t key = 0;
    if (use_cache) {
      key = blas_cache_key(g, bs, kBlasWideLeafPrims);
      std::string why;
      const auto r = cache_->load(key, g.triangle_count, &blas_[m], &why);
      if (r == BvhCache::LoadResult::kHit) {
        loaded.fetch_add(1);
        blas_split_[m] = split && lists_a_triangle_twice(blas_[m].prims, g.triangle_count);
        return;
      }
      if (r == BvhCache::LoadResult::kRejected) log_warning("BVH cache: " + why + "; rebuilding");
    }
    const std::vector<Aabb> boxes = triangle_boxes(g);
    const BuildTree tree = split ? build_bvh_spatial(boxes, {g.positions, g.vertex_count},
                                                     {g.triangles, g.triangle_count}, bs)
                                 : build_bvh(boxes, bs);
    blas_[m] =
        make_layouts(tree, boxes, kBlasWideLeafPrims, bs.traversal_cost, bs.intersection_cost);
    blas_split_[m] = split && lists_a_triangle_twice(blas_[m].prims, g.triangle_count);
    built.fetch_add(1);
    if (use_cache) cache_->store(key, blas_[m]);
  });
  up.blas_built += built.load();
  up.blas_loaded += loaded.load();
}

namespace {
// Whether one of the changed ranges holds all of [b, e).
bool covers(const ArrayChange& c, uint32_t b, uint32_t e) {
  if (e <= b) return false;
  bool all = false;
  c.for_each_range([&](uint32_t lo, uint32_t hi) { all = all || (lo <= b && e <= hi); });
  return all;
}
}  // namespace

std::vector<uint32_t> AccelStructure::refit_blas(KernelScene& ks,
                                                 const std::vector<uint32_t>& meshes,
                                                 const ArrayChange& positions) {
  std::vector<uint8_t> poor(meshes.size(), 0);
  const bool wide_in_use = settings_.refit_unused_layout || settings_.layout == kBvhLayoutWide;
  tbb::parallel_for(size_t(0), meshes.size(), [&](size_t i) {
    const uint32_t m = meshes[i];
    const bool keep_wide = wide_in_use && !binary_only(ks, m);
    BvhLayouts& l = blas_[m];
    const MeshGeometry g = mesh_geometry(ks, m);
    if (blas_split_[m]) {
      // Split references cannot follow the vertices: rebuild it for refits.
      deforms_[m] = 1;
      poor[i] = 1;
      return;
    }
    if (std::isnan(blas_built_quality_[m])) blas_built_quality_[m] = refit_quality(l);
    if (blas_refit_state_[m] == FastRefit::kNotTried) {
      blas_refit_state_[m] = blas_refit_[m].index(l, g) ? FastRefit::kIndexed : FastRefit::kRefused;
    }
    refit_emitted_[m] = 0;
    if (blas_refit_state_[m] == FastRefit::kIndexed) {
      // One pass over the triangles in leaf order, both layouts, straight
      // into the kernel arrays (blas_refit.h).
      // Every vertex rewritten (a skinned or morphed mesh, whose deformer
      // writes them all): no record can be left as it was worth reading the
      // old one to find out, so they are streamed out (blas_refit.h).
      const LayoutBases& b = blas_bases_[m];
      const uint32_t v0 = ks.meshes[m].vertex_offset;
      const bool all_moved = covers(positions, v0, v0 + g.vertex_count);
      // A mesh that deforms whole is traced without records from now on
      // (AccelSettings::deforming_leaf_records): update() flags its root.
      if (all_moved && !settings_.deforming_leaf_records) no_records_[m] = 1;
      KLeafTriangle* records = no_records_[m] ? nullptr : ks.bvh_leaf_triangles.data() + b.prim;
      BlasRefit::Result r = blas_refit_[m].refit(
          l, g, b, ks.bvh_nodes.data() + b.node,
          keep_wide ? ks.bvh_wide_nodes.data() + b.wide_node : nullptr, records, all_moved);
      refit_emitted_[m] = 1;
      host_stale_[m] = 1;
      wide_stale_[m] = keep_wide ? 0 : 1;
      refit_spans_[m] = r.spans;
      refit_leaf_spans_[m] = std::move(r.leaf_spans);
      poor[i] = r.members_changed || refit_too_poor(r.quality, blas_built_quality_[m]);
      return;
    }
    const std::vector<Aabb> boxes = triangle_boxes(g);
    // A triangle whose box became valid or invalid (a vertex went to or
    // came back from NaN) joins or leaves the hierarchy: only a build
    // does that. Equal counts with a swapped member go unnoticed; the
    // swapped-out triangle is then left out (leaf_box skips it) and the
    // new one missed until the next rebuild.
    const size_t valid = tbb::parallel_reduce(
        tbb::blocked_range<size_t>(0, boxes.size(), 65536), size_t(0),
        [&](const tbb::blocked_range<size_t>& r, size_t n) {
          for (size_t b = r.begin(); b < r.end(); ++b)
            n += aabb_valid(boxes[b]) ? 1 : 0;
          return n;
        },
        std::plus<size_t>());
    if (valid != l.prims.size()) {
      poor[i] = 1;
      return;
    }
    poor[i] = refit_too_poor(refit_layouts(l, boxes), blas_built_quality_[m]);
  });
  std::vector<uint32_t> rebuild;
  for (size_t i = 0; i < meshes.size(); ++i) {
    if (poor[i]) rebuild.push_back(meshes[i]);
  }
  return rebuild;
}

void AccelStructure::emit_blas(KernelScene& ks, uint32_t m) const {
  const LayoutBases& b = blas_bases_[m];
  emit_layouts(blas_[m], b, ks.bvh_nodes.data() + b.node, ks.bvh_prim_indices.data() + b.prim,
               ks.bvh_wide_nodes.data() + b.wide_node,
               ks.bvh_wide_prim_indices.data() + b.wide_prim);
  emit_blas_wide_entries(blas_[m], b, ks.bvh_wide_prim_indices.data() + b.wide_prim);
  if (no_records_[m]) return;  // traced through its indices; the records stay zero
  const MeshGeometry g = mesh_geometry(ks, m);
  const std::vector<uint32_t>& prims = blas_[m].prims;
  KLeafTriangle* out = ks.bvh_leaf_triangles.data() + b.prim;
  for (size_t i = 0; i < prims.size(); ++i)
    out[i] = make_leaf_triangle(g, prims[i]);
  // The same records in the wide layout's entry order: each wide entry
  // names its binary record (emit_blas_wide_entries).
  const uint32_t* wide_entries = ks.bvh_wide_prim_indices.data() + b.wide_prim;
  KLeafTriangle* wide_out = ks.bvh_wide_leaf_triangles.data() + b.wide_prim;
  for (size_t j = 0; j < blas_[m].wide_prims.size(); ++j)
    wide_out[j] = ks.bvh_leaf_triangles[wide_entries[j]];
}

bool AccelStructure::mesh_deforms(const KernelScene& ks, uint32_t m) const {
  return deforms_[m] != 0 || (ks.meshes[m].flags & kMeshDeforms) != 0u;
}

bool AccelStructure::binary_only(const KernelScene& ks, uint32_t m) const {
  return settings_.deforming_binary_only && settings_.layout == kBvhLayoutWide &&
         mesh_deforms(ks, m);
}

void AccelStructure::emit_blas_flags(KernelScene& ks, uint32_t m, AccelUpdate& up) const {
  const uint32_t flags = (no_records_[m] ? kBlasNoLeafRecords : 0u) |
                         (wide_records_stale_[m] ? kBlasNoWideRecords : 0u) |
                         (binary_only(ks, m) ? kBlasBinaryOnly : 0u);
  if (ks.blas_roots[m].flags == flags) return;
  ks.blas_roots[m].flags = flags;
  up.delta.blas_roots.mark(m, m + 1);
}

const BvhLayouts& AccelStructure::blas(uint32_t mesh) const {
  std::lock_guard<std::mutex> lock(host_sync_mutex_);
  if (arrays_) sync_host_copy(*arrays_, mesh);
  return blas_[mesh];
}

void AccelStructure::sync_host_copy(const KernelScene& ks, uint32_t m) const {
  if (m >= host_stale_.size() || !host_stale_[m]) return;
  const LayoutBases& b = blas_bases_[m];
  BlasRefit::copy_boxes_to_host(blas_[m], ks.bvh_nodes.data() + b.node,
                                ks.bvh_wide_nodes.data() + b.wide_node);
  // The kernel's wide nodes lag: refit the host copy's from the vertices
  // (the general refit, equal to BlasRefit's; rare: a relayout or blas()
  // while the wide layout is not in use).
  if (wide_stale_[m]) refit_layouts(blas_[m], triangle_boxes(mesh_geometry(ks, m)));
  host_stale_[m] = 0;
}

// Places every BLAS and the TLAS region in fresh arrays.
void AccelStructure::layout_arrays(KernelScene& ks, AccelUpdate& up) {
  const uint32_t n = uint32_t(blas_.size());
  // The arrays are about to be replaced: refit boxes that live only there
  // go back to the host copies they are emitted from.
  for (uint32_t m = 0; m < n; ++m)
    sync_host_copy(ks, m);
  blas_bases_.assign(n, LayoutBases{});
  uint64_t node = 0, prim = 0, wide_node = 0, wide_prim = 0;
  for (uint32_t m = 0; m < n; ++m) {
    blas_bases_[m] = {uint32_t(node), uint32_t(prim), uint32_t(wide_node), uint32_t(wide_prim)};
    node += blas_[m].nodes.size();
    prim += blas_[m].prims.size();
    wide_node += blas_[m].wide_nodes.size();
    wide_prim += blas_[m].wide_prims.size();
  }
  // The TLAS region depends only on the instance count: a binary tree over
  // k <= n leaves has max(1, k - 1) interior nodes, and so at most has a
  // wide tree whose nodes all have two or more children.
  const uint32_t instances = uint32_t(ks.instances.size());
  tlas_capacity_instances_ = instances;
  const uint32_t tlas_nodes = std::max(1u, instances > 0 ? instances - 1 : 0u);
  tlas_base_ = {uint32_t(node), uint32_t(prim), uint32_t(wide_node), uint32_t(wide_prim)};
  node += tlas_nodes;
  prim += instances;
  wide_node += tlas_nodes;
  wide_prim += instances;
  if (std::max({node, prim, wide_node, wide_prim}) >= kBvhLeafFlag) {
    throw std::length_error("scene too large for Tandem's BVH (2^31 nodes or primitives)");
  }
  ks.bvh_nodes.assign(node, KBvhNode{});
  ks.bvh_prim_indices.assign(prim, 0u);
  ks.bvh_leaf_triangles.assign(prim, KLeafTriangle{});
  ks.bvh_wide_nodes.assign(wide_node, KWideBvhNode{});
  ks.bvh_wide_prim_indices.assign(wide_prim, 0u);
  ks.bvh_wide_leaf_triangles.assign(wide_prim, KLeafTriangle{});
  wide_records_stale_.assign(n, 0);  // emitted from the current vertices below
  tbb::parallel_for(0u, n, [&](uint32_t m) { emit_blas(ks, m); });
  if (ks.blas_roots.size() != n) {
    ks.blas_roots.assign(n, KBlasRoot{kInvalidIndex, kInvalidIndex, 0u, 0u});
    mark_all(up.delta.blas_roots);
  }
  for (uint32_t m = 0; m < n; ++m) {
    KBlasRoot& roots = ks.blas_roots[m];
    const bool empty = blas_[m].empty();
    const uint32_t root = empty ? kInvalidIndex : blas_bases_[m].node;
    const uint32_t wide_root = empty ? kInvalidIndex : blas_bases_[m].wide_node;
    if (roots.bvh_root != root || roots.wide_root != wide_root) {
      roots.bvh_root = root;
      roots.wide_root = wide_root;
      up.delta.blas_roots.mark(m, m + 1);
    }
    emit_blas_flags(ks, m, up);
  }
  mark_all(up.delta.bvh_nodes);
  mark_all(up.delta.bvh_prim_indices);
  mark_all(up.delta.bvh_leaf_triangles);
  mark_all(up.delta.bvh_wide_nodes);
  mark_all(up.delta.bvh_wide_prim_indices);
  mark_all(up.delta.bvh_wide_leaf_triangles);
  wide_stale_.assign(n, 0);  // every BLAS emitted from a current host copy
  laid_out_ = true;
}

Aabb AccelStructure::tlas_box(const KInstance& inst) const {
  if (inst.mesh >= blas_.size() || (inst.flags & kInstanceHidden) != 0u) return Aabb{};
  return transform_box(inst.object_to_world, blas_[inst.mesh].bounds);
}

void AccelStructure::compute_tlas_boxes(const KernelScene& ks) {
  const uint32_t instances = uint32_t(ks.instances.size());
  tlas_boxes_.resize(instances);
  auto body = [&](uint32_t i) {
    // Instances of meshes without triangles, and hidden ones, stay out of
    // the TLAS.
    tlas_boxes_[i] = tlas_box(ks.instances[i]);
  };
  if (instances >= 4096) {
    tbb::parallel_for(0u, instances, body);
  } else {
    for (uint32_t i = 0; i < instances; ++i)
      body(i);
  }
}

void AccelStructure::rebuild_tlas(KernelScene& ks, AccelUpdate& up) {
  compute_tlas_boxes(ks);
  const uint32_t instances = uint32_t(ks.instances.size());
  const BuildSettings& ts = settings_.tlas;
  const BuildTree tree = build_bvh(tlas_boxes_, ts);
  tlas_ = BvhLayouts{};
  if (!tree.empty()) {
    flatten_binary(tree, tlas_);
    collapse_wide(tree, tlas_boxes_, kTlasWideLeafPrims, ts.traversal_cost, ts.intersection_cost,
                  tlas_);
  }
  const uint32_t cap_nodes = std::max(1u, instances > 0 ? instances - 1 : 0u);
  if (tlas_.nodes.size() > cap_nodes || tlas_.wide_nodes.size() > cap_nodes) {
    throw std::logic_error("TLAS larger than its region");  // cannot happen, see layout_arrays
  }
  tlas_members_.resize(instances);
  for (uint32_t i = 0; i < instances; ++i)
    tlas_members_[i] = aabb_valid(tlas_boxes_[i]);
  tlas_built_quality_ = refit_quality(tlas_);
  tlas_partial_.index(tlas_, tlas_boxes_, instances);
  emit_tlas(ks, up, /*prims_changed=*/true);
  up.tlas_rebuilt = true;
}

bool AccelStructure::refit_tlas(KernelScene& ks, AccelUpdate& up,
                                const std::vector<uint32_t>* moved) {
  const uint32_t instances = uint32_t(ks.instances.size());
  if (tlas_.empty() || tlas_members_.size() != instances) return false;
  if (moved && tlas_boxes_.size() == instances) {
    // Only the moved instances' boxes and their paths to the root: the
    // result is bit for bit the full refit's (partial_refit.h).
    for (uint32_t i : *moved) {
      if (i >= instances) continue;
      tlas_boxes_[i] = tlas_box(ks.instances[i]);
      if (tlas_members_[i] != uint8_t(aabb_valid(tlas_boxes_[i]))) return false;
    }
    tlas_partial_.refit(tlas_, tlas_boxes_, *moved);
    // refit_quality(), from the refit's running sum of child areas.
    const double root = tlas_.bounds.half_area();
    const double quality = root > 0.0 ? tlas_partial_.child_area_sum() / root : 0.0;
    if (refit_too_poor(quality, tlas_built_quality_)) return false;
    const std::vector<uint32_t>& nodes = tlas_partial_.changed_nodes();
    const std::vector<uint32_t>& wide = tlas_partial_.changed_wide_nodes();
    emit_layout_nodes(tlas_, tlas_base_, nodes, wide, ks.bvh_nodes.data() + tlas_base_.node,
                      ks.bvh_wide_nodes.data() + tlas_base_.wide_node);
    if (!nodes.empty())
      up.delta.bvh_nodes.mark(tlas_base_.node + nodes.front(), tlas_base_.node + nodes.back() + 1);
    if (!wide.empty()) {
      up.delta.bvh_wide_nodes.mark(tlas_base_.wide_node + wide.front(),
                                   tlas_base_.wide_node + wide.back() + 1);
    }
    up.tlas_refit = true;
    return true;
  }
  compute_tlas_boxes(ks);
  for (uint32_t i = 0; i < instances; ++i) {
    if (tlas_members_[i] != uint8_t(aabb_valid(tlas_boxes_[i]))) return false;
  }
  // In place: when the refit turns out too poor, rebuild_tlas starts from
  // the boxes alone.
  if (refit_too_poor(refit_layouts(tlas_, tlas_boxes_), tlas_built_quality_)) return false;
  tlas_partial_.index(tlas_, tlas_boxes_, instances);
  emit_tlas(ks, up, /*prims_changed=*/false);
  up.tlas_refit = true;
  return true;
}

void AccelStructure::emit_tlas(KernelScene& ks, AccelUpdate& up, bool prims_changed) {
  emit_layouts(tlas_, tlas_base_, ks.bvh_nodes.data() + tlas_base_.node,
               ks.bvh_prim_indices.data() + tlas_base_.prim,
               ks.bvh_wide_nodes.data() + tlas_base_.wide_node,
               ks.bvh_wide_prim_indices.data() + tlas_base_.wide_prim);
  SceneDelta& d = up.delta;
  d.bvh_nodes.mark(tlas_base_.node, tlas_base_.node + uint32_t(tlas_.nodes.size()));
  d.bvh_wide_nodes.mark(tlas_base_.wide_node,
                        tlas_base_.wide_node + uint32_t(tlas_.wide_nodes.size()));
  if (prims_changed) {
    d.bvh_prim_indices.mark(tlas_base_.prim, tlas_base_.prim + uint32_t(tlas_.prims.size()));
    d.bvh_wide_prim_indices.mark(tlas_base_.wide_prim,
                                 tlas_base_.wide_prim + uint32_t(tlas_.wide_prims.size()));
  }
  const uint32_t root = tlas_.empty() ? kInvalidIndex : tlas_base_.node;
  const uint32_t wide_root = tlas_.empty() ? kInvalidIndex : tlas_base_.wide_node;
  if (ks.bvh.tlas_root != root || ks.bvh.tlas_wide_root != wide_root) {
    ks.bvh.tlas_root = root;
    ks.bvh.tlas_wide_root = wide_root;
    d.bvh_constants = true;
  }
}

AccelUpdate AccelStructure::update(KernelScene& ks, const SceneDelta& delta) {
  AccelUpdate up;
  arrays_ = &ks;
  const uint32_t n = uint32_t(ks.meshes.size());
  std::vector<uint32_t> rebuild;
  bool relayout = false;
  if (delta.full || !laid_out_ || blas_.size() != n) {
    blas_.assign(n, BvhLayouts{});
    blas_built_quality_.assign(n, kQualityUnknown);
    blas_refit_.assign(n, BlasRefit{});
    blas_refit_state_.assign(n, FastRefit::kNotTried);
    host_stale_.assign(n, 0);
    wide_stale_.assign(n, 0);
    refit_spans_.assign(n, NodeSpans{});
    refit_leaf_spans_.assign(n, {});
    refit_emitted_.assign(n, 0);
    blas_split_.assign(n, 0);
    if (deforms_.size() != n) deforms_.assign(n, 0);
    no_records_.assign(n, 0);
    rebuild.resize(n);
    for (uint32_t m = 0; m < n; ++m)
      rebuild[m] = m;
    relayout = true;
  } else {
    for (uint32_t m : delta.meshes_rebuilt) {
      if (m < n) rebuild.push_back(m);
    }
    std::sort(rebuild.begin(), rebuild.end());
    rebuild.erase(std::unique(rebuild.begin(), rebuild.end()), rebuild.end());
    relayout = !rebuild.empty() || ks.instances.size() != tlas_capacity_instances_;
  }
  std::vector<uint32_t> refit;
  for (uint32_t m : delta.meshes_refit) {
    if (m < n && !std::binary_search(rebuild.begin(), rebuild.end(), m)) {
      refit.push_back(m);
      deforms_[m] = 1;
    }
  }
  // Wide nodes left behind while the binary layout was in use catch up once
  // they are (a refit of an unchanged mesh re-quantises them).
  if (settings_.refit_unused_layout || settings_.layout == kBvhLayoutWide) {
    for (uint32_t m = 0; m < wide_stale_.size() && m < n; ++m) {
      if (wide_stale_[m] && !binary_only(ks, m) &&
          !std::binary_search(rebuild.begin(), rebuild.end(), m))
        refit.push_back(m);
    }
  }
  std::sort(refit.begin(), refit.end());
  refit.erase(std::unique(refit.begin(), refit.end()), refit.end());

  // Refit first: a BLAS whose refit tree got too poor (refit_too_poor())
  // is rebuilt instead, which lays the arrays out anew.
  auto t0 = Clock::now();
  std::vector<uint32_t> poor;
  if (!refit.empty()) {
    poor = refit_blas(ks, refit, delta.positions);
    if (!poor.empty()) {
      std::vector<uint32_t> kept;
      std::set_difference(refit.begin(), refit.end(), poor.begin(), poor.end(),
                          std::back_inserter(kept));
      refit = std::move(kept);
      up.blas_refit_rebuilt = uint32_t(poor.size());
      relayout = true;
    }
    up.blas_refit = uint32_t(refit.size());
  }
  up.refit_seconds = seconds_since(t0);
  t0 = Clock::now();
  if (!rebuild.empty()) build_blas(ks, rebuild, up, /*allow_cache=*/true);
  // Deformed geometry never recurs: not worth a disk cache entry.
  if (!poor.empty()) build_blas(ks, poor, up, /*allow_cache=*/false);
  up.blas_seconds = seconds_since(t0);

  if (relayout) {
    layout_arrays(ks, up);
  } else {
    // A refit keeps every array's size: rewrite the meshes' nodes and
    // report the span of those that changed.
    for (uint32_t m : refit) {
      const LayoutBases& b = blas_bases_[m];
      const NodeSpans spans = refit_emitted_[m]
                                  ? refit_spans_[m]
                                  : emit_refit_nodes(blas_[m], b, ks.bvh_nodes.data() + b.node,
                                                     ks.bvh_wide_nodes.data() + b.wide_node);
      up.delta.bvh_nodes.mark(b.node + spans.nodes.begin, b.node + spans.nodes.end);
      up.delta.bvh_wide_nodes.mark(b.wide_node + spans.wide_nodes.begin,
                                   b.wide_node + spans.wide_nodes.end);
      // Only the binary layout's records follow the vertices: the wide
      // layout reads those until the next layout (kBlasNoWideRecords).
      if (!no_records_[m]) wide_records_stale_[m] = 1;
      emit_blas_flags(ks, m, up);
      // The leaves' records hold the vertices: rewrite the moved ones
      // (BlasRefit did, in its leaf pass).
      if (refit_emitted_[m]) {
        for (const NodeSpan& span : refit_leaf_spans_[m])
          up.delta.bvh_leaf_triangles.mark(b.prim + span.begin, b.prim + span.end);
      } else if (!no_records_[m]) {
        emit_changed_leaf_triangles(blas_[m].prims, mesh_geometry(ks, m), b.prim,
                                    ks.bvh_leaf_triangles.data() + b.prim,
                                    up.delta.bvh_leaf_triangles);
      }
    }
  }

  t0 = Clock::now();
  // Moved instances (and refit BLAS, whose bounds changed) only need the
  // TLAS refit, as long as its quality holds; anything else rebuilds it.
  if (relayout || delta.instances_changed() || !refit.empty()) {
    // Moved instances alone (no BLAS refit, whose bounds every instance of
    // the mesh sees): refit only their paths.
    const std::vector<uint32_t>* moved =
        refit.empty() && !delta.full && !delta.instances_moved.empty() ? &delta.instances_moved
                                                                       : nullptr;
    if (relayout || !refit_tlas(ks, up, moved)) rebuild_tlas(ks, up);
  }
  up.tlas_seconds = seconds_since(t0);

  if (ks.bvh.layout != uint32_t(settings_.layout)) {
    ks.bvh.layout = settings_.layout;
    up.delta.bvh_constants = true;
    // Which meshes keep only their binary layout follows the layout.
    for (uint32_t m = 0; m < n; ++m)
      emit_blas_flags(ks, m, up);
  }
  return up;
}

}  // namespace tandem
