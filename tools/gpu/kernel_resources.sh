#!/usr/bin/env bash
# Prints, for every CUDA kernel of the backend, what the compiler gives it on
# sm_90: registers, spill stores/loads, stack frame, shared memory, and the
# theoretical occupancy that follows from registers and shared memory (64K
# registers and 2048 threads per SM, 128-thread blocks). Runs here, without a
# GPU, from the project root: tools/gpu/kernel_resources.sh [BUILD_DIR [FILE.cu...]]
# (default build/release, which must have been configured with CUDA; the
# compile flags are taken from its compile_commands.json). Naming .cu files
# reports only their kernels, which saves minutes when iterating on one.
set -euo pipefail
build=${1:-build/release}
shift || true
files=("$@")
[ ${#files[@]} -gt 0 ] || files=(backends/cuda/*.cu)
db="$build/compile_commands.json"
[ -f "$db" ] || { echo "no $db: configure $build with CUDA first" >&2; exit 1; }
export PATH=/usr/local/cuda/bin:$PATH
printf '%-34s %5s %8s %8s %7s %7s %9s\n' kernel regs spill_st spill_ld stack smem occupancy
for cu in "${files[@]}"; do
  cmd=$(python3 - "$db" "$cu" <<'PY'
import json, sys
for e in json.load(open(sys.argv[1])):
    if e["file"].endswith(sys.argv[2]):
        print(e["command"])
        break
PY
)
  [ -n "$cmd" ] || continue
  # Compile to a throwaway object with the resource report on.
  out=$(mktemp)
  cmd=${cmd/ -o */ -o $out}
  ( cd "$build" && eval "$cmd -Xptxas -v" ) 2>&1 | python3 -c '
import re, sys
name = None
for line in sys.stdin:
    m = re.search(r"Compiling entry function .(\w+). for .sm_90", line)
    if m:
        name = m.group(1)
        stack = spill_st = spill_ld = 0
        continue
    if name is None:
        continue
    m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads", line)
    if m:
        stack, spill_st, spill_ld = map(int, m.groups())
    m = re.search(r"Used (\d+) registers.*?(?:(\d+) bytes smem)?", line)
    if m and "registers" in line:
        regs = int(m.group(1))
        smem = int(re.search(r"(\d+) bytes smem", line).group(1)) if "smem" in line else 0
        # Blocks of 128 threads per SM, limited by registers (allocated per warp
        # in units of 256), shared memory (228 KB, 1 KB reserved per block) and
        # 32 blocks / 2048 threads.
        per_warp = ((regs * 32 + 255) // 256) * 256
        by_regs = 65536 // (per_warp * 4) if regs else 32
        by_smem = (233472 // (smem + 1024)) if smem else 32
        blocks = min(by_regs, by_smem, 32, 2048 // 128)
        occ = blocks * 128 / 2048
        import subprocess
        full = subprocess.run(["c++filt", name], capture_output=True, text=True).stdout.strip()
        label = re.sub(r"\(.*$", "", full.replace("(anonymous namespace)::", "")).split("::")[-1][:34]
        print(f"{label:34s} {regs:5d} {spill_st:8d} {spill_ld:8d} {stack:7d} {smem:7d} {occ:8.1%}")
        name = None
'
  rm -f "$out"
done
