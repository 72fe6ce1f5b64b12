// KernelChangeLog: each consumer gets exactly the changes after its own
// generation, and everything when it has seen nothing or fell too far
// behind; Backend::sync_from keeps a backend's generation for it.
#include <gtest/gtest.h>

#include <stdexcept>
#include <vector>

#include "core/render/backend.h"
#include "core/world/kernel_change_log.h"

namespace tandem {
namespace {

SceneDelta instance_moved(uint32_t i) {
  SceneDelta d;
  d.instances.mark(i, i + 1);
  d.instances_moved = {i};
  return d;
}

TEST(KernelChangeLog, EachGenerationSinceIsTheUnionOfWhatCameAfterIt) {
  KernelChangeLog log;
  EXPECT_EQ(log.generation(), 0u);
  EXPECT_TRUE(log.changes_since(0).full);
  EXPECT_EQ(log.append(instance_moved(3)), 1u);
  EXPECT_EQ(log.append(SceneDelta{}), 2u);
  EXPECT_EQ(log.append(instance_moved(7)), 3u);
  EXPECT_FALSE(log.changes_since(3).any());
  EXPECT_EQ(log.changes_since(2).instances_moved, std::vector<uint32_t>{7});
  EXPECT_EQ(log.changes_since(1).instances_moved, std::vector<uint32_t>{7});
  KernelChangeLog two;
  two.append(instance_moved(3));
  two.append(instance_moved(7));
  EXPECT_EQ(two.changes_since(1).instances_moved, std::vector<uint32_t>{7});
  two.append(instance_moved(5));
  const SceneDelta union_of_two = two.changes_since(1);
  EXPECT_EQ(union_of_two.instances_moved, (std::vector<uint32_t>{5, 7}));
  EXPECT_FALSE(union_of_two.full);
  EXPECT_THROW(log.changes_since(4), std::logic_error);
}

TEST(KernelChangeLog, AConsumerFurtherBehindThanTheLogKeepsGetsEverything) {
  KernelChangeLog log;
  for (uint32_t i = 0; i < KernelChangeLog::kKept + 4; ++i)
    log.append(instance_moved(i));
  EXPECT_TRUE(log.changes_since(1).full);
  EXPECT_FALSE(log.changes_since(log.generation() - KernelChangeLog::kKept).full);
  EXPECT_TRUE(log.changes_since(log.generation() - KernelChangeLog::kKept - 1).full);
}

TEST(KernelChangeLog, ACopyIsAnotherLog) {
  KernelChangeLog log;
  log.append(instance_moved(1));
  const KernelChangeLog copy = log;
  EXPECT_NE(copy.id(), log.id());
  EXPECT_EQ(copy.generation(), log.generation());
}

// Records the deltas it is synced with.
class RecordingBackend final : public Backend {
 public:
  std::string name() const override { return "recording"; }
  BackendTraits traits() const override { return {}; }
  void sync(const KernelScene&, const SceneDelta& delta) override { synced.push_back(delta); }
  BackendStats render(const RenderPass&, TileSource&, Film&) override { return {}; }
  std::vector<SceneDelta> synced;
};

TEST(KernelChangeLog, ABackendSyncsFromTheGenerationItHas) {
  const KernelScene ks;
  KernelChangeLog log;
  log.append(instance_moved(1));
  RecordingBackend b;
  b.sync_from(ks, log);
  ASSERT_EQ(b.synced.size(), 1u);
  EXPECT_TRUE(b.synced.back().full) << "a backend that has seen nothing gets everything";
  log.append(instance_moved(2));
  log.append(instance_moved(4));
  b.sync_from(ks, log);
  EXPECT_FALSE(b.synced.back().full);
  EXPECT_EQ(b.synced.back().instances_moved, (std::vector<uint32_t>{2, 4}));
  b.sync_from(ks, log);
  EXPECT_FALSE(b.synced.back().any());
  b.forget_synced();
  b.sync_from(ks, log);
  EXPECT_TRUE(b.synced.back().full);
  KernelChangeLog other;
  other.append(instance_moved(9));
  other.append(instance_moved(9));
  other.append(instance_moved(9));
  b.sync_from(ks, other);
  EXPECT_TRUE(b.synced.back().full) << "another log's generations mean nothing here";
}

}  // namespace
}  // namespace tandem
