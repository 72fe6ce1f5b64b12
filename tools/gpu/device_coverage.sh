#!/usr/bin/env bash
# Line coverage of the device code on the simulated device, here, without a GPU:
#   tools/gpu/device_coverage.sh [BUILD_DIR]       (default build/device-coverage)
# Configures BUILD_DIR with TANDEM_DEVICE_COVERAGE=ON (the emulated builds of the .cu files,
# the code a GPU runs, compiled with gcov counters; no CUDA, no MPI), builds cuda_tests, runs
# the simulated-device tests, and prints by file the device code they ran (every .cu/.cuh of
# backends/cuda, the execution policy device_exec.h, and the device-only branches of
# core/kernel: tools/gpu/device_coverage.py) and the lines not run, ending with
#   device coverage: N of M lines (P%)
# The lines not run are also written to BUILD_DIR/device_coverage_missed.txt.
# Environment: JOBS (build jobs, default nproc).
set -euo pipefail
cd "$(dirname "$0")/../.."
build=${1:-build/device-coverage}
jobs=${JOBS:-$(nproc)}
launcher=()
if command -v ccache >/dev/null; then launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache); fi
cmake -S . -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DTANDEM_CUDA=OFF -DTANDEM_MPI=OFF \
  -DTANDEM_DEVICE_COVERAGE=ON "${launcher[@]}" >"$build.configure.log" 2>&1 ||
  { tail -20 "$build.configure.log"; exit 1; }
cmake --build "$build" -j "$jobs" --target cuda_tests
find "$build" -name '*.gcda' -delete
tests="$build/tests/cuda_tests"
# The GPU tests on the simulated device, and the tests of the simulated device's own.
TANDEM_DEVICE=sim "$tests" --gtest_filter='CudaGpu.*' --gtest_brief=1
"$tests" --gtest_brief=1 \
  --gtest_filter='CudaSim.*:CudaDriver.*:CudaDeviceScene.*:CudaBackendQueries.*:CudaEmulat*:CudaSvgf.*'
python3 tools/gpu/device_coverage.py "$build" --list "$build/device_coverage_missed.txt"
