// Backends named on the command line: "cpu", "hetero", or a '+'-separated
// list ("cpu+host") whose frames the core tracer splits between them; and
// the --kernel option that chooses how the CUDA and host backends trace.
#pragma once

#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "backends/backend_factory.h"
#include "core/render/backend.h"

namespace tandem {

// The names of a '+'-separated list, in order ("cpu+host" -> cpu, host).
std::vector<std::string> split_backend_list(const std::string& spec);

// The kinds of a list; throws UsageError for unknown names, an empty list or
// auto/hetero inside a list.
std::vector<BackendKind> parse_backend_list(const std::string& spec);

// Throws UsageError as parse_backend_list. With validate_only, checks the
// spelling and returns nothing (so usage errors come before a scene is
// loaded).
std::vector<std::unique_ptr<Backend>> make_backend_list(const std::string& spec,
                                                        const BackendOptions& options = {},
                                                        bool validate_only = false);

// The value of --kernel (nullopt: not given, the megakernel) checked against
// the backends it would apply to: a UsageError when none of `kinds` has
// kernel variants (only the CUDA backend, through cuda/auto/hetero, and the
// host backend do) or when it asks the host backend for the wavefront.
BackendOptions parse_kernel_option(const std::optional<std::string>& kernel,
                                   const std::vector<BackendKind>& kinds);

}  // namespace tandem
