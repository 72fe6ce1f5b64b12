#include "backends/cuda/cuda_backend.h"

#include <cuda_runtime_api.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "backends/cuda/cuda_check.h"
#include "backends/cuda/cuda_kernels.h"
#include "backends/cuda/device_scene.h"
#include "core/kernel/tone_map.h"
#include "core/util/errors.h"

namespace tandem {

static_assert(uint32_t(ToneMap::kStandard) == kToneMapStandard &&
                  uint32_t(ToneMap::kAces) == kToneMapAces &&
                  uint32_t(ToneMap::kReinhard) == kToneMapReinhard,
              "core/kernel/tone_map.h mirrors ToneMap");

namespace {

// A batch holds at most this many pixels (a 512x512 frame) and one kernel
// launch at most kMaxItems pixel samples (48 MiB of radiance); larger
// sample counts run as several chunks summed in order.
constexpr uint32_t kMaxBatchPixels = 1u << 18;
constexpr uint64_t kMaxItems = 1u << 22;

// The kernels treat a missing BVH as an empty scene, so a caller that forgot
// AccelStructure would get a silently black image.
void check_bvh_present(const KernelScene& ks) {
  const bool wide = ks.constants.bvh_layout == kBvhLayoutWide;
  const size_t nodes = wide ? ks.bvh_wide_nodes.size() : ks.bvh_nodes.size();
  bool any_triangles = false;
  for (const KInstance& inst : ks.instances)
    any_triangles =
        any_triangles || (inst.mesh < ks.meshes.size() && ks.meshes[inst.mesh].triangle_count > 0);
  const uint32_t tlas = wide ? ks.constants.tlas_wide_root : ks.constants.tlas_root;
  if (any_triangles && (nodes == 0 || tlas >= nodes)) {
    throw std::logic_error(
        "cuda backend: the scene has no BVH; run AccelStructure::update_and_mark() before sync()");
  }
}

template <class T>
void device_alloc(T** p, size_t count) {
  TANDEM_CUDA_CHECK(
      cudaMalloc(reinterpret_cast<void**>(p), std::max<size_t>(count, 1) * sizeof(T)));
}
template <class T>
void host_alloc(T** p, size_t count) {
  TANDEM_CUDA_CHECK(
      cudaMallocHost(reinterpret_cast<void**>(p), std::max<size_t>(count, 1) * sizeof(T)));
}

}  // namespace

struct CudaBackend::Impl {
  // One batch in flight: the host keeps its tiles and a pinned landing area
  // for its pixel sums until the event says they arrived.
  struct Slot {
    std::vector<Tile> tiles;
    DeviceTile* host_tiles = nullptr;  // pinned
    double* host_sums = nullptr;       // pinned, 3 per pixel
    uint32_t pixel_count = 0;
    cudaEvent_t done = nullptr;
    bool busy = false;
  };

  CudaKernelVariant variant;
  cudaDeviceProp props{};
  cudaStream_t stream = nullptr;
  DeviceScene scene;
  uint64_t commit_bytes_since_render = 0;
  std::array<Slot, 2> slots;
  DeviceTile* tiles = nullptr;   // device, one batch
  double* pixel_sums = nullptr;  // device, 3 per batch pixel
  Vec3* radiance = nullptr;      // device, radiance_capacity samples
  uint64_t radiance_capacity = 0;
  unsigned long long* ray_count = nullptr;
  unsigned long long* host_ray_count = nullptr;
  uint32_t tile_capacity = 0, pixel_capacity = 0;
  WavefrontScratch wave;
  DeviceFilmView film;

  explicit Impl(CudaKernelVariant v) : variant(v) {
    TANDEM_CUDA_CHECK(cudaGetDeviceProperties(&props, 0));
    TANDEM_CUDA_CHECK(cudaStreamCreateWithFlags(&stream, cudaStreamNonBlocking));
    for (Slot& s : slots)
      TANDEM_CUDA_CHECK(cudaEventCreateWithFlags(&s.done, cudaEventDisableTiming));
    device_alloc(&radiance, kMaxItems);
    radiance_capacity = kMaxItems;
    device_alloc(&ray_count, 1);
    host_alloc(&host_ray_count, 1);
  }
  ~Impl() {
    cudaStreamSynchronize(stream);  // errors ignored: nothing to recover in a destructor
    for (Slot& s : slots) {
      cudaFreeHost(s.host_tiles);
      cudaFreeHost(s.host_sums);
      cudaEventDestroy(s.done);
    }
    cudaFree(tiles);
    cudaFree(pixel_sums);
    cudaFree(radiance);
    cudaFree(ray_count);
    cudaFreeHost(host_ray_count);
    cudaFree(film.sums);
    cudaFree(film.samples);
    wave.release();
    cudaStreamDestroy(stream);
  }

  // Grows the per-batch buffers; only called with no batch in flight.
  void reserve(uint32_t tile_count, uint32_t pixel_count) {
    if (tile_count > tile_capacity) {
      TANDEM_CUDA_CHECK(cudaFree(tiles));
      tiles = nullptr;
      device_alloc(&tiles, tile_count);
      for (Slot& s : slots) {
        TANDEM_CUDA_CHECK(cudaFreeHost(s.host_tiles));
        s.host_tiles = nullptr;
        host_alloc(&s.host_tiles, tile_count);
      }
      tile_capacity = tile_count;
    }
    if (pixel_count > pixel_capacity) {
      TANDEM_CUDA_CHECK(cudaFree(pixel_sums));
      pixel_sums = nullptr;
      device_alloc(&pixel_sums, 3 * size_t(pixel_count));
      for (Slot& s : slots) {
        TANDEM_CUDA_CHECK(cudaFreeHost(s.host_sums));
        s.host_sums = nullptr;
        host_alloc(&s.host_sums, 3 * size_t(pixel_count));
      }
      pixel_capacity = pixel_count;
    }
    // A single tile larger than kMaxItems pixels still needs one sample of
    // each of its pixels per chunk.
    if (pixel_count > radiance_capacity) {
      TANDEM_CUDA_CHECK(cudaFree(radiance));
      radiance = nullptr;
      device_alloc(&radiance, pixel_count);
      radiance_capacity = pixel_count;
    }
  }

  // Pulls the next batch of tiles into `slot`; false when the source is dry.
  bool pull_batch(TileSource& source, Slot& slot) {
    slot.tiles.clear();
    slot.pixel_count = 0;
    Tile t;
    while (slot.pixel_count < kMaxBatchPixels && source.next(&t)) {
      slot.tiles.push_back(t);
      slot.pixel_count += t.pixel_count();
    }
    return !slot.tiles.empty();
  }

  // Enqueues one batch: tiles up, every sample chunk traced and summed per
  // pixel, then (to_host) the sums copied back or (else) added to the
  // device film. Records slot.done.
  void enqueue_batch(const KernelData* kd, const RenderPass& pass, Slot& slot, bool to_host) {
    uint32_t offset = 0;
    for (size_t i = 0; i < slot.tiles.size(); ++i) {
      const Tile& t = slot.tiles[i];
      slot.host_tiles[i] = DeviceTile{t.x0, t.y0, t.x1, t.y1, offset};
      offset += t.pixel_count();
    }
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(tiles, slot.host_tiles,
                                      slot.tiles.size() * sizeof(DeviceTile),
                                      cudaMemcpyHostToDevice, stream));
    TANDEM_CUDA_CHECK(
        cudaMemsetAsync(pixel_sums, 0, 3 * sizeof(double) * slot.pixel_count, stream));
    TileBatch batch;
    batch.tiles = tiles;
    batch.tile_count = uint32_t(slot.tiles.size());
    batch.pixel_count = slot.pixel_count;
    const uint32_t chunk = uint32_t(std::max<uint64_t>(1, radiance_capacity / slot.pixel_count));
    for (uint32_t s = 0; s < pass.sample_count; s += chunk) {
      batch.sample_begin = pass.sample_begin + s;
      batch.sample_count = std::min(chunk, pass.sample_count - s);
      if (variant == CudaKernelVariant::kWavefront)
        launch_wavefront(kd, batch, wave, radiance, ray_count, stream);
      else
        launch_megakernel(kd, batch, radiance, ray_count, stream);
      launch_reduce_samples(batch, radiance, pixel_sums, stream);
    }
    if (to_host) {
      TANDEM_CUDA_CHECK(cudaMemcpyAsync(slot.host_sums, pixel_sums,
                                        3 * sizeof(double) * slot.pixel_count,
                                        cudaMemcpyDeviceToHost, stream));
    } else {
      launch_accumulate_film(batch, pixel_sums, pass.sample_count, film, stream);
    }
    TANDEM_CUDA_CHECK(cudaEventRecord(slot.done, stream));
    slot.busy = true;
  }

  // Waits for a slot's batch and adds its sums to the host film.
  void finish_batch(Slot& slot, const RenderPass& pass, Film* host_film, BackendStats& stats) {
    if (!slot.busy) return;
    TANDEM_CUDA_CHECK(cudaEventSynchronize(slot.done));
    slot.busy = false;
    size_t p = 0;
    for (const Tile& t : slot.tiles) {
      for (uint32_t y = t.y0; y < t.y1; ++y)
        for (uint32_t x = t.x0; x < t.x1; ++x, ++p)
          if (host_film) host_film->add(x, y, &slot.host_sums[3 * p], pass.sample_count);
      stats.tiles += 1;
      stats.pixels += t.pixel_count();
      stats.samples += uint64_t(t.pixel_count()) * pass.sample_count;
    }
  }

  BackendStats render(const RenderPass& pass, TileSource& source, Film* host_film) {
    if (!scene.ready()) throw std::logic_error("cuda backend: render() before sync()");
    const auto start = std::chrono::steady_clock::now();
    BackendStats stats;
    stats.commit_bytes = commit_bytes_since_render;
    commit_bytes_since_render = 0;
    if (pass.sample_count == 0) return stats;
    const KernelData* kd = scene.begin_render(stream);
    TANDEM_CUDA_CHECK(cudaMemsetAsync(ray_count, 0, sizeof(unsigned long long), stream));
    // Two slots: while the GPU traces batch k, the host pulls batch k + 1's
    // tiles and then adds batch k - 1's pixels to the film.
    for (uint32_t k = 0;; ++k) {
      Slot& slot = slots[k % 2];
      Slot& previous = slots[(k + 1) % 2];
      finish_batch(slot, pass, host_film, stats);  // two batches ago: long done
      if (!pull_batch(source, slot)) break;
      if (slot.tiles.size() > tile_capacity || slot.pixel_count > pixel_capacity) {
        finish_batch(previous, pass, host_film, stats);  // buffers are about to move
        reserve(uint32_t(slot.tiles.size()), slot.pixel_count);
      }
      enqueue_batch(kd, pass, slot, host_film != nullptr);
      finish_batch(previous, pass, host_film, stats);
    }
    for (Slot& s : slots)
      finish_batch(s, pass, host_film, stats);
    scene.end_render(stream);
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(host_ray_count, ray_count, sizeof(unsigned long long),
                                      cudaMemcpyDeviceToHost, stream));
    TANDEM_CUDA_CHECK(cudaStreamSynchronize(stream));
    stats.rays = *host_ray_count;
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
  }
};

CudaBackend::CudaBackend(CudaKernelVariant variant) {
  std::string reason;
  if (!cuda_query_device(&reason)) throw InputError("CUDA backend: " + reason);
  TANDEM_CUDA_CHECK(cudaSetDevice(0));
  impl_ = std::make_unique<Impl>(variant);
}

CudaBackend::~CudaBackend() = default;

void CudaBackend::sync(const KernelScene& scene, const SceneDelta& delta) {
  check_bvh_present(scene);
  impl_->commit_bytes_since_render += impl_->scene.commit(scene, delta);
}

BackendStats CudaBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  return impl_->render(pass, tiles, &film);
}

void CudaBackend::set_variant(CudaKernelVariant variant) {
  impl_->variant = variant;
}
CudaKernelVariant CudaBackend::variant() const {
  return impl_->variant;
}
std::string CudaBackend::device_name() const {
  return impl_->props.name;
}
uint64_t CudaBackend::last_commit_bytes() const {
  return impl_->scene.last_commit_bytes();
}
uint64_t CudaBackend::scene_device_bytes() const {
  return impl_->scene.device_bytes();
}

void CudaBackend::reset_device_film(uint32_t width, uint32_t height) {
  DeviceFilmView& f = impl_->film;
  TANDEM_CUDA_CHECK(cudaStreamSynchronize(impl_->stream));
  if (size_t(width) * height != size_t(f.width) * f.height) {
    TANDEM_CUDA_CHECK(cudaFree(f.sums));
    TANDEM_CUDA_CHECK(cudaFree(f.samples));
    f = DeviceFilmView{};
    device_alloc(&f.sums, 3 * size_t(width) * height);
    device_alloc(&f.samples, size_t(width) * height);
  }
  f.width = width;
  f.height = height;
  TANDEM_CUDA_CHECK(cudaMemsetAsync(f.sums, 0, 3 * sizeof(double) * width * height, impl_->stream));
  TANDEM_CUDA_CHECK(
      cudaMemsetAsync(f.samples, 0, sizeof(uint32_t) * width * height, impl_->stream));
}

BackendStats CudaBackend::render_to_device_film(const RenderPass& pass, TileSource& tiles) {
  if (impl_->film.width == 0) throw std::logic_error("cuda backend: reset_device_film() first");
  return impl_->render(pass, tiles, nullptr);
}

ImageRGB CudaBackend::resolve_device_film() {
  const DeviceFilmView& f = impl_->film;
  ImageRGB image(f.width, f.height);
  float* rgb = nullptr;
  device_alloc(&rgb, image.rgb.size());
  launch_resolve_film(f, rgb, impl_->stream);
  const cudaError_t copied =
      cudaMemcpyAsync(image.rgb.data(), rgb, image.rgb.size() * sizeof(float),
                      cudaMemcpyDeviceToHost, impl_->stream);
  const cudaError_t synced = cudaStreamSynchronize(impl_->stream);
  cudaFree(rgb);
  TANDEM_CUDA_CHECK(copied);
  TANDEM_CUDA_CHECK(synced);
  return image;
}

std::vector<uint8_t> CudaBackend::tone_map_device_film(float exposure_stops, ToneMap curve) {
  const DeviceFilmView& f = impl_->film;
  std::vector<uint8_t> out(3 * size_t(f.width) * f.height);
  uint8_t* rgb8 = nullptr;
  device_alloc(&rgb8, out.size());
  launch_tone_map_film(f, std::exp2(exposure_stops), uint32_t(curve), rgb8, impl_->stream);
  const cudaError_t copied =
      cudaMemcpyAsync(out.data(), rgb8, out.size(), cudaMemcpyDeviceToHost, impl_->stream);
  const cudaError_t synced = cudaStreamSynchronize(impl_->stream);
  cudaFree(rgb8);
  TANDEM_CUDA_CHECK(copied);
  TANDEM_CUDA_CHECK(synced);
  return out;
}

std::vector<Hit> CudaBackend::trace_rays(const std::vector<Ray>& rays,
                                         const std::vector<uint32_t>& alpha_keys, bool any_hit) {
  if (!impl_->scene.ready()) throw std::logic_error("cuda backend: trace_rays() before sync()");
  if (!alpha_keys.empty() && alpha_keys.size() != rays.size())
    throw std::invalid_argument("cuda backend: one alpha key per ray, or none");
  const size_t n = rays.size();
  std::vector<Hit> hits(n);
  if (n == 0) return hits;
  Ray* d_rays = nullptr;
  uint32_t* d_keys = nullptr;
  Hit* d_hits = nullptr;
  uint32_t* d_counter = nullptr;
  cudaStream_t s = impl_->stream;
  // Freed whatever happens: a failed test must not leak device memory into
  // the next one.
  struct Free {
    void* p[4];
    ~Free() {
      for (void* q : p)
        cudaFree(q);
    }
  };
  device_alloc(&d_rays, n);
  Free guard{{d_rays, nullptr, nullptr, nullptr}};
  device_alloc(&d_hits, n);
  guard.p[1] = d_hits;
  device_alloc(&d_counter, 1);
  guard.p[2] = d_counter;
  if (!alpha_keys.empty()) {
    device_alloc(&d_keys, n);
    guard.p[3] = d_keys;
    TANDEM_CUDA_CHECK(cudaMemcpyAsync(d_keys, alpha_keys.data(), n * sizeof(uint32_t),
                                      cudaMemcpyHostToDevice, s));
  }
  TANDEM_CUDA_CHECK(
      cudaMemcpyAsync(d_rays, rays.data(), n * sizeof(Ray), cudaMemcpyHostToDevice, s));
  TANDEM_CUDA_CHECK(cudaMemsetAsync(d_counter, 0, sizeof(uint32_t), s));
  const KernelData* kd = impl_->scene.begin_render(s);
  launch_trace_rays(kd, d_rays, d_keys, uint32_t(n), any_hit, d_hits, d_counter, nullptr, nullptr,
                    nullptr, s);
  impl_->scene.end_render(s);
  TANDEM_CUDA_CHECK(
      cudaMemcpyAsync(hits.data(), d_hits, n * sizeof(Hit), cudaMemcpyDeviceToHost, s));
  TANDEM_CUDA_CHECK(cudaStreamSynchronize(s));
  return hits;
}

}  // namespace tandem
