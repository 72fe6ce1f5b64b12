// The simulated device's build of wavefront.cu (see emulated_megakernel.cpp).
#define TANDEM_EMULATED_GPU 1

#include "backends/cuda/wavefront.cu"
