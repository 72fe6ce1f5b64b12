#include "accstruc/content_hash.h"

#include <cstring>

namespace tandem {

namespace {

// Odd constants with well-spread bits: the golden ratio and two constants of
// the splitmix64 finaliser.
constexpr uint64_t kMulA = 0x9e3779b97f4a7c15ull;
constexpr uint64_t kMulB = 0xbf58476d1ce4e5b9ull;
constexpr uint64_t kMulC = 0x94d049bb133111ebull;

uint64_t rotl(uint64_t x, int r) {
  return (x << r) | (x >> (64 - r));
}

uint64_t load64(const uint8_t* p) {
  uint64_t v;
  std::memcpy(&v, p, 8);
  return v;
}

// One lane step: the word is spread by a multiply before it is mixed in, so
// neighbouring inputs that differ in a few low bits land far apart.
uint64_t lane_step(uint64_t acc, uint64_t word) {
  acc ^= word * kMulB;
  return rotl(acc, 29) * kMulA;
}

uint64_t avalanche(uint64_t x) {
  x ^= x >> 30;
  x *= kMulB;
  x ^= x >> 27;
  x *= kMulC;
  x ^= x >> 31;
  return x;
}

}  // namespace

ContentHasher::ContentHasher(uint64_t seed) {
  for (int i = 0; i < 4; ++i)
    lanes_[i] = avalanche(seed + kMulA * uint64_t(i + 1));
}

void ContentHasher::stripe(const uint8_t* p) {
  for (int i = 0; i < 4; ++i)
    lanes_[i] = lane_step(lanes_[i], load64(p + 8 * i));
}

void ContentHasher::update(const void* data, size_t bytes) {
  const uint8_t* p = static_cast<const uint8_t*>(data);
  total_ += bytes;
  if (buffered_ > 0) {
    const size_t take = bytes < 32 - buffered_ ? bytes : 32 - buffered_;
    std::memcpy(buffer_ + buffered_, p, take);
    buffered_ += take;
    p += take;
    bytes -= take;
    if (buffered_ < 32) return;
    stripe(buffer_);
    buffered_ = 0;
  }
  for (; bytes >= 32; bytes -= 32, p += 32)
    stripe(p);
  std::memcpy(buffer_, p, bytes);
  buffered_ = bytes;
}

uint64_t ContentHasher::finish() const {
  uint64_t h = total_ * kMulC;
  for (int i = 0; i < 4; ++i)
    h = lane_step(h ^ rotl(lanes_[i], 7 * (i + 1)), lanes_[i]);
  // Tail bytes, zero-padded to whole words; the length above keeps "abc"
  // and "abc\0" apart.
  uint8_t tail[32] = {};
  std::memcpy(tail, buffer_, buffered_);
  for (size_t i = 0; i < (buffered_ + 7) / 8; ++i)
    h = lane_step(h, load64(tail + 8 * i));
  return avalanche(h);
}

uint64_t content_hash(const void* data, size_t bytes, uint64_t seed) {
  ContentHasher h(seed);
  h.update(data, bytes);
  return h.finish();
}

}  // namespace tandem
