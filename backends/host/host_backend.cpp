#include "backends/host/host_backend.h"

#include <chrono>
#include <vector>

#include "core/kernel/bvh_traverse.h"
#include "core/render/cpu_tile_loop.h"
#include "core/render/cpu_wavefront.h"

namespace tandem {

namespace {

// A batch of the wavefront pipeline: up to 16 tiles of 32x32 (fewer, larger
// batches would leave less for the tile scheduler to balance), traced in
// chunks of at most kMaxItems pixel samples with at most kSlots paths in
// flight (enough to keep every core busy in each stage).
constexpr uint32_t kMaxBatchPixels = 16 * 32 * 32;
constexpr uint64_t kMaxItems = 1u << 18;
constexpr uint32_t kSlots = 1u << 14;

}  // namespace

HostBackend::HostBackend(CudaKernelVariant kernel) : kernel_(kernel) {}
HostBackend::~HostBackend() = default;

void HostBackend::sync(const KernelScene& scene, const SceneDelta& /*delta*/) {
  // Nothing to copy: the BVH lives in the KernelScene's own arrays, which
  // AccelStructure has already brought up to date for this delta.
  check_bvh_present(scene, "host backend");
  kd_ = scene.view();
}

BackendStats HostBackend::render(const RenderPass& pass, TileSource& tiles, Film& film) {
  if (kernel_ == CudaKernelVariant::kWavefront) return render_wavefront(pass, tiles, film);
  return render_tiles_on_cpu(kd_, BvhTracer{&kd_}, pass, tiles, film);
}

BackendStats HostBackend::render_wavefront(const RenderPass& pass, TileSource& source, Film& film) {
  const auto start = std::chrono::steady_clock::now();
  if (!wavefront_) wavefront_ = std::make_unique<CpuWavefrontStorage>();
  BackendStats stats;
  std::vector<Tile> tiles;
  std::vector<DeviceTile> batch_tiles;
  std::vector<Vec3> radiance;
  std::vector<double> sums;
  const BvhTracer tracer{&kd_};
  for (;;) {
    tiles.clear();
    batch_tiles.clear();
    uint32_t pixels = 0;
    Tile t;
    while (pixels < kMaxBatchPixels && source.next(&t)) {
      tiles.push_back(t);
      batch_tiles.push_back(DeviceTile{t.x0, t.y0, t.x1, t.y1, pixels});
      pixels += t.pixel_count();
    }
    if (tiles.empty()) break;
    TileBatch batch;
    batch.tiles = batch_tiles.data();
    batch.tile_count = uint32_t(batch_tiles.size());
    batch.pixel_count = pixels;
    const uint32_t chunk = uint32_t(std::max<uint64_t>(1, kMaxItems / pixels));
    sums.assign(3 * size_t(pixels), 0.0);
    for (uint32_t done = 0; done < pass.sample_count; done += chunk) {
      batch.sample_begin = pass.sample_begin + done;
      batch.sample_count = std::min(chunk, pass.sample_count - done);
      radiance.resize(batch.items());
      stats.rays += run_wavefront_on_cpu(kd_, tracer, batch, kSlots, *wavefront_, radiance.data());
      // Sample order and double precision per pixel, as the tile loop sums.
      detail::parallel_over(pixels, [&](uint32_t p) {
        reduce_pixel_samples(batch, radiance.data(), p, sums.data());
      });
    }
    size_t p = 0;
    for (const Tile& tile : tiles) {
      for (uint32_t y = tile.y0; y < tile.y1; ++y)
        for (uint32_t x = tile.x0; x < tile.x1; ++x, ++p)
          film.add(x, y, &sums[3 * p], pass.sample_count);
      stats.tiles += 1;
      stats.pixels += tile.pixel_count();
      stats.samples += uint64_t(tile.pixel_count()) * pass.sample_count;
    }
  }
  stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return stats;
}

}  // namespace tandem
