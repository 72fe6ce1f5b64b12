#include "core/world/kernel_change_log.h"

#include <atomic>
#include <stdexcept>
#include <string>

namespace tandem {

namespace {
uint64_t next_log_id() {
  static std::atomic<uint64_t> next{1};
  return next.fetch_add(1, std::memory_order_relaxed);
}
}  // namespace

KernelChangeLog::KernelChangeLog() : id_(next_log_id()) {}

KernelChangeLog::KernelChangeLog(const KernelChangeLog& other)
    : id_(next_log_id()), generation_(other.generation_), kept_(other.kept_) {}

KernelChangeLog& KernelChangeLog::operator=(const KernelChangeLog& other) {
  id_ = next_log_id();
  generation_ = other.generation_;
  kept_ = other.kept_;
  return *this;
}

uint64_t KernelChangeLog::append(const SceneDelta& changes) {
  kept_.push_back(changes);
  if (kept_.size() > kKept) kept_.pop_front();
  return ++generation_;
}

void KernelChangeLog::add_to_newest(const SceneDelta& changes) {
  if (kept_.empty()) throw std::logic_error("KernelChangeLog::add_to_newest: no generation yet");
  kept_.back().merge(changes);
}

SceneDelta KernelChangeLog::changes_since(uint64_t since) const {
  if (since > generation_)
    throw std::logic_error("KernelChangeLog::changes_since: generation " + std::to_string(since) +
                           " is ahead of the log's " + std::to_string(generation_));
  if (since == 0 || generation_ - since > kept_.size()) return SceneDelta::everything();
  SceneDelta changes;
  for (size_t i = kept_.size() - size_t(generation_ - since); i < kept_.size(); ++i)
    changes.merge(kept_[i]);
  return changes;
}

}  // namespace tandem
