#include "backends/cuda/device_ops.h"

#include <cstdlib>
#include <utility>

#include "backends/cuda/device_faults.h"
#include "backends/cuda/sim_device.h"

#if TANDEM_HAVE_CUDA_DEVICE
#include "backends/cuda/cuda_device_ops.h"
#endif

namespace tandem {

DeviceStreamOwner& DeviceStreamOwner::operator=(DeviceStreamOwner&& o) noexcept {
  if (this != &o) {
    reset();
    ops_ = std::exchange(o.ops_, nullptr);
    stream_ = std::exchange(o.stream_, nullptr);
  }
  return *this;
}

void DeviceStreamOwner::reset() noexcept {
  if (stream_) {
    try {
      ops_->destroy_stream(stream_);
    } catch (...) {  // a failed device: nothing left to release
    }
  }
  stream_ = nullptr;
}

DeviceEventOwner& DeviceEventOwner::operator=(DeviceEventOwner&& o) noexcept {
  if (this != &o) {
    reset();
    ops_ = std::exchange(o.ops_, nullptr);
    event_ = std::exchange(o.event_, nullptr);
  }
  return *this;
}

void DeviceEventOwner::reset() noexcept {
  if (event_) {
    try {
      ops_->destroy_event(event_);
    } catch (...) {
    }
  }
  event_ = nullptr;
}

DeviceBuffer& DeviceBuffer::operator=(DeviceBuffer&& o) noexcept {
  if (this != &o) {
    reset();
    ops_ = std::exchange(o.ops_, nullptr);
    kind_ = o.kind_;
    ptr_ = std::exchange(o.ptr_, nullptr);
    bytes_ = std::exchange(o.bytes_, 0);
  }
  return *this;
}

void DeviceBuffer::allocate(size_t bytes) {
  reset();  // bytes_ is 0 from here until the allocation succeeded
  const size_t n = bytes ? bytes : 1;
  ptr_ = kind_ == kPinned ? ops_->alloc_pinned(n) : ops_->alloc(n);
  bytes_ = n;
}

void DeviceBuffer::reset() noexcept {
  if (ptr_) {
    try {
      if (kind_ == kPinned)
        ops_->free_pinned(ptr_);
      else
        ops_->free(ptr_);
    } catch (...) {
    }
  }
  ptr_ = nullptr;
  bytes_ = 0;
}

namespace {

bool simulated_device_requested() {
  const char* v = std::getenv("TANDEM_DEVICE");
  return v && std::string(v) == "sim";
}

}  // namespace

bool device_available(std::string* reason) {
  if (simulated_device_requested()) {
    if (reason) reason->clear();
    return true;
  }
#if TANDEM_HAVE_CUDA_DEVICE
  return cuda_query_device(reason);
#else
  if (reason)
    *reason =
        "this build of tandem has no CUDA backend (nvcc was not found when it was configured)";
  return false;
#endif
}

std::shared_ptr<DeviceOps> open_device(std::string* reason) {
  const char* fault = std::getenv("TANDEM_DEVICE_FAULT");
  const FaultSpec spec = parse_fault_spec(fault ? fault : "");
  std::shared_ptr<DeviceOps> device;
  if (simulated_device_requested()) {
    device = std::make_shared<SimDevice>();
  } else {
#if TANDEM_HAVE_CUDA_DEVICE
    device = make_cuda_device(reason);
#else
    device_available(reason);
#endif
  }
  if (!device) return nullptr;
  return inject_faults(std::move(device), spec);
}

}  // namespace tandem
