// The figures of `tandem bench --gpu` and how they are shown: one table on
// stdout and the same numbers in the JSON report. Kept apart from the
// measuring code (bench_gpu.cpp, built only with the CUDA backend) so that
// both are built and tested everywhere, with made-up figures.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "app/json_writer.h"

namespace tandem {

// One ray set (camera, shadow or diffuse rays of the Embree comparison)
// traced by Embree on the CPU and by the GPU with each BVH layout.
struct GpuRayFigures {
  std::string kind;  // "camera", "shadow", "diffuse"
  bool any_hit = false;
  uint64_t rays = 0;
  double embree_mrays = 0.0;
  double gpu_binary_mrays = 0.0;
  double gpu_wide_mrays = 0.0;
};

// Path tracing frames with one kernel variant and one BVH layout.
struct GpuFrameFigures {
  std::string kernel;  // "megakernel", "wavefront"
  std::string layout;  // "binary", "wide"
  double ms_per_frame_median = 0.0;
  double samples_per_second = 0.0;
  double mrays_per_second = 0.0;
};

struct GpuBenchFigures {
  std::string device;
  std::string scene;
  int embree_threads = 0;
  uint32_t ray_width = 0, ray_height = 0;  // the image the ray sets were cast from
  uint32_t frame_width = 0, frame_height = 0, spp = 0, max_depth = 0;
  uint32_t timed_frames = 0, warmup_frames = 0;
  std::vector<GpuRayFigures> rays;
  std::vector<GpuFrameFigures> frames;
};

// The table `bench --gpu` prints.
std::string format_gpu_bench_table(const GpuBenchFigures& f);

// Adds the figures to a bench_report() object: "device", the render facts,
// "ray_sets" (one object per ray kind) and "path_tracing" (one object per
// kernel and layout), every figure the table shows.
void add_gpu_bench_json(JsonValue& report, const GpuBenchFigures& f);

}  // namespace tandem
