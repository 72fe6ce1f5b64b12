// TANDEM_KERNEL_ARRAYS turned into an indexable table, so the CUDA backend's
// device scene handles every kernel array with one loop instead of one
// hand-written block per array: adding an array to kernel_data.h adds its
// device buffer, its delta upload and its KernelData pointer automatically.
// Host-only code (no CUDA headers), so it is unit-tested without a GPU.
#pragma once

#include <cstddef>
#include <cstdint>

#include "core/world/kernel_scene.h"

namespace tandem {

enum KernelArrayId : uint32_t {
#define TANDEM_ARRAY_ID(T, name) kArray_##name,
  TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_ID)
#undef TANDEM_ARRAY_ID
      kKernelArrayCount
};

const char* kernel_array_name(uint32_t id);
size_t kernel_array_element_size(uint32_t id);
// Element count and bytes of the host vector for array `id`.
size_t kernel_array_host_count(const KernelScene& ks, uint32_t id);
const void* kernel_array_host_data(const KernelScene& ks, uint32_t id);
const ArrayChange& kernel_array_change(const SceneDelta& delta, uint32_t id);
// Points KernelData's entry for `id` at `data` (a device pointer on the GPU).
void set_kernel_array_view(KernelData& kd, uint32_t id, const void* data, uint32_t count);

}  // namespace tandem
