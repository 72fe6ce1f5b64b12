// The operations the CUDA backend asks of a device, behind one small
// interface: memory, streams, events, copies and kernel launches by name.
// On a GPU they are CUDA runtime calls (cuda_device_ops.cpp); in CI, without
// a GPU, a simulated device (sim_device.h) runs them on the CPU with delays,
// records every access so that tests can assert the backend's ordering (no
// copy into a buffer a kernel is reading, no kernel reading a buffer whose
// copy has not landed), and runs the very kernel bodies of the .cu files on
// an emulated grid. What the kernels are launched with, and in which order,
// is host code written once over this interface (device_launch.h).
// A decorator (device_faults.h) makes the n-th operation of a kind fail, on
// either device. No CUDA headers here: the backend's logic compiles in every
// build.
#pragma once

#include <cstddef>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "backends/cuda/device_kernel_ids.h"
#include "core/render/device_error.h"

namespace tandem {

// What the launch geometry depends on: the device's multiprocessors and
// how many threads each holds at once.
struct DeviceProperties {
  uint32_t multiprocessors = 1;
  uint32_t max_threads_per_multiprocessor = 2048;
};

struct DeviceStreamHandle;
struct DeviceEventHandle;
using DeviceStream = DeviceStreamHandle*;  // opaque; null is never a valid stream
using DeviceEvent = DeviceEventHandle*;

// Every call may throw DeviceError. Asynchronous calls (those taking a
// stream) are ordered within their stream only; events order streams and
// the host. Device pointers are opaque to the host: only the device's own
// operations may dereference them.
class DeviceOps {
 public:
  virtual ~DeviceOps() = default;
  virtual std::string name() const = 0;

  virtual void* alloc(size_t bytes) = 0;
  virtual void free(void* p) = 0;
  // Stream-ordered: usable by later work on `stream` (and by other streams
  // once ordered after it by an event).
  virtual void* alloc_async(size_t bytes, DeviceStream stream) = 0;
  virtual void free_async(void* p, DeviceStream stream) = 0;
  // Page-locked host memory, the only host memory asynchronous copies may
  // use without becoming synchronous.
  virtual void* alloc_pinned(size_t bytes) = 0;
  virtual void free_pinned(void* p) = 0;

  virtual DeviceStream create_stream() = 0;
  virtual void destroy_stream(DeviceStream stream) = 0;
  // `timing`: the event can be used with elapsed_seconds().
  virtual DeviceEvent create_event(bool timing) = 0;
  virtual void destroy_event(DeviceEvent event) = 0;
  // Captures the work enqueued on `stream` so far.
  virtual void record(DeviceEvent event, DeviceStream stream) = 0;
  // Later work on `stream` waits for the event's most recent record.
  virtual void wait(DeviceStream stream, DeviceEvent event) = 0;
  // The host blocks (without spinning) until the event / the stream is done.
  virtual void synchronize(DeviceEvent event) = 0;
  virtual void synchronize(DeviceStream stream) = 0;
  // Seconds from `from` to `to` (negative if `to` completed first); both
  // must be timing events whose records have completed.
  virtual double elapsed_seconds(DeviceEvent from, DeviceEvent to) = 0;

  virtual void copy_to_device(void* dst, const void* src, size_t bytes, DeviceStream stream) = 0;
  virtual void copy_to_host(void* dst, const void* src, size_t bytes, DeviceStream stream) = 0;
  virtual void zero(void* dst, size_t bytes, DeviceStream stream) = 0;

  // What the launch geometry depends on.
  virtual DeviceProperties properties() const = 0;
  // Blocks of `kernel` at `block_threads` threads each that one
  // multiprocessor holds at once (at least 1): what persistent threads fill
  // the device with.
  virtual uint32_t resident_blocks(DeviceKernel kernel, uint32_t block_threads) = 0;
  // Enqueues `kernel` (device_kernels.h) on `stream` with `args`, its Args
  // struct, which is copied (`args_bytes` must be its size). The launch
  // helpers of device_launch.h are the typed way to call it.
  virtual void launch(DeviceKernel kernel, const LaunchDims& dims, const void* args,
                      size_t args_bytes, DeviceStream stream) = 0;
};

// ---------------------------------------------------------------------------
// Owners of device resources: release in the destructor (errors ignored: a
// lost device is being abandoned anyway), so that no exception path leaks a
// stream, an event or memory.

class DeviceStreamOwner {
 public:
  DeviceStreamOwner() = default;
  explicit DeviceStreamOwner(DeviceOps& ops) : ops_(&ops), stream_(ops.create_stream()) {}
  ~DeviceStreamOwner() { reset(); }
  DeviceStreamOwner(DeviceStreamOwner&& o) noexcept { *this = std::move(o); }
  DeviceStreamOwner& operator=(DeviceStreamOwner&& o) noexcept;
  DeviceStream get() const { return stream_; }
  void reset() noexcept;

 private:
  DeviceOps* ops_ = nullptr;
  DeviceStream stream_ = nullptr;
};

class DeviceEventOwner {
 public:
  DeviceEventOwner() = default;
  DeviceEventOwner(DeviceOps& ops, bool timing) : ops_(&ops), event_(ops.create_event(timing)) {}
  ~DeviceEventOwner() { reset(); }
  DeviceEventOwner(DeviceEventOwner&& o) noexcept { *this = std::move(o); }
  DeviceEventOwner& operator=(DeviceEventOwner&& o) noexcept;
  DeviceEvent get() const { return event_; }
  void reset() noexcept;

 private:
  DeviceOps* ops_ = nullptr;
  DeviceEvent event_ = nullptr;
};

// Device or pinned host memory. `bytes()` always describes memory that is
// allocated: a failed (re)allocation leaves the buffer empty, never a size
// that refers to freed memory.
class DeviceBuffer {
 public:
  enum Kind { kDevice, kPinned };
  DeviceBuffer() = default;
  DeviceBuffer(DeviceOps& ops, Kind kind) : ops_(&ops), kind_(kind) {}
  ~DeviceBuffer() { reset(); }
  DeviceBuffer(DeviceBuffer&& o) noexcept { *this = std::move(o); }
  DeviceBuffer& operator=(DeviceBuffer&& o) noexcept;

  // Frees what is held, then allocates `bytes` (at least 1).
  void allocate(size_t bytes);
  // Grows to at least `bytes` (nothing happens when it is large enough).
  void reserve(size_t bytes) {
    if (bytes > bytes_) allocate(bytes);
  }
  void reset() noexcept;
  void* get() const { return ptr_; }
  template <class T>
  T* as() const {
    return static_cast<T*>(ptr_);
  }
  size_t bytes() const { return bytes_; }

 private:
  DeviceOps* ops_ = nullptr;
  Kind kind_ = kDevice;
  void* ptr_ = nullptr;
  size_t bytes_ = 0;
};

// The device the CUDA backend runs on: TANDEM_DEVICE=sim selects the
// simulated device (tests, CI), anything else the first CUDA GPU. Every
// device is wrapped in the fault injector when TANDEM_DEVICE_FAULT is set.
// Returns null with `reason` set when there is none.
std::shared_ptr<DeviceOps> open_device(std::string* reason);
// Whether open_device() would succeed, without creating anything heavy.
bool device_available(std::string* reason);

}  // namespace tandem
