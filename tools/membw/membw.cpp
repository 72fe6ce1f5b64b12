// The memory bandwidth a machine leaves a streaming loop: read (a sum), write
// (plain and non-temporal stores) and y += x, over buffers far larger than
// the caches, on 1 and 2 threads; the best of five passes. It tells how far
// a per-frame pass that must stream N bytes can go (the deforming meshes'
// floor in docs/performance/log/deforming_meshes_rounds_1_6.md). Not part of the build:
//   g++ -O2 -pthread tools/membw/membw.cpp -o /tmp/membw && /tmp/membw
#include <emmintrin.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <thread>
#include <vector>

namespace {

constexpr size_t kBytes = size_t(256) << 20;  // per buffer and thread
enum Kind { kRead, kWriteStream, kWrite, kAdd, kKinds };
const char* const kNames[kKinds] = {"read", "write (non-temporal)", "write", "y += x"};

void pass(Kind kind, float* x, float* y, volatile float* sink) {
  const size_t n = kBytes / sizeof(float);
  if (kind == kRead) {
    __m128 s0 = _mm_setzero_ps(), s1 = s0, s2 = s0, s3 = s0;
    for (size_t i = 0; i < n; i += 16) {
      s0 = _mm_add_ps(s0, _mm_load_ps(x + i));
      s1 = _mm_add_ps(s1, _mm_load_ps(x + i + 4));
      s2 = _mm_add_ps(s2, _mm_load_ps(x + i + 8));
      s3 = _mm_add_ps(s3, _mm_load_ps(x + i + 12));
    }
    float r[4];
    _mm_storeu_ps(r, _mm_add_ps(_mm_add_ps(s0, s1), _mm_add_ps(s2, s3)));
    *sink = r[0] + r[1] + r[2] + r[3];
  } else if (kind == kWriteStream) {
    const __m128 v = _mm_set1_ps(1.0f);
    for (size_t i = 0; i < n; i += 4)
      _mm_stream_ps(x + i, v);
    _mm_sfence();
  } else if (kind == kWrite) {
    const __m128 v = _mm_set1_ps(1.0f);
    for (size_t i = 0; i < n; i += 4)
      _mm_store_ps(x + i, v);
  } else {
    for (size_t i = 0; i < n; i += 4)
      _mm_store_ps(y + i, _mm_add_ps(_mm_load_ps(x + i), _mm_load_ps(y + i)));
  }
}

// GB/s of `kind` on `threads` threads: bytes moved (y += x reads two
// buffers and writes one) over the best pass's time.
double bandwidth(unsigned threads, Kind kind) {
  std::vector<float*> x(threads), y(threads);
  for (unsigned t = 0; t < threads; ++t) {
    x[t] = static_cast<float*>(std::aligned_alloc(64, kBytes));
    y[t] = static_cast<float*>(std::aligned_alloc(64, kBytes));
    std::memset(x[t], 0, kBytes);  // fault the pages in before timing
    std::memset(y[t], 0, kBytes);
  }
  volatile float sink = 0.0f;
  double best = 1e30;
  for (int rep = 0; rep < 5; ++rep) {
    const auto t0 = std::chrono::steady_clock::now();
    std::vector<std::thread> workers;
    for (unsigned t = 0; t < threads; ++t)
      workers.emplace_back([&, t] { pass(kind, x[t], y[t], &sink); });
    for (std::thread& w : workers)
      w.join();
    const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    if (s < best) best = s;
  }
  for (unsigned t = 0; t < threads; ++t) {
    std::free(x[t]);
    std::free(y[t]);
  }
  return double(kBytes) * threads * (kind == kAdd ? 3.0 : 1.0) / best * 1e-9;
}

}  // namespace

int main() {
  for (unsigned threads = 1; threads <= 2; ++threads) {
    for (int k = 0; k < kKinds; ++k)
      std::printf("%u thread%s  %-22s %6.2f GB/s\n", threads, threads > 1 ? "s" : " ", kNames[k],
                  bandwidth(threads, Kind(k)));
  }
  return 0;
}
