#include "tracer/core_tracer.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <optional>
#include <stdexcept>
#include <thread>

#include "core/util/activity.h"
#include "core/util/errors.h"

namespace tandem {

namespace {

using Clock = std::chrono::steady_clock;
double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

// Settings that change what a pixel converges to (or which samples it gets).
bool same_image(const TracerSettings& a, const TracerSettings& b) {
  return a.render == b.render;
}

}  // namespace

uint64_t FrameMetrics::rays() const {
  uint64_t r = 0;
  for (const BackendFrameMetrics& b : backends)
    r += b.rays;
  return r;
}

uint64_t FrameMetrics::samples() const {
  uint64_t s = 0;
  for (const BackendFrameMetrics& b : backends)
    s += b.samples;
  return s;
}

CoreTracer::CoreTracer(std::vector<std::unique_ptr<Backend>> backends, TracerSettings settings)
    : backends_(std::move(backends)), settings_(settings), scheduler_(settings.scheduler) {
  if (backends_.empty()) throw InputError("core tracer: no backend to render with");
  probe_rate_.assign(backends_.size(), 0.0);
  refresh_traits();
  // Only at the start: a BVH built from some later frame on would need a
  // full build, and backends only ever lose the need (a GPU falling back).
  // Every backend traces the layout kd.bvh.layout names, so refit frames
  // keep only that one.
  SceneSyncSettings sync;
  sync.bvh = bvh_needed();
  sync.accel.refit_unused_layout = false;
  sync.accel.layout = bvh_layout();
  // The wide layout is chosen only when the host's loops alone trace it:
  // deforming meshes can then be refit in the binary layout alone.
  sync.accel.deforming_binary_only = true;
  scene_sync_ = std::make_unique<SceneSync>(sync);
}

bool CoreTracer::bvh_needed() const {
  for (const BackendTraits& t : traits_) {
    if (t.needs_bvh) return true;
  }
  return false;
}

KBvhLayout CoreTracer::bvh_layout() const {
  bool any = false, all_wide = true;
  for (const BackendTraits& t : traits_) {
    if (!t.needs_bvh) continue;
    any = true;
    all_wide = all_wide && t.bvh_layout == kBvhLayoutWide;
  }
  return any && all_wide ? kBvhLayoutWide : kBvhLayoutBinary;
}

// While no backend traces Tandem's BVH (the GPU that needed it fell back to
// Embree), nobody reads it: SceneSync leaves it alone until a backend needs
// it again. The layout follows the backends that trace it.
const SceneSyncUpdate& CoreTracer::update_scene(Scene& scene, const RenderSettings& settings) {
  const bool needed = bvh_needed();
  scene_sync_->set_bvh_needed(needed);
  if (needed) scene_sync_->set_bvh_layout(bvh_layout());
  return scene_sync_->update(scene, settings);
}

// Called every frame, also when nothing changed: a backend with two copies
// of the scene learns here which one the next render reads.
void CoreTracer::sync_backend(size_t b) {
  backends_[b]->sync_from(scene_sync_->kernel_scene(), scene_sync_->change_log());
}

void CoreTracer::resync_backend(size_t b) {
  backends_[b]->forget_synced();
  sync_backend(b);
}

void CoreTracer::refresh_traits() {
  std::vector<BackendTraits> now;
  for (const auto& b : backends_)
    now.push_back(b->traits());
  if (now == traits_) return;
  traits_ = std::move(now);
  std::vector<size_t> host;
  for (size_t i = 0; i < traits_.size(); ++i) {
    if (traits_[i].uses_host_cores) host.push_back(i);
  }
  if (host != host_core_backends_) {
    // A new set of backends competes for the cores (a GPU fell back to the
    // CPU): time them alone again.
    host_core_backends_ = std::move(host);
    probe_ = 0;
    frames_since_probe_ = 0;
    std::fill(probe_rate_.begin(), probe_rate_.end(), 0.0);
  }
}

CoreTracer::~CoreTracer() {
  for (std::thread& th : flight_.threads)
    th.join();
}

void CoreTracer::set_settings(const TracerSettings& settings) {
  // The backends read the film and the scheduler while a frame is in
  // flight: changes wait for the next begin_frame().
  if (in_flight_) {
    pending_settings_ = settings;
    return;
  }
  apply_settings(settings);
}

void CoreTracer::apply_settings(const TracerSettings& settings) {
  if (!same_image(settings, settings_)) reset_pending_ = true;
  if (settings.render.width != settings_.render.width ||
      settings.render.height != settings_.render.height ||
      settings.tile_size != settings_.tile_size) {
    grid_stale_ = true;
  }
  settings_ = settings;
  scheduler_.set_settings(settings.scheduler);
}

bool CoreTracer::render_features(MotionHistory& motion, std::vector<PixelFeatures>& out,
                                 const PassStop& stop) {
  const KernelData kd = scene_sync_->view();
  out.resize(size_t(kd.constants.camera.width) * kd.constants.camera.height);
  const FeaturePass pass = motion.advance(kd);
  for (const std::unique_ptr<Backend>& backend : backends_)
    if (backend->render_features(pass, out.data(), stop)) return true;
  return false;
}

const FrameMetrics& CoreTracer::render_frame(Scene& scene) {
  begin_frame(scene);
  return end_frame();
}

const FrameMetrics& CoreTracer::render_frame(Scene& scene,
                                             const std::function<void(Scene&)>& advance_to_next) {
  begin_frame(scene);
  if (advance_to_next) {
    try {
      advance_to_next(scene);
      prepare_next_frame(scene);
    } catch (...) {
      end_frame();  // the render threads must be joined before anything else
      throw;
    }
  }
  return end_frame();
}

void CoreTracer::begin_frame(Scene& scene) {
  if (in_flight_)
    throw std::logic_error("CoreTracer::begin_frame: the previous frame was not ended");
  if (pending_settings_) {
    apply_settings(*pending_settings_);
    pending_settings_.reset();
  }
  frame_start_ = Clock::now();
  FrameMetrics& m = metrics_;
  m = FrameMetrics{};
  m.frame = frame_++;

  refresh_traits();

  // SyncScene (the compiler also notices changed render settings) and
  // UpdateAccStruc; prepare_next_frame() may have done most of it already,
  // and then this update holds only the edits made since.
  const SceneSyncUpdate& up = update_scene(scene, settings_.render);
  m.sync_scene_seconds = up.compile_seconds;
  m.update_accstruc_seconds = up.accstruc_seconds;
  if (prepared_) {
    m.sync_scene_seconds += prepared_sync_seconds_;
    m.update_accstruc_seconds += prepared_accstruc_seconds_;
    m.overlapped_prepare = true;
    prepared_ = false;
  }
  const uint64_t previous_frame = frame_generation_;
  const SceneDelta changes = scene_sync_->changes_since(previous_frame);
  frame_generation_ = scene_sync_->generation();
  m.delta_bytes = changes.any() ? changes.bytes(scene_sync_->kernel_scene()) : 0;

  // SyncAccStruc: each backend commits what changed since it last did (the
  // CUDA backend queues the upload on its copy stream and returns).
  // Backends that prepare_next_frame() synced already get only the late
  // edits.
  {
    const ScopedActivity activity("copying the scene of " + scene.source_name() +
                                  " to the backends");
    const auto t = Clock::now();
    for (size_t b = 0; b < backends_.size(); ++b)
      sync_backend(b);
    m.overlapped_commit = committed_ahead_;
    committed_ahead_ = false;
    m.sync_accstruc_seconds = seconds_since(t) + prepared_commit_seconds_;
    prepared_commit_seconds_ = 0.0;
  }

  if (changes.any()) reset_pending_ = true;
  if (grid_stale_) {
    film_.resize(settings_.render.width, settings_.render.height);
    scheduler_.reset(
        make_tile_grid(settings_.render.width, settings_.render.height, settings_.tile_size),
        backends_.size());
    grid_stale_ = false;
    reset_pending_ = true;
  }
  if (reset_pending_) {
    film_.clear();
    accumulated_spp_ = 0;
    m.accumulation_reset = true;
    reset_pending_ = false;
  }
  choose_host_core_backends();
  launch_render();
}

namespace {
// Frames between re-checks of which host-core backend is fastest, and how
// many frames alone each of them gets per check (alternating).
constexpr uint64_t kHostCoreReprobeFrames = 240;
constexpr size_t kHostCoreProbeRounds = 2;
}  // namespace

void CoreTracer::choose_host_core_backends() {
  std::vector<bool> enabled(backends_.size(), true);
  const size_t n = host_core_backends_.size();
  const bool exclusive =
      settings_.exclusive_host_cores && settings_.scheduler.forced_split < 0.0f && n >= 2;
  if (exclusive && frames_since_probe_ >= kHostCoreReprobeFrames) {
    probe_ = 0;
    frames_since_probe_ = 0;
    std::fill(probe_rate_.begin(), probe_rate_.end(), 0.0);
  }
  // Frame 0 warms every backend up (thread pools, caches) with the usual
  // split; then each host-core backend renders one frame alone.
  if (exclusive && metrics_.frame > 0) {
    for (size_t i : host_core_backends_)
      enabled[i] = false;
    if (probe_ < kHostCoreProbeRounds * n) {
      enabled[host_core_backends_[probe_ % n]] = true;
    } else {
      size_t best = host_core_backends_[0];
      for (size_t i : host_core_backends_) {
        if (probe_rate_[i] > probe_rate_[best]) best = i;
      }
      enabled[best] = true;
    }
  }
  scheduler_.set_enabled(enabled);
}

void CoreTracer::record_host_core_probe() {
  ++frames_since_probe_;
  const size_t n = host_core_backends_.size();
  if (metrics_.frame == 0 || probe_ >= kHostCoreProbeRounds * n) return;
  const size_t b = host_core_backends_[probe_ % n];
  const BackendStats& st = flight_.stats[b];
  // The best of the rounds: other load on the machine only ever slows a
  // probe down.
  if (st.seconds > 0.0) probe_rate_[b] = std::max(probe_rate_[b], double(st.samples) / st.seconds);
  ++probe_;
}

void CoreTracer::launch_render() {
  Flight& f = flight_;
  f.pass = RenderPass{};
  f.pass.sample_begin = accumulated_spp_;
  f.pass.sample_count = std::max(settings_.samples_per_frame, 1u);
  f.tile_seconds.assign(scheduler_.tile_count(), -1.0);
  f.pass.tile_seconds = f.tile_seconds.data();
  f.pass.host_scene_may_change = true;
  for (const BackendTraits& tr : traits_)
    f.pass.host_scene_may_change =
        f.pass.host_scene_may_change && !tr.reads_host_scene_while_rendering;
  f.cancelled = false;
  f.done = 0;
  f.sources = scheduler_.begin_frame();
  f.cancellable.clear();
  for (TileSource*& source : f.sources) {
    f.cancellable.push_back(std::make_unique<CancellableTiles>(*source, f.cancelled));
    source = f.cancellable.back().get();
  }
  const size_t n = backends_.size();
  f.stats.assign(n, BackendStats{});
  f.errors.assign(n, nullptr);
  f.claimed.assign(n, false);
  f.start = Clock::now();
  // Every backend renders on its own thread (CPU backends fan out further
  // through TBB; the CUDA backend mostly waits on its stream), so the caller
  // is free to prepare the next frame's Scene meanwhile.
  f.threads.clear();
  for (size_t b = 0; b < n; ++b) {
    f.threads.emplace_back([this, b] {
      auto claim = [this, b] {
        std::lock_guard<std::mutex> lock(flight_.claim_mutex);
        flight_.claimed[b] = true;
        flight_.claim_cv.notify_all();
      };
      RenderPass pass = flight_.pass;
      if (traits_[b].syncs_while_rendering) pass.scene_claimed = claim;
      try {
        flight_.stats[b] = backends_[b]->render(pass, *flight_.sources[b], film_);
      } catch (...) {
        flight_.errors[b] = std::current_exception();
      }
      claim();  // also when the backend never got to claim its scene
      std::lock_guard<std::mutex> lock(flight_.done_mutex);
      ++flight_.done;
      flight_.done_cv.notify_all();
    });
  }
  in_flight_ = true;
}

void CoreTracer::sync_scene(Scene& scene) {
  if (in_flight_ || prepared_)
    throw std::logic_error("CoreTracer::sync_scene: a frame is in flight or prepared");
  if (pending_settings_) {
    apply_settings(*pending_settings_);
    pending_settings_.reset();
  }
  update_scene(scene, settings_.render);
  const bool changed = scene_sync_->changes_since(frame_generation_).any();
  frame_generation_ = scene_sync_->generation();
  const ScopedActivity activity("copying the scene of " + scene.source_name() + " to the backends");
  for (size_t b = 0; b < backends_.size(); ++b)
    sync_backend(b);
  if (changed) reset_pending_ = true;
}

bool CoreTracer::prepare_next_frame(Scene& scene) {
  if (!in_flight_) throw std::logic_error("CoreTracer::prepare_next_frame: no frame in flight");
  if (prepared_) return true;
  for (const BackendTraits& t : traits_) {
    if (t.reads_host_scene_while_rendering) return false;
  }
  // The settings the next frame will use (a pending change applies then).
  const RenderSettings& next = pending_settings_ ? pending_settings_->render : settings_.render;
  const ScopedActivity activity("preparing the next frame of " + scene.source_name());
  const SceneSyncUpdate& up = update_scene(scene, next);
  prepared_sync_seconds_ = up.compile_seconds;
  prepared_accstruc_seconds_ = up.accstruc_seconds;

  // SyncAccStruc ahead, for backends that commit into a copy this frame's
  // render does not read: once each render holds its scene, its backend may
  // receive the next frame.
  const auto t = Clock::now();
  for (size_t b = 0; b < backends_.size(); ++b) {
    if (!traits_[b].syncs_while_rendering) continue;
    {
      std::unique_lock<std::mutex> lock(flight_.claim_mutex);
      flight_.claim_cv.wait(lock, [&] { return bool(flight_.claimed[b]); });
    }
    // A backend whose render failed, or that fell back to the CPU, is
    // synced by the next begin_frame() instead.
    if (flight_.errors[b] || !backends_[b]->traits().syncs_while_rendering) continue;
    sync_backend(b);
    committed_ahead_ = true;
  }
  prepared_commit_seconds_ = seconds_since(t);
  prepared_ = true;
  return true;
}

void CoreTracer::complete_incomplete_renders() {
  Flight& f = flight_;
  for (size_t b = 0; b < backends_.size(); ++b) {
    if (!f.errors[b]) continue;
    try {
      std::rethrow_exception(f.errors[b]);
    } catch (const RenderIncomplete& e) {
      // The backend stopped part-way and switched to the CPU; nothing
      // renders now, so it may read the host scene (which holds the next
      // frame's scene if prepare_next_frame() ran: this frame shows that).
      resync_backend(b);
      committed_ahead_ = true;  // it has all the next frame needs
      ResumedTiles tiles(e.unfinished(), *f.sources[b]);
      RenderPass pass = f.pass;
      pass.host_scene_may_change = false;
      BackendStats stats = backends_[b]->render(pass, tiles, film_);
      stats += e.finished();
      f.stats[b] = stats;
      f.errors[b] = nullptr;
      metrics_.backends[b].completed_after_failure = true;
    } catch (...) {  // other failures are the caller's (end_frame rethrows)
    }
  }
}

bool CoreTracer::wait_rendered(double seconds) {
  if (!in_flight_) throw std::logic_error("CoreTracer::wait_rendered: no frame in flight");
  Flight& f = flight_;
  std::unique_lock<std::mutex> lock(f.done_mutex);
  return f.done_cv.wait_for(lock, std::chrono::duration<double>(std::max(seconds, 0.0)),
                            [&] { return f.done == f.threads.size(); });
}

void CoreTracer::cancel_frame() {
  if (!in_flight_) throw std::logic_error("CoreTracer::cancel_frame: no frame in flight");
  flight_.cancelled = true;
}

const FrameMetrics& CoreTracer::end_frame() {
  if (!in_flight_) throw std::logic_error("CoreTracer::end_frame: no frame in flight");
  Flight& f = flight_;
  for (std::thread& th : f.threads)
    th.join();
  f.threads.clear();
  in_flight_ = false;
  FrameMetrics& m = metrics_;
  m.render_seconds = seconds_since(f.start);
  const size_t n = backends_.size();
  m.backends.assign(n, BackendFrameMetrics{});
  m.cancelled = f.cancelled;
  // (In a cancelled frame this completes only the tiles a failed backend
  // had taken: its source hands out no more.)
  complete_incomplete_renders();
  std::vector<double> backend_seconds(n);
  for (size_t b = 0; b < n; ++b)
    backend_seconds[b] = f.stats[b].seconds;
  const std::vector<uint32_t> stolen = scheduler_.stolen_counts();
  for (size_t b = 0; b < n; ++b) {
    BackendFrameMetrics& bm = m.backends[b];
    bm.name = backends_[b]->name();
    bm.failure = backends_[b]->failure();
    bm.enabled = scheduler_.enabled(b);
    bm.tiles = f.stats[b].tiles;
    bm.stolen = stolen[b];
    bm.planned_share = scheduler_.planned_shares()[b];
    bm.seconds = f.stats[b].seconds;
    bm.idle_seconds = std::max(0.0, m.render_seconds - f.stats[b].seconds);
    bm.rays = f.stats[b].rays;
    bm.samples = f.stats[b].samples;
    bm.commit_bytes = f.stats[b].commit_bytes;
    bm.commit_copy_seconds = f.stats[b].commit_copy_seconds;
    bm.commit_hidden_seconds = f.stats[b].commit_hidden_seconds;
  }
  for (const std::exception_ptr& e : f.errors) {
    if (e) {
      // The frame's samples are incomplete: start over next frame.
      reset_pending_ = true;
      std::rethrow_exception(e);
    }
  }
  if (m.cancelled) {
    // Some tiles have this frame's samples, others not: none keeps them.
    film_.clear();
    accumulated_spp_ = 0;
    reset_pending_ = true;
    m.accumulated_spp = 0;
    m.total_seconds = seconds_since(frame_start_);
    return m;
  }
  scheduler_.end_frame(backend_seconds, f.tile_seconds);
  if (settings_.exclusive_host_cores && settings_.scheduler.forced_split < 0.0f &&
      host_core_backends_.size() >= 2) {
    record_host_core_probe();
  }
  accumulated_spp_ += f.pass.sample_count;
  m.accumulated_spp = accumulated_spp_;
  m.total_seconds = seconds_since(frame_start_);
  return m;
}

}  // namespace tandem
