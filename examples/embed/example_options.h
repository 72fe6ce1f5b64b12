// Command-line pieces both examples parse the same way.
#pragma once

#include <tandem/tandem.h>

#include <string>

namespace embed_example {

// auto|cpu|cuda|hetero into *choice; false for anything else.
inline bool parse_backend(const std::string& name, tandem::BackendChoice* choice) {
  if (name == "auto")
    *choice = tandem::BackendChoice::kAuto;
  else if (name == "cpu")
    *choice = tandem::BackendChoice::kCpu;
  else if (name == "cuda")
    *choice = tandem::BackendChoice::kCuda;
  else if (name == "hetero")
    *choice = tandem::BackendChoice::kHetero;
  else
    return false;
  return true;
}

}  // namespace embed_example
