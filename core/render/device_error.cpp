#include "core/render/device_error.h"

namespace tandem {

const char* device_fault_name(DeviceFault fault) {
  switch (fault) {
    case DeviceFault::kOutOfMemory:
      return "out of device memory";
    case DeviceFault::kLaunchFailure:
      return "kernel launch failure";
    case DeviceFault::kIllegalAddress:
      return "illegal memory access in a kernel";
    case DeviceFault::kDeviceLost:
      return "device lost";
    case DeviceFault::kOther:
      break;
  }
  return "device error";
}

}  // namespace tandem
