// The inside of tandem::Renderer, shared by its translation units
// (renderer.cpp: scene, settings and frames; renderer_image.cpp: the
// images): the engine objects behind the API, and the one place engine
// exceptions become tandem::Error.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <new>
#include <optional>
#include <stdexcept>
#include <utility>

#include <tbb/global_control.h>

#include <thread>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/type_ptr.hpp>

#include "api/api_convert.h"
#include "api/api_ids.h"
#include "api/tandem/tandem.h"
#include "backends/backend_factory.h"
#include "backends/cuda/cuda_backend.h"
#include "core/image/image.h"
#include "core/render/denoise_blend.h"
#include "core/render/device_error.h"
#include "core/render/temporal_denoiser.h"
#include "core/util/errors.h"
#include "core/util/log.h"
#include "core/world/motion_history.h"
#include "core/world/scene_ranges.h"
#include "scenes/gltf_loader.h"
#include "scenes/scene_loader.h"
#include "tracer/core_tracer.h"

namespace tandem {
inline namespace embed_v0 {

using api_detail::invalid;

// Runs `body`, translating what the engine throws into the API's one
// exception type. `input_error_kind` says what an InputError means there:
// a bad file (loading, writing) or an unusable device (creating backends,
// rendering).
template <class F>
inline auto guarded(F&& body, Error::Kind input_error_kind = Error::Kind::kFile)
    -> decltype(body()) {
  try {
    return body();
  } catch (const Error&) {
    throw;
  } catch (const std::bad_alloc&) {
    throw;
  } catch (const DeviceError& e) {
    throw Error(Error::Kind::kDevice, e.what());
  } catch (const InputError& e) {
    throw Error(input_error_kind, e.what());
  } catch (const UsageError& e) {
    throw Error(Error::Kind::kInvalidArgument, e.what());
  } catch (const std::length_error& e) {  // e.g. a scene too large for the BVH
    throw Error(Error::Kind::kInvalidArgument, e.what());
  } catch (const std::logic_error& e) {
    throw Error(Error::Kind::kInvalidState, e.what());
  } catch (const std::exception& e) {
    throw Error(Error::Kind::kInternal, e.what());
  }
}

inline BackendKind to_backend_kind(BackendChoice choice) {
  switch (choice) {
    case BackendChoice::kCpu:
      return BackendKind::kCpu;
    case BackendChoice::kCuda:
      return BackendKind::kCuda;
    case BackendChoice::kHetero:
      return BackendKind::kHetero;
    case BackendChoice::kAuto:
      break;
  }
  return BackendKind::kAuto;
}

inline float aspect(const RendererOptions& o) {
  return float(o.width) / float(o.height);
}

// The CPU threads `o` allows: threads (0 = one per core) less the cores
// reserved for the host, at least 1.
inline uint32_t thread_budget(const RendererOptions& o) {
  const uint32_t cores = std::max(1u, std::thread::hardware_concurrency());
  const uint32_t threads = o.threads > 0 ? o.threads : cores;
  return threads > o.reserve_cores ? threads - o.reserve_cores : 1u;
}

struct Renderer::Impl {
  RendererOptions options;
  // TBB's process-wide limit while this renderer lives: every CPU stage of
  // the engine runs on TBB (the texture decoders read the same limit).
  std::optional<tbb::global_control> thread_limit;
  Scene scene;
  std::unique_ptr<CoreTracer> tracer;
  std::vector<std::string> last_backend_names;  // of the last completed frame
  // The denoiser (RendererOptions::denoise) and the feature pass.
  MotionHistory motion;
  std::vector<PixelFeatures> features;
  uint64_t features_frame = 0;  // frames + 1 of the frame `features` belong to; 0: none
  TemporalDenoiser denoiser;
  ImageRGB accumulated;  // the image after the previous frame, for its samples
  uint32_t accumulated_spp = 0;
  ImageRGB denoised;  // blended as image_denoised() returns it
  bool in_flight = false;
  bool image_valid = false;
  uint64_t frames = 0;
  // Ids to slots (api_ids.h). A removed instance's slot is hidden and kept
  // for the next instance of its mesh: per mesh slot, those free slots and
  // how many instances are alive.
  api_detail::IdTable mesh_ids, instance_ids, light_ids;
  std::vector<std::vector<uint32_t>> free_instance_slots;
  std::vector<uint32_t> mesh_instances_alive;
  uint32_t instances_alive = 0;
  std::vector<float> texture_peaks;  // per texture: its largest texel value (1 for 8-bit)

  // Ids for the scene as it is now (a new one: loaded, cleared).
  void reset_ids() {
    mesh_ids.reset(uint32_t(scene.mesh_count()));
    instance_ids.reset(uint32_t(scene.instances().size()));
    light_ids.reset(uint32_t(scene.lights().size()));
    free_instance_slots.assign(scene.mesh_count(), {});
    mesh_instances_alive.assign(scene.mesh_count(), 0);
    for (const Instance& inst : scene.instances()) {
      if (inst.mesh < mesh_instances_alive.size()) ++mesh_instances_alive[inst.mesh];
    }
    instances_alive = uint32_t(scene.instances().size());
    texture_peaks.assign(scene.textures().size(), 1.0f);  // a file's textures are 8-bit
  }

  void apply_thread_budget() {
    thread_limit.reset();
    const uint32_t budget = thread_budget(options);
    if (budget < std::max(1u, std::thread::hardware_concurrency()) || options.threads > 0)
      thread_limit.emplace(tbb::global_control::max_allowed_parallelism, budget);
  }

  TracerSettings tracer_settings() const {
    TracerSettings s;
    s.render.width = options.width;
    s.render.height = options.height;
    s.render.max_depth = options.max_depth;
    s.render.seed = options.seed;
    s.render.light_sampler = options.light_sampling == LightSampling::kPower
                                 ? tandem::LightSampler::kPower
                                 : tandem::LightSampler::kTree;
    s.samples_per_frame = options.samples_per_frame;
    return s;
  }

  std::string gpu_unused;  // why kAuto/kHetero run without a GPU; empty otherwise

  // A new tracer compiles the whole scene on its first frame.
  void create_tracer() {
    gpu_unused.clear();
    if (options.backend == BackendChoice::kAuto || options.backend == BackendChoice::kHetero) {
      std::string why;
      if (!cuda_device_available(&why)) gpu_unused = why.empty() ? "no usable GPU" : why;
    }
    tracer = guarded(
        [&] {
          std::vector<std::unique_ptr<Backend>> backends =
              create_backends(to_backend_kind(options.backend));
          // A device that is there but would not start (out of memory, a
          // driver fault) leaves kAuto/kHetero on the CPU too.
          const bool cuda = std::any_of(backends.begin(), backends.end(),
                                        [](const auto& b) { return b->name() == "cuda"; });
          if (!cuda && gpu_unused.empty() && options.backend != BackendChoice::kCpu)
            gpu_unused = "the CUDA backend failed to start";
          if (options.cuda_image) {
            // check_options: kCuda, so the one backend is the CUDA backend.
            auto* gpu = dynamic_cast<CudaBackend*>(backends.at(0).get());
            if (gpu == nullptr) throw std::logic_error("cuda_image: no CUDA backend");
            gpu->set_device_image(true);
          }
          return std::make_unique<CoreTracer>(std::move(backends), tracer_settings());
        },
        Error::Kind::kDevice);
    image_valid = false;
    last_backend_names.clear();
  }

  // After a frame: its features, the filter of its own samples, and the
  // blend with the accumulated image (the viewer's recipe).
  void denoise_frame(bool restarted) {
    const ImageRGB now = tracer->image();
    const uint32_t spp = tracer->accumulated_spp();
    if (restarted || now.width != accumulated.width || now.height != accumulated.height) {
      accumulated_spp = 0;
      denoiser.reset();
    }
    const bool have =
        guarded([&] { return tracer->render_features(motion, features); }, Error::Kind::kDevice);
    features_frame = have ? frames + 1 : 0;
    if (have) {
      const ImageRGB own = frame_samples(now, spp, accumulated, accumulated_spp);
      const ImageRGB filtered = denoiser.process(features, own);
      denoised = blend_images(filtered, now, accumulated_blend_weight(spp));
    } else {
      denoised = now;  // no feature pass (a GPU-only list): the image as it is
    }
    accumulated = now;
    accumulated_spp = spp;
  }

  void require_idle(const char* what) const {
    if (in_flight) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": not allowed while a frame is in flight");
    }
  }

  void require_image(const char* what) const {
    if (in_flight) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": the image is not ready while a frame is in flight");
    }
    if (!image_valid) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": no frame has been rendered yet");
    }
  }

  // The CUDA backend that mirrors the image (RendererOptions::cuda_image),
  // after the checks of require_image().
  CudaBackend& cuda_image_backend(const char* what) {
    require_image(what);
    if (!options.cuda_image) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": RendererOptions::cuda_image is off");
    }
    return dynamic_cast<CudaBackend&>(tracer->backend(0));
  }

  // The denoised image, after the checks of require_image().
  const ImageRGB& denoised_image(const char* what) const {
    require_image(what);
    if (!options.denoise) {
      throw Error(Error::Kind::kInvalidState,
                  std::string(what) + ": RendererOptions::denoise is off");
    }
    return denoised;
  }

  // The image `which` names: the accumulation resolved now, or the denoised one.
  ImageRGB frame_image(FrameImage which, const char* what) const {
    if (which == FrameImage::kDenoised) return denoised_image(what);
    require_image(what);
    return tracer->image();
  }

  // Without a camera from the caller or the file, one that frames the
  // scene as it is at the first frame (and stays, so that motion in the
  // scene does not move it).
  void place_camera() {
    if (scene.has_camera()) return;
    Camera c = frame_bounds_camera(scene.bounds(), 0.6911112f, aspect(options));
    // Bounds near the range Tandem traces can put the framing camera beyond
    // it: the default camera is better than a refusal.
    scene.set_camera(camera_problem(c).empty() ? c : Camera{});
  }
};

}  // namespace embed_v0
}  // namespace tandem
