// What crosses the wire between rank 0 and a worker rank, as plain bytes
// (no MPI here, so it is unit-tested without mpirun).
//
// The scene travels as the kernel arrays of TANDEM_KERNEL_ARRAYS: the first
// sync sends every array whole, later syncs only the element ranges the
// frame's SceneDelta marks (what the CUDA backend uploads). Arrays are
// encoded by their position in that one list, never through a struct that
// mirrors it, so a new array travels without a line here.
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>
#include <vector>

#include "core/render/tiles.h"
#include "core/world/kernel_scene.h"

namespace tandem::mpi {

// Raised for a message that does not decode (truncated, out of range): the
// peer runs another build or memory was corrupted.
class WireError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// Bumped whenever a message layout changes; the handshake also compares the
// kernel arrays' element sizes (build_fingerprint()).
inline constexpr uint32_t kProtocolVersion = 4;

enum Tag : int {
  kTagHello = 1,     // worker -> 0: fingerprint, its backends
  kTagError = 2,     // worker -> 0: why it cannot go on
  kTagReset = 3,     // 0 -> worker: forget the scene (a new renderer starts)
  kTagSync = 4,      // 0 -> worker: scene delta
  kTagBatch = 5,     // 0 -> worker: tiles to render
  kTagResult = 6,    // worker -> 0: the tiles' sums
  kTagShutdown = 7,  // 0 -> worker: leave the worker loop
};

inline constexpr uint32_t kKernelArrayTotal = 0
#define TANDEM_COUNT_ARRAY(T, name) +1
    TANDEM_KERNEL_ARRAYS(TANDEM_COUNT_ARRAY)
#undef TANDEM_COUNT_ARRAY
    ;

class WireWriter {
 public:
  template <class T>
  void put(const T& v) {
    static_assert(std::is_trivially_copyable_v<T>);
    put_bytes(&v, sizeof(T));
  }
  void put_bytes(const void* p, size_t n) {
    if (n == 0) return;
    const size_t at = bytes_.size();
    bytes_.resize(at + n);
    std::memcpy(bytes_.data() + at, p, n);
  }
  void put_string(const std::string& s) {
    put(uint32_t(s.size()));
    put_bytes(s.data(), s.size());
  }
  void reserve(size_t n) { bytes_.reserve(n); }
  std::vector<uint8_t>& bytes() { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

class WireReader {
 public:
  WireReader(const uint8_t* data, size_t size, std::string what)
      : data_(data), size_(size), what_(std::move(what)) {}
  explicit WireReader(const std::vector<uint8_t>& b, std::string what)
      : WireReader(b.data(), b.size(), std::move(what)) {}
  template <class T>
  T get() {
    static_assert(std::is_trivially_copyable_v<T>);
    T v;
    get_bytes(&v, sizeof(T));
    return v;
  }
  void get_bytes(void* p, size_t n) {
    need(n);
    if (n == 0) return;  // p may be an empty vector's null data()
    std::memcpy(p, data_ + at_, n);
    at_ += n;
  }
  std::string get_string() {
    const uint32_t n = get<uint32_t>();
    need(n);
    std::string s(reinterpret_cast<const char*>(data_ + at_), n);
    at_ += n;
    return s;
  }
  // Throws WireError unless `n` more bytes are there.
  void need(size_t n) const {
    if (n > size_ - at_) throw WireError(what_ + ": message truncated");
  }
  bool done() const { return at_ == size_; }
  [[noreturn]] void fail(const std::string& why) const { throw WireError(what_ + ": " + why); }

 private:
  const uint8_t* data_;
  size_t size_, at_ = 0;
  std::string what_;
};

// "tandem 0.1.0, protocol 1, positions:12 normals:12 ...": two ranks whose
// strings differ cannot exchange scenes.
std::string build_fingerprint();

// Element count of every kernel array as the receiver holds it.
using ArrayCounts = std::array<uint32_t, kKernelArrayTotal>;

// Appends the parts of `ks` that `delta` changed. `receiver` is what the
// other side holds and is updated: an array whose size differs from it is
// sent whole even where the delta names a range (never a range against a
// buffer of another length).
void encode_scene(const KernelScene& ks, const SceneDelta& delta, ArrayCounts& receiver,
                  WireWriter& w);
// Applies an encoded scene message to `ks`; returns the delta the worker's
// own backends sync with.
SceneDelta decode_scene(WireReader& r, KernelScene& ks);

// A batch of tiles and the samples to take of them.
struct TileBatch {
  uint32_t id = 0;
  uint32_t sample_begin = 0, sample_count = 1;
  uint32_t film_width = 0, film_height = 0;
  std::vector<Tile> tiles;
};
void encode_batch(const TileBatch& b, WireWriter& w);
TileBatch decode_batch(WireReader& r);

// A worker's answer: per tile the seconds it took (< 0: not measured) and
// the sum of its pixels' samples, row by row, 3 doubles per pixel. The sums
// are added to rank 0's film as they are, so the image is the one a local
// backend would have made.
struct BatchResult {
  uint32_t id = 0;
  double busy_seconds = 0.0;  // inside the worker's render()
  // The worker's process CPU time since rank 0's reset, in all and inside
  // its backends (rendering, syncing the scene): the difference is what
  // waiting, packing and MPI cost it.
  double cpu_seconds = 0.0, render_cpu_seconds = 0.0;
  uint64_t rays = 0, samples = 0;
  std::vector<Tile> tiles;
  std::vector<double> tile_seconds;
  std::vector<double> sums;  // all tiles, in order
};
void encode_result(const BatchResult& r, WireWriter& w);
BatchResult decode_result(WireReader& r);

// The same message, written without a BatchResult in between: the header
// now, then the pixel sums straight from the worker's film, row by row.
// `sum_count` is the number of doubles that will follow (3 per pixel).
void encode_result_header(const BatchResult& r, WireWriter& w, size_t sum_count);

}  // namespace tandem::mpi
