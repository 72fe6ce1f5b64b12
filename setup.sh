#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a result:
#   ./setup.sh demo   install what is missing, build, render builtin:cornell to demo.png
#   ./setup.sh test   install what is missing, build, run the whole test suite
#                     (Release suite, then the AddressSanitizer+UBSan suite)
# Package installation is idempotent: only missing packages are installed.
set -euo pipefail
cd "$(dirname "$0")"

mode="${1:-}"
case "$mode" in
  demo|test|deps|build) ;;
  *) echo "usage: ./setup.sh demo|test   (also: deps, build)" >&2; exit 2 ;;
esac

packages=(cmake ninja-build g++ pkg-config
          libembree-dev libtbb-dev libglm-dev libtinygltf-dev libstb-dev
          libsdl2-dev libimgui-dev libgtest-dev libbenchmark-dev
          xvfb xauth)

missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  echo "setup: installing missing packages: ${missing[*]}"
  sudo=""
  [ "$(id -u)" -ne 0 ] && sudo="sudo"
  export DEBIAN_FRONTEND=noninteractive
  if ! $sudo apt-get install -y --no-install-recommends "${missing[@]}"; then
    $sudo apt-get update
    $sudo apt-get install -y --no-install-recommends "${missing[@]}"
  fi
fi
[ "$mode" = deps ] && exit 0

# nvcc is optional: with it the CUDA backend is built (it runs only where a GPU exists).
if [ -x /usr/local/cuda/bin/nvcc ] && ! command -v nvcc >/dev/null; then
  export PATH="/usr/local/cuda/bin:$PATH"
fi

jobs="$(nproc)"
cmake --preset release >/dev/null
cmake --build --preset release -j "$jobs"

case "$mode" in
  demo)
    ./build/release/app/tandem render builtin:cornell --width 512 --height 512 --spp 256 --output demo.png
    echo "setup: wrote $(pwd)/demo.png"
    ;;
  test)
    ctest --preset release -j "$jobs"
    # The same suite with AddressSanitizer + UndefinedBehaviorSanitizer: bad
    # input must not produce a single report.
    cmake --preset asan >/dev/null
    cmake --build --preset asan -j "$jobs"
    ctest --preset asan -j "$jobs"
    echo "setup: all tests passed"
    ;;
esac
