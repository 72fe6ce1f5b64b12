#!/usr/bin/env bash
# One command from a fresh Debian 12 machine to a result:
#   ./setup.sh demo   install what is missing, build, render builtin:cornell to demo.png
#   ./setup.sh test   install what is missing, build, run the whole test suite
#                     (Release suite, then the AddressSanitizer+UBSan suite, then
#                     one bounded minute of libFuzzer per fuzz target)
# Package installation is idempotent: only missing packages are installed.
set -euo pipefail
cd "$(dirname "$0")"

mode="${1:-}"
case "$mode" in
  demo|test|deps|build) ;;
  *) echo "usage: ./setup.sh demo|test   (also: deps, build)" >&2; exit 2 ;;
esac

# What building `tandem` needs: all the demo installs. The rest (viewer,
# tests, benchmarks, MPI, sanitizers, fuzzing) comes with the other modes.
packages=(cmake ninja-build g++ pkg-config
          libembree-dev libtbb-dev libglm-dev libtinygltf-dev libstb-dev libopenexr-dev
          libpng-dev)
if [ "$mode" != demo ]; then
  packages+=(libsdl2-dev libimgui-dev
             libgtest-dev libbenchmark-dev
             xvfb xauth
             libopenmpi-dev openmpi-bin
             clang libclang-rt-14-dev clang-format
             python3)
fi

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

# libFuzzer (clang, ASan + UBSan) on the glTF loader and the image readers,
# seeded from the shared scenes and from images the release build writes;
# FUZZ_SECONDS (default 30) per target, so CI time stays bounded. A crash, sanitizer report, leak
# or RSS over the limit fails the run and leaves the input in build/fuzz/findings.
# A fixed -seed keeps CI reproducible; explore more with another seed or longer.
run_fuzzers() {
  cmake -S . -B build/fuzz -G Ninja -DTANDEM_FUZZ=ON -DTANDEM_BUILD_TESTS=OFF \
        -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ >/dev/null
  cmake --build build/fuzz -j "$jobs" --target fuzz_gltf fuzz_image
  local corpus=build/fuzz/corpus findings=build/fuzz/findings
  rm -rf "$corpus"
  mkdir -p "$corpus/gltf" "$corpus/image" "$findings"
  if [ -d ../shared/scenes ]; then
    find ../shared/scenes -type f \( -name '*.gltf' -o -name '*.glb' \) -size -256k \
      -exec sh -c 'for f; do cp "$f" "$0/$(printf %s "$f" | md5sum | cut -c1-16)"; done' \
      "$corpus/gltf" {} +
    find ../shared/scenes -type f \( -name '*.png' -o -name '*.jpg' \) -size -64k \
      -exec sh -c 'for f; do cp "$f" "$0/$(printf %s "$f" | md5sum | cut -c1-16)"; done' \
      "$corpus/image" {} +
  fi
  for ext in exr pfm png; do
    ./build/release/app/tandem render builtin:cornell --width 6 --height 4 --spp 1 --quiet \
      --backend cpu --output "$corpus/image/seed.$ext"
  done
  # OpenEXR in the compressions users' files come in (ZIP above, by default).
  for c in piz dwaa rle b44; do
    ./build/release/app/tandem render builtin:cornell --width 40 --height 36 --spp 1 --quiet \
      --backend cpu --exr-pixel half --exr-compression "$c" --output "$corpus/image/seed-$c.exr"
  done
  printf '#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 2\n\200\100\000\201\000\000\200\202' \
    > "$corpus/image/seed.hdr"
  for target in gltf image; do
    echo "setup: fuzzing $target for ${FUZZ_SECONDS:-30} s"
    if ! ASAN_OPTIONS="detect_leaks=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
         ./build/fuzz/tools/fuzz/fuzz_$target "$corpus/$target" -dict="tools/fuzz/$target.dict" \
           -max_total_time="${FUZZ_SECONDS:-30}" -rss_limit_mb=2048 -timeout=30 -print_final_stats=1 -seed=1 \
           -artifact_prefix="$findings/$target-" > "$findings/$target.log" 2>&1; then
      tail -n 80 "$findings/$target.log" >&2
      echo "setup: fuzz_$target found a bug (input and log in $findings)" >&2
      exit 1
    fi
    grep -E '^stat::number_of_executed_units|^Done' "$findings/$target.log" || true
  done
}
case "$mode" in
  demo)
    # Only the executables: the demo needs neither the test binaries nor
    # the benchmarks (most of a full build). `./setup.sh test` later turns
    # the tests back on in the same build folder.
    cmake --preset release -DTANDEM_BUILD_TESTS=OFF >/dev/null
    cmake --build --preset release -j "$jobs" --target tandem
    ;;
  *)
    cmake --preset release -DTANDEM_BUILD_TESTS=ON >/dev/null
    cmake --build --preset release -j "$jobs"
    ;;
esac

case "$mode" in
  demo)
    ./build/release/app/tandem render builtin:cornell --width 512 --height 512 --spp 256 --output demo.png
    echo "setup: wrote $(pwd)/demo.png"
    ;;
  test)
    ctest --preset release -j "$jobs"
    # The same suite with AddressSanitizer + UndefinedBehaviorSanitizer: bad
    # input must not produce a single report. The asan test preset leaves out
    # what a sanitizer cannot add to (the tree checks, label project) and the
    # long chi-square runs of the BSDF lobes: pure arithmetic on the stack
    # that the release suite runs in full and the render tests still drive
    # through the same code under the sanitizers. The preset compiles with
    # line tables only (-g1): reports keep their file:line, and the build,
    # the longest step of CI, is about a fifth shorter than with -g. It
    # builds with clang++ (the release build with g++): a third faster to
    # compile under the sanitizers, and a second compiler in CI.
    cmake --preset asan >/dev/null
    cmake --build --preset asan -j "$jobs"
    ctest --preset asan -j "$jobs"
    run_fuzzers
    echo "setup: all tests passed"
    ;;
esac
