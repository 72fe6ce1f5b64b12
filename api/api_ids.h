// The API's ids and the scene's slots. An id is handed out once and never
// again, so an id of a removed object is refused ever after, while the
// scene's slots behind the ids move (a removed mesh or light closes its
// gap) or are reused (a removed instance's slot takes the next instance of
// its mesh).
#pragma once

#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

#include "api/api_convert.h"

namespace tandem::api_detail {

class IdTable {
 public:
  static constexpr uint32_t kGone = 0xffffffffu;

  // Ids 0..count-1 for slots 0..count-1 (a scene just loaded).
  void reset(uint32_t count) {
    slot_.resize(count);
    id_of_.resize(count);
    for (uint32_t i = 0; i < count; ++i)
      slot_[i] = id_of_[i] = i;
  }
  // A new id for `slot` (a new slot at the end, or a reused one).
  uint32_t add(uint32_t slot) {
    const uint32_t id = uint32_t(slot_.size());
    slot_.push_back(slot);
    if (id_of_.size() <= slot) id_of_.resize(slot + 1, kGone);
    id_of_[slot] = id;
    return id;
  }
  // The slot of `id`; throws kInvalidArgument naming `what` and `kind`
  // when the id was never handed out or its object was removed.
  uint32_t slot(uint32_t id, const char* what, const char* kind) const {
    if (id >= slot_.size()) {
      invalid(std::string(what) + ": " + kind + " " + std::to_string(id) +
              " does not exist (ids so far: " + std::to_string(slot_.size()) + ")");
    }
    if (slot_[id] == kGone) {
      invalid(std::string(what) + ": " + kind + " " + std::to_string(id) + " was removed");
    }
    return slot_[id];
  }
  // The object in `slot` is gone; its slot stays (to be reused).
  void release(uint32_t slot) {
    slot_[id_of_[slot]] = kGone;
    id_of_[slot] = kGone;
  }
  // Slot `slot` is gone and later slots moved down one.
  void erase_slot(uint32_t slot) {
    release(slot);
    id_of_.erase(id_of_.begin() + slot);
    for (uint32_t s = slot; s < id_of_.size(); ++s) {
      if (id_of_[s] != kGone) slot_[id_of_[s]] = s;
    }
  }
  // Every slot moved to remap[slot] (kGone: removed).
  void remap(const std::vector<uint32_t>& remap) {
    const size_t kept =
        size_t(std::count_if(remap.begin(), remap.end(), [](uint32_t s) { return s != kGone; }));
    std::vector<uint32_t> id_of(kept, kGone);
    for (uint32_t s = 0; s < id_of_.size() && s < remap.size(); ++s) {
      const uint32_t id = id_of_[s];
      if (id == kGone) continue;
      slot_[id] = remap[s];
      if (remap[s] != kGone) id_of[remap[s]] = id;
    }
    id_of_ = std::move(id_of);
  }

 private:
  std::vector<uint32_t> slot_;   // id -> slot, kGone once removed
  std::vector<uint32_t> id_of_;  // slot -> id, kGone for a free slot
};

}  // namespace tandem::api_detail
