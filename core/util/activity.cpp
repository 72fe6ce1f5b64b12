#include "core/util/activity.h"

#include <mutex>
#include <utility>

namespace tandem {

namespace {
std::mutex activity_mutex;
std::string& activity() {
  static std::string* label = new std::string;  // never destroyed: read at exit
  return *label;
}
}  // namespace

ScopedActivity::ScopedActivity(std::string what) {
  std::lock_guard<std::mutex> lock(activity_mutex);
  previous_ = std::exchange(activity(), std::move(what));
}

ScopedActivity::~ScopedActivity() {
  std::lock_guard<std::mutex> lock(activity_mutex);
  activity() = std::move(previous_);
}

std::string current_activity() {
  std::lock_guard<std::mutex> lock(activity_mutex);
  return activity();
}

}  // namespace tandem
