// The worker rank's loop: keep a copy of rank 0's kernel arrays, render the
// tile batches it sends with this machine's own backends, send back sums.
#include <chrono>
#include <cstdlib>
#include <mutex>
#include <new>
#include <thread>

#include "backends/mpi/mpi_channel.h"
#include "backends/mpi/mpi_cluster.h"
#include "backends/mpi/mpi_protocol.h"
#include "core/render/backend.h"
#include "core/render/film.h"
#include "core/util/cpu_time.h"

namespace tandem::mpi {

namespace {

using Clock = std::chrono::steady_clock;

// Hands out a batch's tiles to the local renderers and, between tiles,
// lets MPI move the previous batches' results (Open MPI progresses a large
// send only inside MPI calls, and the renderers make none).
class ProgressingTiles final : public TileSource {
 public:
  ProgressingTiles(const std::vector<Tile>& tiles, PendingSends& sends)
      : queue_(tiles), sends_(sends) {}
  bool next(Tile* tile) override {
    {
      std::lock_guard<std::mutex> lock(mutex_);
      sends_.progress();
    }
    return queue_.next(tile);
  }

 private:
  TileQueue queue_;
  PendingSends& sends_;
  std::mutex mutex_;
};

[[noreturn]] void inject(FaultKind kind, int me) {
  switch (kind) {
    case FaultKind::kThrow:
      throw std::runtime_error("injected failure in the renderer (TANDEM_MPI_FAULT=throw@" +
                               std::to_string(me) + ")");
    case FaultKind::kOom:
      throw std::bad_alloc();
    case FaultKind::kHang:
      for (;;)
        std::this_thread::sleep_for(std::chrono::seconds(1));
    default:
      std::fflush(stderr);
      std::_Exit(1);
  }
}

class Worker {
 public:
  Worker(std::vector<std::unique_ptr<Backend>> backends, Fault fault, double timeout)
      : backends_(std::move(backends)), fault_(fault), timeout_(timeout), me_(rank()) {}

  // Returns at rank 0's shutdown.
  void serve() {
    for (;;) {
      Message m = receive(0, 0.0, "", [this] { sends_.progress(); });
      WireReader r(m.bytes, "message from rank 0");
      switch (m.tag) {
        case kTagReset:
          scene_ = KernelScene{};
          cpu_mark_ = process_cpu_seconds();
          render_cpu_ = 0.0;
          break;
        case kTagSync: {
          // Counted as work like rendering (building the Embree scene is
          // part of a frame), not as the waiting that follows.
          const double cpu_start = process_cpu_seconds();
          const SceneDelta delta = decode_scene(r, scene_);
          for (auto& b : backends_)
            b->sync(scene_, delta);
          render_cpu_ += process_cpu_seconds() - cpu_start;
          break;
        }
        case kTagBatch:
          render(decode_batch(r));
          break;
        case kTagShutdown:
          sends_.drain(timeout_);
          return;
        default:
          r.fail("unknown message");
      }
    }
  }

 private:
  void render(const TileBatch& batch) {
    if (fault_.rank == me_ && fault_.kind != FaultKind::kNone && fault_.kind != FaultKind::kVersion)
      inject(fault_.kind, me_);
    if (film_.width() != batch.film_width || film_.height() != batch.film_height)
      film_.resize(batch.film_width, batch.film_height);
    uint32_t max_index = 0;
    for (const Tile& t : batch.tiles)
      max_index = std::max(max_index, t.index);
    tile_seconds_.assign(size_t(max_index) + 1, -1.0);
    RenderPass pass;
    pass.sample_begin = batch.sample_begin;
    pass.sample_count = batch.sample_count;
    pass.tile_seconds = tile_seconds_.data();
    ProgressingTiles tiles(batch.tiles, sends_);
    const auto start = Clock::now();
    const double cpu_start = process_cpu_seconds();
    BackendStats stats;
    if (backends_.size() == 1) {
      stats = render_on(*backends_[0], pass, tiles);
    } else {
      // Several local backends (a GPU and the CPU): each on its own thread
      // pulling from the same tiles, as the core tracer does.
      std::vector<BackendStats> each(backends_.size());
      std::vector<std::exception_ptr> errors(backends_.size());
      std::vector<std::thread> threads;
      for (size_t b = 0; b < backends_.size(); ++b) {
        threads.emplace_back([&, b] {
          try {
            each[b] = render_on(*backends_[b], pass, tiles);
          } catch (...) {
            errors[b] = std::current_exception();
          }
        });
      }
      for (std::thread& t : threads)
        t.join();
      for (auto& e : errors)
        if (e) std::rethrow_exception(e);
      for (const BackendStats& s : each)
        stats += s;
    }
    render_cpu_ += process_cpu_seconds() - cpu_start;
    BatchResult res;
    res.id = batch.id;
    res.busy_seconds = std::chrono::duration<double>(Clock::now() - start).count();
    res.rays = stats.rays;
    res.samples = stats.samples;
    res.tiles = batch.tiles;
    size_t sum_count = 0;
    for (const Tile& t : batch.tiles) {
      res.tile_seconds.push_back(tile_seconds_[t.index]);
      sum_count += size_t(t.pixel_count()) * 3;
    }
    // The sums go from the film into the message a row at a time (a tile's
    // row is contiguous in the film): one copy, no per-pixel packing.
    res.render_cpu_seconds = render_cpu_;
    res.cpu_seconds = process_cpu_seconds() - cpu_mark_;
    WireWriter w;
    encode_result_header(res, w, sum_count);
    for (const Tile& t : batch.tiles) {
      for (uint32_t y = t.y0; y < t.y1; ++y)
        w.put_bytes(film_.sum(t.x0, y), size_t(t.x1 - t.x0) * 3 * sizeof(double));
      film_.clear_rect(t.x0, t.y0, t.x1, t.y1);
    }
    sends_.start(0, kTagResult, std::move(w.bytes()));
  }

  // A GPU that fails part-way under `auto` hands its tiles to the CPU
  // (RenderIncomplete): finish them here, as the core tracer does on rank 0.
  BackendStats render_on(Backend& backend, const RenderPass& pass, TileSource& tiles) {
    try {
      return backend.render(pass, tiles, film_);
    } catch (const RenderIncomplete& e) {
      backend.sync(scene_, SceneDelta::everything());
      ResumedTiles rest(e.unfinished(), tiles);
      BackendStats stats = backend.render(pass, rest, film_);
      stats += e.finished();
      return stats;
    }
  }

  std::vector<std::unique_ptr<Backend>> backends_;
  Fault fault_;
  double timeout_;
  int me_;
  KernelScene scene_;
  Film film_;
  std::vector<double> tile_seconds_;
  PendingSends sends_;
  // Process CPU time at rank 0's last reset, and spent since inside the
  // backends' render() and sync() (reported with every result).
  double cpu_mark_ = process_cpu_seconds(), render_cpu_ = 0.0;
};

// Tells rank 0 why this worker cannot go on and waits for it to end the run
// (it prints the reason once, naming this rank). Should rank 0 not answer
// either, this rank says it itself and ends the run.
[[noreturn]] void report_failure(const std::string& reason, double timeout) {
  try {
    WireWriter w;
    w.put_string(reason);
    send(0, kTagError, w.bytes(), timeout);
    const auto start = Clock::now();
    Message m;
    while (std::chrono::duration<double>(Clock::now() - start).count() < timeout) {
      if (try_receive(0, &m) && m.tag == kTagShutdown) break;
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    }
  } catch (...) {
  }
  std::fprintf(stderr, "tandem: error: rank %d: %s\n", rank(), reason.c_str());
  abort_all(1);
}

}  // namespace

int serve_as_worker(const std::function<std::vector<std::unique_ptr<Backend>>()>& make_backends) {
  const double timeout = answer_timeout_seconds();
  const Fault fault = parse_fault(std::getenv("TANDEM_MPI_FAULT"));
  const int me = rank();
  std::string reason;
  try {
    std::vector<std::unique_ptr<Backend>> backends = make_backends();
    std::string names;
    bool needs_bvh = false;
    for (const auto& b : backends) {
      if (!names.empty()) names += '+';
      names += b->name();
      needs_bvh = needs_bvh || b->traits().needs_bvh;
    }
    WireWriter hello;
    hello.put(fault.rank == me && fault.kind == FaultKind::kVersion ? kProtocolVersion + 1
                                                                    : kProtocolVersion);
    hello.put_string(build_fingerprint());
    hello.put_string(names);
    hello.put(uint8_t(needs_bvh));
    send(0, kTagHello, hello.bytes(), timeout);
    Worker worker(std::move(backends), fault, timeout);
    worker.serve();
    finalize();
    return 0;
  } catch (const RankFailure&) {
    // Rank 0 itself stopped answering: nobody is left to tell.
    throw;
  } catch (const std::bad_alloc&) {
    reason = "out of memory";
  } catch (const std::exception& e) {
    reason = e.what();
  }
  report_failure(reason, timeout);
}

}  // namespace tandem::mpi
