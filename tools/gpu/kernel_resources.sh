#!/usr/bin/env bash
# What the compiler gives every CUDA kernel of the backend on sm_90 (registers, spills, stack,
# shared memory, occupancy at the kernel's own block size), here, without a GPU:
#   tools/gpu/kernel_resources.sh [--check] [BUILD_DIR [FILE.cu...]]
# BUILD_DIR (default build/release) must have been configured with CUDA; the compile flags
# are taken from its compile_commands.json. Naming .cu files reports only their kernels.
# --check compares with tools/gpu/kernel_budget.txt and exits 1 on a regression (the ctest
# cuda_kernel_resources runs it in every build with nvcc). See kernel_resources.py.
set -euo pipefail
cd "$(dirname "$0")/../.."
check=()
if [ "${1:-}" = --check ]; then
  check=(--check)
  shift
fi
build=${1:-build/release}
shift || true
export PATH=/usr/local/cuda/bin:$PATH
exec python3 tools/gpu/kernel_resources.py "${check[@]}" "$build" "$@"
