// `tandem bench --gpu`: the CUDA backend measured on the device (built only
// with the CUDA backend). The same ray sets the Embree comparison casts,
// traced by the GPU with both BVH layouts beside Embree on the CPU; and path
// tracing frames with both kernel variants and both layouts.
#pragma once

#include <string>
#include <vector>

#include "app/bench/bench_accstruc.h"
#include "app/bench/bench_gpu_report.h"
#include "backends/kernel_variant.h"
#include "core/world/kernel_scene.h"
#include "core/world/scene.h"

namespace tandem {

struct GpuBenchConfig {
  uint32_t frame_width = 1920, frame_height = 1080;
  uint32_t spp = 1, max_depth = 4;
  uint32_t warmup_frames = 2, timed_frames = 10;
  std::vector<CudaKernelVariant> kernels = {CudaKernelVariant::kMegakernel,
                                            CudaKernelVariant::kWavefront};
};

// `ks` is the scene compiled for the ray sets (`delta` its first compile),
// `embree` synced to it, `rays` cast from it at ray_width x ray_height.
// `scene` is compiled again at the frame resolution for path tracing (with
// a camera of that aspect when `frame_camera_from_bounds`). Throws
// InputError when no CUDA device is usable.
GpuBenchFigures measure_gpu_bench(Scene& scene, const std::string& scene_name,
                                  const CpuBackend& embree, const BenchRays& rays,
                                  const RenderSettings& ray_settings, int embree_threads,
                                  bool frame_camera_from_bounds, const GpuBenchConfig& config);

}  // namespace tandem
