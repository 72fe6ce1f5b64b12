// The simulated device's build of megakernel.cu and ray_query.cu: the same
// source compiled by the C++ compiler with the GPU's branches on
// (TANDEM_EMULATED_GPU, core/kernel/defines.h), run by the emulated grid
// (emulated_grid.h). Nothing else may come before the define.
#define TANDEM_EMULATED_GPU 1

#include "backends/cuda/megakernel.cu"
#include "backends/cuda/ray_query.cu"
