// The simulated device's build of film_kernels.cu and svgf_kernels.cu (see
// emulated_megakernel.cpp).
#define TANDEM_EMULATED_GPU 1

#include "backends/cuda/film_kernels.cu"
#include "backends/cuda/svgf_kernels.cu"
