// A 64-bit streaming hash for cache keys and file checksums.
//
// Four independent multiply-rotate lanes over 32-byte stripes (so hashing
// runs at memory speed), folded together with the length and finished with
// a strong 64-bit avalanche. Not cryptographic: it detects corruption and
// distinguishes inputs, it does not resist deliberate collisions (cache
// files are validated structurally anyway).
#pragma once

#include <cstddef>
#include <cstdint>

namespace tandem {

class ContentHasher {
 public:
  explicit ContentHasher(uint64_t seed = 0);
  void update(const void* data, size_t bytes);
  template <class T>
  void update_value(const T& v) {
    update(&v, sizeof v);
  }
  uint64_t finish() const;

 private:
  void stripe(const uint8_t* p);
  uint64_t lanes_[4];
  uint8_t buffer_[32];
  size_t buffered_ = 0;
  uint64_t total_ = 0;
};

uint64_t content_hash(const void* data, size_t bytes, uint64_t seed = 0);

}  // namespace tandem
