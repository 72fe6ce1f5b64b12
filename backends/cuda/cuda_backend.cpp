#include "backends/cuda/cuda_backend.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <mutex>
#include <stdexcept>

#include "backends/cuda/device_launch.h"
#include "backends/cuda/device_scene.h"
#include "core/kernel/features.h"
#include "core/kernel/tone_map.h"
#include "core/util/errors.h"

namespace tandem {

bool cuda_backend_device_available(std::string* reason) {
  return device_available(reason);
}

struct CudaBackend::Impl {
  // One batch in flight: the host keeps its tiles and a pinned landing area
  // for its pixel sums until the event says they arrived. `holds_tiles`:
  // tiles were taken from the source whose sums are not in the film yet.
  struct Slot {
    std::vector<Tile> tiles;
    DeviceBuffer host_tiles, host_sums;  // pinned: DeviceTile[], 3 doubles per pixel
    DeviceEventOwner done;
    uint32_t pixel_count = 0;
    bool busy = false;  // enqueued, done not yet waited for
    bool holds_tiles = false;
  };

  std::shared_ptr<DeviceOps> dev;
  CudaKernelVariant variant;
  LaunchLimits limits;
  DeviceStreamOwner stream;
  DeviceScene scene;
  std::array<Slot, 2> slots;
  DeviceBuffer tiles, pixel_sums, radiance, ray_count, host_ray_count;
  DeviceBuffer wave;  // the wavefront's arrays (wavefront.h), carved out of one block
  WavefrontArrays wave_arrays{};
  WavefrontDriver wave_driver;
  DeviceBuffer film_sums, film_samples;
  DeviceFilmView film;
  // set_device_image(): render() also adds its sums to `film`, sized as
  // the host film, and device_image_*() resolve it into `presented`.
  bool mirror_film = false;
  DeviceBuffer presented;
  uint64_t commit_bytes_since_render = 0;
  // The feature pass's buffers, kept between frames (pinned allocations are
  // slow): the features on the device and their host landing area, and the
  // previous frame's instance transforms on both sides.
  DeviceBuffer features, host_features, prev_transforms, host_prev_transforms;
  // trace_rays()'s buffers, grown before a call claims the scene and kept:
  // freeing device memory waits for the whole device.
  DeviceBuffer query_rays, query_keys, query_hits, query_counter, query_staging;
  // The film size of the camera of the newest sync(), which render_features'
  // caller sized its output for. sync() may run on another thread.
  std::mutex camera_mutex;
  uint32_t synced_width = 0, synced_height = 0;
  void note_synced_camera(const KernelScene& ks) {
    std::lock_guard<std::mutex> lock(camera_mutex);
    synced_width = ks.constants.camera.width;
    synced_height = ks.constants.camera.height;
  }

  Impl(std::shared_ptr<DeviceOps> device, CudaKernelVariant v, LaunchLimits l)
      : dev(std::move(device)),
        variant(v),
        limits(l),
        stream(*dev),
        scene(*dev),
        tiles(*dev, DeviceBuffer::kDevice),
        pixel_sums(*dev, DeviceBuffer::kDevice),
        radiance(*dev, DeviceBuffer::kDevice),
        ray_count(*dev, DeviceBuffer::kDevice),
        host_ray_count(*dev, DeviceBuffer::kPinned),
        wave(*dev, DeviceBuffer::kDevice),
        wave_driver(*dev),
        film_sums(*dev, DeviceBuffer::kDevice),
        film_samples(*dev, DeviceBuffer::kDevice),
        presented(*dev, DeviceBuffer::kDevice),
        features(*dev, DeviceBuffer::kDevice),
        host_features(*dev, DeviceBuffer::kPinned),
        prev_transforms(*dev, DeviceBuffer::kDevice),
        host_prev_transforms(*dev, DeviceBuffer::kPinned),
        query_rays(*dev, DeviceBuffer::kDevice),
        query_keys(*dev, DeviceBuffer::kDevice),
        query_hits(*dev, DeviceBuffer::kDevice),
        query_counter(*dev, DeviceBuffer::kDevice),
        query_staging(*dev, DeviceBuffer::kPinned) {
    if (limits.max_batch_pixels == 0 || limits.max_items == 0)
      throw std::invalid_argument("cuda backend: launch limits must be positive");
    for (Slot& s : slots) {
      s.host_tiles = DeviceBuffer(*dev, DeviceBuffer::kPinned);
      s.host_sums = DeviceBuffer(*dev, DeviceBuffer::kPinned);
      s.done = DeviceEventOwner(*dev, false);
    }
    radiance.allocate(limits.max_items * sizeof(Vec3));
    ray_count.allocate(sizeof(unsigned long long));
    host_ray_count.allocate(sizeof(unsigned long long));
  }

  ~Impl() {
    try {
      dev->synchronize(stream.get());
    } catch (...) {  // nothing to recover in a destructor
    }
  }

  uint64_t radiance_items() const { return radiance.bytes() / sizeof(Vec3); }

  // A cleared device film of width x height (after the stream's work).
  void reset_film(uint32_t width, uint32_t height) {
    const size_t pixels = size_t(width) * height;
    film = DeviceFilmView{};  // until both buffers exist
    film_sums.reserve(3 * sizeof(double) * pixels);
    film_samples.reserve(sizeof(uint32_t) * pixels);
    dev->zero(film_sums.get(), 3 * sizeof(double) * pixels, stream.get());
    dev->zero(film_samples.get(), sizeof(uint32_t) * pixels, stream.get());
    film = DeviceFilmView{film_sums.as<double>(), film_samples.as<uint32_t>(), width, height};
  }

  // Grows the per-batch buffers; only called with no batch in flight. Each
  // buffer on its own: after a failed allocation some are large enough and
  // some are empty.
  void reserve(uint32_t tile_count, uint32_t pixel_count) {
    const size_t tile_bytes = size_t(tile_count) * sizeof(DeviceTile);
    const size_t sum_bytes = 3 * sizeof(double) * size_t(pixel_count);
    tiles.reserve(tile_bytes);
    pixel_sums.reserve(sum_bytes);
    for (Slot& s : slots) {
      s.host_tiles.reserve(tile_bytes);
      s.host_sums.reserve(sum_bytes);
    }
    // A single tile larger than max_items pixels still needs one sample of
    // each of its pixels per chunk.
    radiance.reserve(std::max<uint64_t>(limits.max_items, pixel_count) * sizeof(Vec3));
  }

  bool buffers_fit(const Slot& slot) const {
    return slot.tiles.size() * sizeof(DeviceTile) <= tiles.bytes() &&
           slot.host_tiles.bytes() >= slot.tiles.size() * sizeof(DeviceTile) &&
           3 * sizeof(double) * size_t(slot.pixel_count) <= pixel_sums.bytes() &&
           slot.host_sums.bytes() >= 3 * sizeof(double) * size_t(slot.pixel_count) &&
           slot.pixel_count <= radiance_items();
  }

  // Enough slots for a launch of `items` pixel samples.
  void ensure_wavefront(uint64_t items) {
    const uint32_t slots = uint32_t(std::min<uint64_t>(items, wavefront_slots(dev->properties())));
    if (slots <= wave_arrays.slots) return;
    wave_arrays = WavefrontArrays{};  // until the block exists
    uint64_t bytes = 0;
    wavefront_arrays_in(nullptr, slots, &bytes);
    wave.allocate(bytes);
    wave_arrays = wavefront_arrays_in(wave.get(), slots, &bytes);
  }

  // Pulls the next batch of tiles into `slot`; false when the source is
  // dry. Every tile must lie inside the film it will be added to.
  bool pull_batch(TileSource& source, Slot& slot, uint32_t film_width, uint32_t film_height) {
    slot.tiles.clear();
    slot.pixel_count = 0;
    Tile t;
    while (slot.pixel_count < limits.max_batch_pixels && source.next(&t)) {
      slot.tiles.push_back(t);
      slot.holds_tiles = true;
      if (t.x1 <= t.x0 || t.y1 <= t.y0 || t.x1 > film_width || t.y1 > film_height) {
        throw std::logic_error(
            "cuda backend: tile [" + std::to_string(t.x0) + ", " + std::to_string(t.x1) + ") x [" +
            std::to_string(t.y0) + ", " + std::to_string(t.y1) + ") is empty or outside the " +
            std::to_string(film_width) + "x" + std::to_string(film_height) + " film");
      }
      slot.pixel_count += t.pixel_count();
    }
    return !slot.tiles.empty();
  }

  // Enqueues one batch: tiles up, every sample chunk traced and summed per
  // pixel, then (to_host) the sums copied back or (else) added to the
  // device film. Records slot.done.
  void enqueue_batch(const DeviceScene::RenderTicket& ticket, const RenderPass& pass, Slot& slot,
                     bool to_host) {
    const DeviceStream s = stream.get();
    auto* host_tiles = slot.host_tiles.as<DeviceTile>();
    uint32_t offset = 0;
    for (size_t i = 0; i < slot.tiles.size(); ++i) {
      const Tile& t = slot.tiles[i];
      host_tiles[i] = DeviceTile{t.x0, t.y0, t.x1, t.y1, offset};
      offset += t.pixel_count();
    }
    dev->copy_to_device(tiles.get(), host_tiles, slot.tiles.size() * sizeof(DeviceTile), s);
    dev->zero(pixel_sums.get(), 3 * sizeof(double) * slot.pixel_count, s);
    TileBatch batch;
    batch.tiles = tiles.as<const DeviceTile>();
    batch.tile_count = uint32_t(slot.tiles.size());
    batch.pixel_count = slot.pixel_count;
    const uint32_t chunk = uint32_t(std::max<uint64_t>(1, radiance_items() / slot.pixel_count));
    if (variant == CudaKernelVariant::kWavefront)
      ensure_wavefront(uint64_t(chunk) * slot.pixel_count);
    for (uint32_t done = 0; done < pass.sample_count; done += chunk) {
      batch.sample_begin = pass.sample_begin + done;
      batch.sample_count = std::min(chunk, pass.sample_count - done);
      if (variant == CudaKernelVariant::kWavefront) {
        wave_driver.launch(ticket.view, batch, ticket.max_segments, wave_arrays,
                           radiance.as<Vec3>(), ray_count.as<unsigned long long>(), s);
      } else {
        launch_megakernel(*dev, ticket.view, batch, radiance.as<Vec3>(),
                          ray_count.as<unsigned long long>(), s);
      }
      launch_reduce_samples(*dev, batch, radiance.as<const Vec3>(), pixel_sums.as<double>(), s);
    }
    if (to_host) {
      dev->copy_to_host(slot.host_sums.get(), pixel_sums.get(),
                        3 * sizeof(double) * slot.pixel_count, s);
    }
    if (!to_host || mirror_film) {
      launch_accumulate_film(*dev, batch, pixel_sums.as<const double>(), pass.sample_count, film,
                             s);
    }
    dev->record(slot.done.get(), s);
    slot.busy = true;
  }

  // Waits for a slot's batch and adds its sums to the host film.
  void finish_batch(Slot& slot, const RenderPass& pass, Film* host_film, BackendStats& stats) {
    if (!slot.busy) return;
    dev->synchronize(slot.done.get());
    slot.busy = false;
    const double* sums = slot.host_sums.as<const double>();
    size_t p = 0;
    for (const Tile& t : slot.tiles) {
      for (uint32_t y = t.y0; y < t.y1; ++y)
        for (uint32_t x = t.x0; x < t.x1; ++x, ++p)
          if (host_film) host_film->add(x, y, &sums[3 * p], pass.sample_count);
      stats.tiles += 1;
      stats.pixels += t.pixel_count();
      stats.samples += uint64_t(t.pixel_count()) * pass.sample_count;
    }
    slot.holds_tiles = false;
  }

  void render_batches(const DeviceScene::RenderTicket& ticket, const RenderPass& pass,
                      TileSource& source, Film* host_film, BackendStats& stats) {
    const uint32_t width = host_film ? host_film->width() : film.width;
    const uint32_t height = host_film ? host_film->height() : film.height;
    // Two slots: while the device traces batch k, the host pulls batch
    // k + 1's tiles and then adds batch k - 1's pixels to the film.
    for (uint32_t k = 0;; ++k) {
      Slot& slot = slots[k % 2];
      Slot& previous = slots[(k + 1) % 2];
      finish_batch(slot, pass, host_film, stats);  // two batches ago: long done
      if (!pull_batch(source, slot, width, height)) break;
      if (!buffers_fit(slot)) {
        finish_batch(previous, pass, host_film, stats);  // buffers are about to move
        reserve(uint32_t(slot.tiles.size()), slot.pixel_count);
      }
      enqueue_batch(ticket, pass, slot, host_film != nullptr);
      finish_batch(previous, pass, host_film, stats);
    }
    for (Slot& s : slots)
      finish_batch(s, pass, host_film, stats);
  }

  BackendStats render(const RenderPass& pass, TileSource& source, Film* host_film) {
    const auto start = std::chrono::steady_clock::now();
    BackendStats stats;
    stats.commit_bytes = commit_bytes_since_render;
    commit_bytes_since_render = 0;
    if (pass.sample_count == 0) return stats;
    const DeviceStream s = stream.get();
    const DeviceScene::RenderTicket ticket = scene.begin_render(s);
    bool ended = false;
    try {
      dev->zero(ray_count.get(), sizeof(unsigned long long), s);
      // The mirror starts over with the host film's accumulation.
      if (host_film && mirror_film &&
          (pass.sample_begin == 0 || film.width != host_film->width() ||
           film.height != host_film->height())) {
        reset_film(host_film->width(), host_film->height());
      }
      render_batches(ticket, pass, source, host_film, stats);
      scene.end_render(ticket, s);
      ended = true;
      dev->copy_to_host(host_ray_count.get(), ray_count.get(), sizeof(unsigned long long), s);
      dev->synchronize(s);
      stats.rays = *host_ray_count.as<const unsigned long long>();
      const DeviceScene::CommitTiming timing = scene.take_timing(ticket);
      stats.commit_copy_seconds = timing.copy_seconds;
      stats.commit_hidden_seconds = timing.hidden_seconds;
    } catch (const DeviceError& e) {
      throw DeviceRenderError(e, abandon(ticket, ended), stats);
    } catch (...) {
      abandon(ticket, ended);
      throw;
    }
    stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return stats;
  }

  // After a failure inside render(): releases the scene set, lets nothing
  // still queued write into buffers the next render reuses, and returns the
  // tiles whose sums did not reach the film. No slot stays busy.
  std::vector<Tile> abandon(const DeviceScene::RenderTicket& ticket, bool ended) noexcept {
    std::vector<Tile> unfinished;
    for (Slot& slot : slots) {
      if (slot.holds_tiles)
        unfinished.insert(unfinished.end(), slot.tiles.begin(), slot.tiles.end());
      slot.tiles.clear();
      slot.busy = slot.holds_tiles = false;
    }
    try {
      if (!ended) scene.end_render(ticket, stream.get());
    } catch (...) {
    }
    try {
      dev->synchronize(stream.get());
    } catch (...) {
    }
    return unfinished;
  }
};

CudaBackend::CudaBackend(CudaKernelVariant variant) {
  std::string reason;
  std::shared_ptr<DeviceOps> device = open_device(&reason);
  if (!device) throw InputError("CUDA backend: " + reason);
  impl_ = std::make_unique<Impl>(std::move(device), variant, LaunchLimits{});
}

CudaBackend::CudaBackend(std::shared_ptr<DeviceOps> device, CudaKernelVariant variant,
                         LaunchLimits limits) {
  if (!device) throw std::invalid_argument("CudaBackend: no device");
  impl_ = std::make_unique<Impl>(std::move(device), variant, limits);
}

CudaBackend::~CudaBackend() = default;

void CudaBackend::sync(const KernelScene& scene, const SceneDelta& delta) {
  check_bvh_present(scene, "cuda backend");
  impl_->commit_bytes_since_render += impl_->scene.commit(scene, delta);
  impl_->note_synced_camera(scene);
}

void CudaBackend::sync_from(const KernelScene& scene, const KernelChangeLog& log) {
  check_bvh_present(scene, "cuda backend");
  impl_->commit_bytes_since_render += impl_->scene.commit(scene, log);
  impl_->note_synced_camera(scene);
}

void CudaBackend::forget_synced() {
  impl_->scene.forget_generations();
}

bool CudaBackend::render_features(const FeaturePass& pass, PixelFeatures* out,
                                  const PassStop& /*stop: one launch*/) {
  Impl& m = *impl_;
  if (!m.scene.ready()) throw std::logic_error("cuda backend: render_features() before sync()");
  // The size the caller sized `out` for: the newest sync()'s camera.
  uint32_t width, height;
  {
    std::lock_guard<std::mutex> lock(m.camera_mutex);
    width = m.synced_width;
    height = m.synced_height;
  }
  const size_t n = size_t(width) * height;
  if (n == 0) return true;
  DeviceOps& dev = *m.dev;
  const DeviceStream s = m.stream.get();
  // Buffers first, before the scene is claimed.
  const size_t feature_bytes = n * sizeof(PixelFeatures);
  m.features.reserve(feature_bytes);
  m.host_features.reserve(feature_bytes);
  const size_t prev_bytes =
      pass.prev_object_to_world ? size_t(pass.prev_instance_count) * sizeof(Mat34) : 0;
  if (prev_bytes > 0) {
    m.prev_transforms.reserve(prev_bytes);
    m.host_prev_transforms.reserve(prev_bytes);
  }
  // The kernel's film is the claimed set's camera, which a sync() on
  // another thread since the size was read would have changed: refused
  // rather than computed for one size and copied out for another.
  const DeviceScene::RenderTicket ticket = m.scene.begin_render(s);
  if (ticket.width != width || ticket.height != height) {
    m.abandon(ticket, false);
    throw std::logic_error("cuda backend: a sync() with a " + std::to_string(ticket.width) + "x" +
                           std::to_string(ticket.height) +
                           " camera ran during render_features() for " + std::to_string(width) +
                           "x" + std::to_string(height));
  }
  try {
    // The pass points at host transforms: the kernel reads a device copy.
    FeaturePass device_pass = pass;
    if (prev_bytes > 0) {
      std::memcpy(m.host_prev_transforms.get(), pass.prev_object_to_world, prev_bytes);
      dev.copy_to_device(m.prev_transforms.get(), m.host_prev_transforms.get(), prev_bytes, s);
      device_pass.prev_object_to_world = m.prev_transforms.as<const Mat34>();
    } else {
      device_pass.prev_object_to_world = nullptr;
      device_pass.prev_instance_count = 0;
    }
    launch_features(dev, ticket.view, device_pass, width, height, m.features.as<PixelFeatures>(),
                    s);
  } catch (...) {
    m.abandon(ticket, false);
    throw;
  }
  m.scene.end_render(ticket, s);
  dev.copy_to_host(m.host_features.get(), m.features.get(), feature_bytes, s);
  // Also orders the next call's transform copy after this kernel's reads.
  dev.synchronize(s);
  std::memcpy(out, m.host_features.get(), feature_bytes);
  return true;
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
  return impl_->dev->name();
}
uint64_t CudaBackend::last_commit_bytes() const {
  return impl_->scene.last_commit_bytes();
}
uint64_t CudaBackend::scene_device_bytes() const {
  return impl_->scene.device_bytes();
}
std::vector<std::vector<uint8_t>> CudaBackend::read_back_scene(uint32_t set) {
  return impl_->scene.read_back(set);
}
uint32_t CudaBackend::newest_scene_set() const {
  return impl_->scene.newest_set();
}

void CudaBackend::reset_device_film(uint32_t width, uint32_t height) {
  impl_->dev->synchronize(impl_->stream.get());
  impl_->reset_film(width, height);
}

void CudaBackend::set_device_image(bool on) {
  impl_->mirror_film = on;
  if (!on) impl_->film = DeviceFilmView{};
}

const void* CudaBackend::device_image_linear() {
  Impl& m = *impl_;
  if (!m.mirror_film || m.film.width == 0)
    throw std::logic_error("cuda backend: no device image (set_device_image, then render)");
  m.presented.reserve(size_t(m.film.width) * m.film.height * 3 * sizeof(float));
  launch_resolve_film(*m.dev, m.film, m.presented.as<float>(), m.stream.get());
  m.dev->synchronize(m.stream.get());
  return m.presented.get();
}

const void* CudaBackend::device_image_srgb8(float exposure_stops, ToneMap curve) {
  Impl& m = *impl_;
  if (!m.mirror_film || m.film.width == 0)
    throw std::logic_error("cuda backend: no device image (set_device_image, then render)");
  m.presented.reserve(size_t(m.film.width) * m.film.height * 3);
  launch_tone_map_film(*m.dev, m.film, std::exp2(exposure_stops), uint32_t(curve),
                       m.presented.as<uint8_t>(), m.stream.get());
  m.dev->synchronize(m.stream.get());
  return m.presented.get();
}

BackendStats CudaBackend::render_to_device_film(const RenderPass& pass, TileSource& tiles) {
  if (impl_->film.width == 0) throw std::logic_error("cuda backend: reset_device_film() first");
  return impl_->render(pass, tiles, nullptr);
}

ImageRGB CudaBackend::resolve_device_film() {
  Impl& m = *impl_;
  const DeviceFilmView& f = m.film;
  ImageRGB image(f.width, f.height);
  DeviceBuffer rgb(*m.dev, DeviceBuffer::kDevice), landing(*m.dev, DeviceBuffer::kPinned);
  rgb.allocate(image.rgb.size() * sizeof(float));
  landing.allocate(image.rgb.size() * sizeof(float));
  launch_resolve_film(*m.dev, f, rgb.as<float>(), m.stream.get());
  m.dev->copy_to_host(landing.get(), rgb.get(), image.rgb.size() * sizeof(float), m.stream.get());
  m.dev->synchronize(m.stream.get());
  if (!image.rgb.empty())
    std::memcpy(image.rgb.data(), landing.get(), image.rgb.size() * sizeof(float));
  return image;
}

std::vector<uint8_t> CudaBackend::tone_map_device_film(float exposure_stops, ToneMap curve) {
  Impl& m = *impl_;
  const DeviceFilmView& f = m.film;
  std::vector<uint8_t> out(3 * size_t(f.width) * f.height);
  DeviceBuffer rgb8(*m.dev, DeviceBuffer::kDevice), landing(*m.dev, DeviceBuffer::kPinned);
  rgb8.allocate(out.size());
  landing.allocate(out.size());
  launch_tone_map_film(*m.dev, f, std::exp2(exposure_stops), uint32_t(curve), rgb8.as<uint8_t>(),
                       m.stream.get());
  m.dev->copy_to_host(landing.get(), rgb8.get(), out.size(), m.stream.get());
  m.dev->synchronize(m.stream.get());
  if (!out.empty()) std::memcpy(out.data(), landing.get(), out.size());
  return out;
}

std::vector<Hit> CudaBackend::trace_rays(const std::vector<Ray>& rays,
                                         const std::vector<uint32_t>& alpha_keys, bool any_hit) {
  Impl& m = *impl_;
  if (!m.scene.ready()) throw std::logic_error("cuda backend: trace_rays() before sync()");
  if (!alpha_keys.empty() && alpha_keys.size() != rays.size())
    throw std::invalid_argument("cuda backend: one alpha key per ray, or none");
  const size_t n = rays.size();
  std::vector<Hit> hits(n);
  if (n == 0) return hits;
  DeviceOps& dev = *m.dev;
  const DeviceStream s = m.stream.get();
  const size_t ray_bytes = n * sizeof(Ray), key_bytes = alpha_keys.size() * sizeof(uint32_t),
               hit_bytes = n * sizeof(Hit);
  // The previous call's work is done (it synchronised), so growing a buffer
  // here waits for nothing of ours; the buffers are kept for the next call.
  m.query_rays.reserve(ray_bytes);
  m.query_hits.reserve(hit_bytes);
  m.query_counter.reserve(sizeof(uint32_t));
  m.query_staging.reserve(std::max(ray_bytes + key_bytes, hit_bytes));
  if (key_bytes) m.query_keys.reserve(key_bytes);
  std::memcpy(m.query_staging.get(), rays.data(), ray_bytes);
  dev.copy_to_device(m.query_rays.get(), m.query_staging.get(), ray_bytes, s);
  if (key_bytes) {
    std::memcpy(m.query_staging.as<uint8_t>() + ray_bytes, alpha_keys.data(), key_bytes);
    dev.copy_to_device(m.query_keys.get(), m.query_staging.as<uint8_t>() + ray_bytes, key_bytes, s);
  }
  dev.zero(m.query_counter.get(), sizeof(uint32_t), s);
  const DeviceScene::RenderTicket ticket = m.scene.begin_render(s);
  try {
    launch_trace_rays(dev, ticket.view, m.query_rays.as<const Ray>(),
                      key_bytes ? m.query_keys.as<const uint32_t>() : nullptr, uint32_t(n), any_hit,
                      m.query_hits.as<Hit>(), m.query_counter.as<uint32_t>(), s);
  } catch (...) {
    m.abandon(ticket, false);
    throw;
  }
  m.scene.end_render(ticket, s);
  // The rays were read before the hits are written back (stream order), so
  // the staging buffer can take the hits.
  dev.copy_to_host(m.query_staging.get(), m.query_hits.get(), hit_bytes, s);
  dev.synchronize(s);
  std::memcpy(hits.data(), m.query_staging.get(), hit_bytes);
  return hits;
}

}  // namespace tandem
