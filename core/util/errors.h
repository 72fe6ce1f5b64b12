// Error types that map onto the CLI's exit codes: InputError -> 1 (a file or
// value the user gave is bad), UsageError -> 2 (the command line is wrong).
// Messages are complete sentences naming the offending file and the reason,
// because they are printed to the user as they are.
#pragma once

#include <stdexcept>
#include <string>

namespace tandem {

class InputError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

class UsageError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace tandem
