// Backends named on the command line: "cpu", "hetero", or a '+'-separated
// list ("cpu+host") whose frames the core tracer splits between them.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "core/render/backend.h"

namespace tandem {

// The names of a '+'-separated list, in order ("cpu+host" -> cpu, host).
std::vector<std::string> split_backend_list(const std::string& spec);

// Throws UsageError for unknown names or auto/hetero inside a list. With
// validate_only, checks the spelling and returns nothing (so usage errors
// come before a scene is loaded).
std::vector<std::unique_ptr<Backend>> make_backend_list(const std::string& spec,
                                                        bool validate_only = false);

}  // namespace tandem
