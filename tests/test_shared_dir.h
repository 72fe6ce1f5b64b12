// Where the tests find the shared test data (../shared of the source tree):
// $TANDEM_SHARED_DIR when it is set, so that test binaries bundled for a
// machine without the source tree (tools/gpu/make_bundle.sh) find the copy
// shipped next to them; otherwise the directory configured at build time.
//
// tests/CMakeLists.txt force-includes this header (in each test binary's
// precompiled header) and defines the macro
// TANDEM_SHARED_DIR as a call of shared_dir(), so every test that writes
// fs::path(TANDEM_SHARED_DIR) or std::string(TANDEM_SHARED_DIR) honours the
// variable without knowing about it.
#pragma once

#include <cstdlib>

namespace tandem_test {

inline const char* shared_dir() {
  const char* dir = std::getenv("TANDEM_SHARED_DIR");
  return dir && *dir ? dir : TANDEM_SHARED_DIR_DEFAULT;
}

}  // namespace tandem_test
