// How a backend says that its device failed, for whoever drives it: the
// backend factory's CPU fallback, the core tracer, the public API (which
// turns it into tandem::Error::Kind::kDevice). On the render floor so that
// none of them includes a device backend to catch it.
#pragma once

#include <cstdint>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "core/render/backend.h"

namespace tandem {

// What went wrong on a device, as far as the caller's recovery cares.
enum class DeviceFault : uint8_t {
  kOutOfMemory,     // an allocation failed; the device is still usable
  kLaunchFailure,   // a kernel could not be launched or aborted
  kIllegalAddress,  // a kernel faulted; the context is unusable from now on
  kDeviceLost,      // the device fell off the bus / the driver reset it
  kOther,
};
const char* device_fault_name(DeviceFault fault);

// Any failure of a device operation. The backend factory catches it under
// `--backend auto` and in backend lists and falls back to the CPU; with
// `--backend cuda` it reaches the user (exit 1) with the message.
class DeviceError : public std::runtime_error {
 public:
  DeviceError(DeviceFault fault, const std::string& what)
      : std::runtime_error(what), fault_(fault) {}
  DeviceFault fault() const { return fault_; }

 private:
  DeviceFault fault_;
};

// Thrown by a device backend's render() when a device operation failed
// part-way. The film then holds exactly the sums of the batches that
// completed; `unfinished()` lists the tiles taken from the source whose sums
// never reached it, so a fallback can render just those (and finish the
// frame with the image a CPU-only run would give). Unlike RenderIncomplete
// (backend.h), the backend that threw it has not switched to anything: it
// is for the fallback, not for the tracer.
class DeviceRenderError : public DeviceError {
 public:
  DeviceRenderError(const DeviceError& cause, std::vector<Tile> unfinished, BackendStats finished)
      : DeviceError(cause), unfinished_(std::move(unfinished)), finished_(finished) {}
  const std::vector<Tile>& unfinished() const { return unfinished_; }
  const BackendStats& finished() const { return finished_; }

 private:
  std::vector<Tile> unfinished_;
  BackendStats finished_;
};

}  // namespace tandem
