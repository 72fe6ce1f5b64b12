#include "backends/cuda/commit_plan.h"

#include <algorithm>

namespace tandem {

size_t CommitPlan::array_bytes() const {
  size_t total = 0;
  for (const ArrayCopy& c : copies)
    total += c.bytes();
  return total;
}

size_t CommitPlan::total_bytes() const {
  return array_bytes() + (view_changed ? sizeof(KernelData) : 0);
}

bool DoubleBufferedCommits::pending(uint32_t set, const KernelChangeLog& log) const {
  const SetState& s = sets_[set];
  return s.log != log.id() || log.changes_since(s.generation).any();
}

CommitPlan DoubleBufferedCommits::plan(const KernelScene& ks, uint32_t target,
                                       const KernelChangeLog& log) const {
  const SetState& s = sets_[target];
  const SceneDelta changes = log.changes_since(s.log == log.id() ? s.generation : 0);
  CommitPlan plan;
  plan.set = target;
  plan.log = log.id();
  plan.generation = log.generation();
  // KernelData carries both writers' constants by value (the compiler's
  // KernelConstants, the BVH's KBvhConstants), so a change of either means
  // re-sending it (a few hundred bytes).
  plan.view_changed =
      changes.constants || changes.bvh_constants || changes.full || !s.view_uploaded;
  for (uint32_t a = 0; a < kKernelArrayCount; ++a) {
    const size_t host_count = kernel_array_host_count(ks, a);
    const uint32_t n = uint32_t(host_count);
    const ArrayChange& p = kernel_array_change(changes, a);
    // A size change the delta did not flag still needs the whole array:
    // never trust a range against a buffer of a different length.
    const bool whole = changes.full || p.reallocated || n != s.count[a];
    if (whole) {
      ArrayCopy c;
      c.array = a;
      c.begin = 0;
      c.end = n;
      c.resize = true;
      c.count = n;
      // 25% headroom: scenes that grow a little every frame (spawned
      // instances) do not reallocate every frame.
      if (host_count > s.capacity[a]) c.new_capacity = host_count + host_count / 4;
      // A resize changes KernelData's count (and maybe its pointer).
      if (n != s.count[a] || c.new_capacity != 0) plan.view_changed = true;
      // Pushed even when empty: the copy also carries the new count.
      plan.copies.push_back(c);
    } else {
      // One copy per changed range: the gaps between them stay on the device.
      p.for_each_range([&](uint32_t b, uint32_t e) {
        const uint32_t end = std::min(e, n);
        if (end <= b) return;
        ArrayCopy c;
        c.array = a;
        c.begin = b;
        c.end = end;
        c.count = n;
        plan.copies.push_back(c);
      });
    }
  }
  return plan;
}

void DoubleBufferedCommits::complete(const CommitPlan& plan) {
  SetState& s = sets_[plan.set];
  for (const ArrayCopy& c : plan.copies) {
    if (c.new_capacity) s.capacity[c.array] = c.new_capacity;
    if (c.resize) s.count[c.array] = c.count;
  }
  s.log = plan.log;
  s.generation = plan.generation;
  s.view_uploaded = true;
  current_ = plan.set;
  committed_ = true;
}

void DoubleBufferedCommits::invalidate(uint32_t set) {
  SetState& s = sets_[set];
  s.log = s.generation = 0;
  s.count.fill(0);
  s.capacity.fill(0);
  s.view_uploaded = false;
  // A set that cannot be rendered from is not the current one any more; if
  // it was, nothing is ready until the next commit completes.
  if (current_ == set) committed_ = false;
}

void DoubleBufferedCommits::forget_generations() {
  for (SetState& s : sets_)
    s.log = s.generation = 0;
}

CommitPlan DoubleBufferedCommits::plan(const KernelScene& ks, const SceneDelta& delta) {
  own_log_.append(delta);
  const CommitPlan p = plan(ks, (current_ + 1) % kSets, own_log_);
  complete(p);
  return p;
}

}  // namespace tandem
