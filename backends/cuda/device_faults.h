// Fault injection for the CUDA backend's device, simulated or real: a
// decorator that makes a chosen device operation fail the way a GPU fails,
// so that every recovery path (the CPU fallback, exception safety, no leaks)
// is tested in CI and can be exercised on a GPU machine too.
//
// TANDEM_DEVICE_FAULT=KIND[@N] (N counts from 1, default 1):
//   oom              the N-th allocation (device, stream-ordered or pinned)
//                    fails with out of memory; the device stays usable
//   launch           the N-th kernel launch fails, and so does every later
//                    operation (a launch failure poisons a CUDA context)
//   illegal-address  the N-th kernel launch is accepted, the next
//                    synchronising call reports the fault (as a faulting
//                    kernel does), and every later operation fails
//   lost             the N-th operation of any kind, and every later one,
//                    fails: the device is gone
#pragma once

#include <memory>
#include <string>

#include "backends/cuda/device_ops.h"

namespace tandem {

struct FaultSpec {
  enum Kind { kNone, kOutOfMemory, kLaunch, kIllegalAddress, kLost } kind = kNone;
  uint64_t nth = 1;
  std::string text;  // as given, for messages
};

// Parses the value of TANDEM_DEVICE_FAULT; throws InputError naming the
// variable when it is malformed. An empty string means no fault.
FaultSpec parse_fault_spec(const std::string& text);

// Wraps `device` so that the operation `spec` names fails.
std::shared_ptr<DeviceOps> inject_faults(std::shared_ptr<DeviceOps> device, const FaultSpec& spec);

}  // namespace tandem
