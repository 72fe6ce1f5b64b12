#include "backends/cuda/kernel_arrays.h"

namespace tandem {

const char* kernel_array_name(uint32_t id) {
  switch (id) {
#define TANDEM_ARRAY_NAME(T, name) \
  case kArray_##name:              \
    return #name;
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_NAME)
#undef TANDEM_ARRAY_NAME
  }
  return "?";
}

size_t kernel_array_element_size(uint32_t id) {
  switch (id) {
#define TANDEM_ARRAY_SIZE(T, name) \
  case kArray_##name:              \
    return sizeof(T);
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_SIZE)
#undef TANDEM_ARRAY_SIZE
  }
  return 0;
}

size_t kernel_array_host_count(const KernelScene& ks, uint32_t id) {
  switch (id) {
#define TANDEM_ARRAY_COUNT(T, name) \
  case kArray_##name:               \
    return ks.name.size();
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_COUNT)
#undef TANDEM_ARRAY_COUNT
  }
  return 0;
}

const void* kernel_array_host_data(const KernelScene& ks, uint32_t id) {
  switch (id) {
#define TANDEM_ARRAY_DATA(T, name) \
  case kArray_##name:              \
    return ks.name.data();
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_DATA)
#undef TANDEM_ARRAY_DATA
  }
  return nullptr;
}

const ArrayChange& kernel_array_change(const SceneDelta& delta, uint32_t id) {
  switch (id) {
#define TANDEM_ARRAY_CHANGE(T, name) \
  case kArray_##name:                \
    return delta.name;
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_CHANGE)
#undef TANDEM_ARRAY_CHANGE
  }
  static const ArrayChange none;
  return none;
}

void set_kernel_array_view(KernelData& kd, uint32_t id, const void* data, uint32_t count) {
  switch (id) {
#define TANDEM_ARRAY_VIEW(T, name)         \
  case kArray_##name:                      \
    kd.name = static_cast<const T*>(data); \
    kd.name##_count = count;               \
    return;
    TANDEM_KERNEL_ARRAYS(TANDEM_ARRAY_VIEW)
#undef TANDEM_ARRAY_VIEW
  }
}

}  // namespace tandem
