// The GPU runbook (tools/gpu/run_on_gpu.sh) reports the GPU tests by
// counting gtest's result lines (tools/gpu/gtest_counts.sh); a count that
// missed failures once reported "0 failed" while 13 tests failed. The ctest
// gpu_runbook_counts_failures runs these three cases with
// TANDEM_RUNBOOK_SELFTEST=1, under which one passes, one skips and one fails
// on purpose, and requires the count "1 passed, 1 skipped, 1 failed". In any
// other run none of them fails.
#include <gtest/gtest.h>

#include <cstdlib>

namespace {

bool self_test() {
  const char* v = std::getenv("TANDEM_RUNBOOK_SELFTEST");
  return v && v[0] == '1';
}

TEST(RunbookSelfTest, Passes) {
  SUCCEED();
}

TEST(RunbookSelfTest, Skips) {
  GTEST_SKIP() << "skipped on purpose: the runbook counts skips";
}

TEST(RunbookSelfTest, FailsOnPurposeUnderTheSelfTest) {
  if (!self_test()) GTEST_SKIP() << "fails only under TANDEM_RUNBOOK_SELFTEST=1";
  ADD_FAILURE() << "failed on purpose: the runbook's count of failures is being tested";
}

}  // namespace
