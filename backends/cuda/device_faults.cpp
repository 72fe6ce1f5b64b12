#include "backends/cuda/device_faults.h"

#include <cstdlib>
#include <exception>
#include <mutex>
#include <optional>

#include "core/util/errors.h"

namespace tandem {

FaultSpec parse_fault_spec(const std::string& text) {
  FaultSpec spec;
  spec.text = text;
  if (text.empty()) return spec;
  const size_t at = text.find('@');
  const std::string kind = text.substr(0, at);
  if (kind == "oom")
    spec.kind = FaultSpec::kOutOfMemory;
  else if (kind == "launch")
    spec.kind = FaultSpec::kLaunch;
  else if (kind == "illegal-address")
    spec.kind = FaultSpec::kIllegalAddress;
  else if (kind == "lost")
    spec.kind = FaultSpec::kLost;
  else
    throw InputError("TANDEM_DEVICE_FAULT='" + text +
                     "': unknown fault (expected oom, launch, illegal-address or lost, "
                     "optionally followed by @N)");
  if (at != std::string::npos) {
    const std::string n = text.substr(at + 1);
    char* end = nullptr;
    const unsigned long long v = n.empty() ? 0 : std::strtoull(n.c_str(), &end, 10);
    if (n.empty() || *end != '\0' || v == 0 || n[0] == '-')
      throw InputError("TANDEM_DEVICE_FAULT='" + text + "': N in KIND@N must be a count >= 1");
    spec.nth = v;
  }
  return spec;
}

namespace {

class FaultInjectingDevice final : public DeviceOps {
 public:
  FaultInjectingDevice(std::shared_ptr<DeviceOps> inner, FaultSpec spec)
      : inner_(std::move(inner)), spec_(std::move(spec)) {}

  std::string name() const override { return inner_->name(); }

  void* alloc(size_t bytes) override {
    on_alloc("alloc", bytes);
    return inner_->alloc(bytes);
  }
  void free(void* p) override { inner_->free(p); }
  void* alloc_async(size_t bytes, DeviceStream s) override {
    on_alloc("alloc_async", bytes);
    return inner_->alloc_async(bytes, s);
  }
  void free_async(void* p, DeviceStream s) override { inner_->free_async(p, s); }
  void* alloc_pinned(size_t bytes) override {
    on_alloc("alloc_pinned", bytes);
    return inner_->alloc_pinned(bytes);
  }
  void free_pinned(void* p) override { inner_->free_pinned(p); }
  DeviceStream create_stream() override {
    on_op("create_stream");
    return inner_->create_stream();
  }
  // Releasing never fails here: teardown after a fault still frees what
  // the inner device holds (the simulated device counts it).
  void destroy_stream(DeviceStream s) override { inner_->destroy_stream(s); }
  DeviceEvent create_event(bool timing) override {
    on_op("create_event");
    return inner_->create_event(timing);
  }
  void destroy_event(DeviceEvent e) override { inner_->destroy_event(e); }
  void record(DeviceEvent e, DeviceStream s) override {
    on_op("record");
    inner_->record(e, s);
  }
  void wait(DeviceStream s, DeviceEvent e) override {
    on_op("wait");
    inner_->wait(s, e);
  }
  // The host still waits for what was queued before it hears of the fault,
  // as it does on a GPU: nothing queued runs on after the call returns.
  void synchronize(DeviceEvent e) override {
    const std::exception_ptr fault = sync_fault("synchronize(event)");
    inner_->synchronize(e);
    if (fault) std::rethrow_exception(fault);
  }
  void synchronize(DeviceStream s) override {
    const std::exception_ptr fault = sync_fault("synchronize(stream)");
    inner_->synchronize(s);
    if (fault) std::rethrow_exception(fault);
  }
  double elapsed_seconds(DeviceEvent from, DeviceEvent to) override {
    on_op("elapsed_seconds");
    return inner_->elapsed_seconds(from, to);
  }
  void copy_to_device(void* dst, const void* src, size_t bytes, DeviceStream s) override {
    on_op("copy_to_device");
    inner_->copy_to_device(dst, src, bytes, s);
  }
  void copy_to_host(void* dst, const void* src, size_t bytes, DeviceStream s) override {
    on_op("copy_to_host");
    inner_->copy_to_host(dst, src, bytes, s);
  }
  void zero(void* dst, size_t bytes, DeviceStream s) override {
    on_op("zero");
    inner_->zero(dst, bytes, s);
  }
  DeviceProperties properties() const override { return inner_->properties(); }
  uint32_t resident_blocks(DeviceKernel kernel, uint32_t block_threads) override {
    return inner_->resident_blocks(kernel, block_threads);
  }
  void launch(DeviceKernel kernel, const LaunchDims& dims, const void* args, size_t args_bytes,
              DeviceStream s) override {
    on_launch(device_kernel_name(kernel));
    inner_->launch(kernel, dims, args, args_bytes, s);
  }

 private:
  [[noreturn]] void fail(DeviceFault fault, const char* what, const std::string& detail) {
    throw DeviceError(fault, std::string("injected device fault (TANDEM_DEVICE_FAULT=") +
                                 spec_.text + "): " + device_fault_name(fault) + " in " + what +
                                 detail);
  }
  // Every operation: a poisoned device fails everything; `lost` counts all.
  void on_op(const char* what) {
    std::lock_guard<std::mutex> lock(mutex_);
    check_poisoned(what);
    if (spec_.kind == FaultSpec::kLost && ++ops_ == spec_.nth) {
      poisoned_ = DeviceFault::kDeviceLost;
      fail(DeviceFault::kDeviceLost, what, "");
    }
  }
  void on_alloc(const char* what, size_t bytes) {
    on_op(what);
    std::lock_guard<std::mutex> lock(mutex_);
    if (spec_.kind == FaultSpec::kOutOfMemory && ++allocs_ == spec_.nth)
      fail(DeviceFault::kOutOfMemory, what, " of " + std::to_string(bytes) + " bytes");
  }
  void on_launch(const char* what) {
    on_op(what);
    std::lock_guard<std::mutex> lock(mutex_);
    const bool hit =
        (spec_.kind == FaultSpec::kLaunch || spec_.kind == FaultSpec::kIllegalAddress) &&
        ++launches_ == spec_.nth;
    if (!hit) return;
    if (spec_.kind == FaultSpec::kLaunch) {
      poisoned_ = DeviceFault::kLaunchFailure;
      fail(DeviceFault::kLaunchFailure, what, "");
    }
    pending_fault_ = true;  // reported by the next synchronising call
    faulting_kernel_ = what;
  }
  // The error a synchronising call reports, if any (not thrown yet).
  std::exception_ptr sync_fault(const char* what) {
    try {
      on_op(what);
      std::lock_guard<std::mutex> lock(mutex_);
      if (pending_fault_) {
        pending_fault_ = false;
        poisoned_ = DeviceFault::kIllegalAddress;
        fail(DeviceFault::kIllegalAddress, what, std::string(" (kernel ") + faulting_kernel_ + ")");
      }
    } catch (const DeviceError&) {
      return std::current_exception();
    }
    return nullptr;
  }
  void check_poisoned(const char* what) {
    if (poisoned_) fail(*poisoned_, what, " (the device failed earlier)");
  }

  std::shared_ptr<DeviceOps> inner_;
  FaultSpec spec_;
  std::mutex mutex_;
  uint64_t ops_ = 0, allocs_ = 0, launches_ = 0;
  bool pending_fault_ = false;
  const char* faulting_kernel_ = "";
  std::optional<DeviceFault> poisoned_;
};

}  // namespace

std::shared_ptr<DeviceOps> inject_faults(std::shared_ptr<DeviceOps> device, const FaultSpec& spec) {
  if (spec.kind == FaultSpec::kNone) return device;
  return std::make_shared<FaultInjectingDevice>(std::move(device), spec);
}

}  // namespace tandem
