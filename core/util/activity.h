// What the process is building right now ("building the BVH of room.gltf"),
// so that running out of memory anywhere can be reported as what ran out
// and for which file, not just "not enough memory". Set on the thread that
// drives a stage (worker threads allocate on its behalf); nested scopes
// restore the outer label.
#pragma once

#include <string>

namespace tandem {

class ScopedActivity {
 public:
  explicit ScopedActivity(std::string what);
  ~ScopedActivity();
  ScopedActivity(const ScopedActivity&) = delete;
  ScopedActivity& operator=(const ScopedActivity&) = delete;

 private:
  std::string previous_;
};

// The innermost activity in progress, or "" when none is.
std::string current_activity();

}  // namespace tandem
