#!/usr/bin/env python3
"""What ptxas gives every CUDA kernel on sm_90, and the gate on it.

usage: kernel_resources.py [--check] [--budget FILE] [--jobs N] BUILD_DIR [FILE.cu ...]

Compiles each .cu file of backends/cuda (or the ones named) to a cubin for
sm_90 with the build's own flags (from BUILD_DIR/compile_commands.json, which
must have been configured with CUDA) and the resource report on, and prints
per kernel: its block size and launch bounds (backends/cuda/device_kernels.h),
registers, spill stores and loads, stack frame, static shared memory, and the
theoretical occupancy at that block size (64K registers allocated per warp in
units of 256, 228 KiB of shared memory with 1 KiB reserved per block, at most
32 blocks and 2048 threads per multiprocessor).

--check compares every kernel with the committed budget (default
tools/gpu/kernel_budget.txt: registers, spills and stack at most, occupancy
at least) and exits 1 on any regression, on a kernel without a budget and on
a budgeted kernel that is gone.
"""
import argparse
import concurrent.futures
import json
import os
import re
import shlex
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
REGISTERS_PER_SM = 65536
REGISTER_UNIT = 256  # registers are allocated per warp in these units
SHARED_PER_SM = 233472
SHARED_RESERVED_PER_BLOCK = 1024
MAX_BLOCKS_PER_SM = 32
MAX_THREADS_PER_SM = 2048


def launch_bounds():
    """kernel -> (threads, min_blocks), from device_kernels.h."""
    text = open(os.path.join(ROOT, "backends/cuda/device_kernels.h"), encoding="utf-8").read()
    return {m.group(1): (int(m.group(2)), int(m.group(3))) for m in re.finditer(
        r"TANDEM_DEVICE_KERNEL_TRAITS\((\w+),\s*\w+,\s*(\d+),\s*(\d+)\)", text)}


def occupancy(threads, regs, smem):
    warps = (threads + 31) // 32
    per_warp = -(-regs * 32 // REGISTER_UNIT) * REGISTER_UNIT
    by_regs = REGISTERS_PER_SM // (per_warp * warps) if regs else MAX_BLOCKS_PER_SM
    by_smem = SHARED_PER_SM // (smem + SHARED_RESERVED_PER_BLOCK)
    blocks = min(by_regs, by_smem, MAX_BLOCKS_PER_SM, MAX_THREADS_PER_SM // (warps * 32))
    return blocks * warps * 32 / MAX_THREADS_PER_SM


def cubin_command(build, cu):
    with open(os.path.join(build, "compile_commands.json"), encoding="utf-8") as f:
        for entry in json.load(f):
            if entry["file"].endswith(cu):
                args = shlex.split(entry["command"])
                out = []
                skip = False
                for a in args:
                    if skip:
                        skip = False
                        continue
                    if a == "-o":
                        skip = True
                        continue
                    if a.startswith("--generate-code") or a.startswith("-gencode"):
                        continue
                    out.append("-cubin" if a == "-c" else a)
                return out + ["-arch=sm_90", "-Xptxas", "-v"], entry["directory"]
    return None, None


def report(build, cu):
    """[(kernel, regs, spill stores, spill loads, stack, smem)] of one file."""
    cmd, cwd = cubin_command(build, cu)
    if cmd is None:
        sys.exit(f"kernel_resources: {cu} is not in {build}/compile_commands.json "
                 "(configure the build with CUDA)")
    with tempfile.TemporaryDirectory() as tmp:
        cmd += ["-o", os.path.join(tmp, "out.cubin")]
        done = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, check=False)
    if done.returncode != 0:
        sys.exit(f"kernel_resources: compiling {cu} failed:\n{done.stderr[-3000:]}")
    rows, name = [], None
    for line in done.stderr.splitlines():
        m = re.search(r"Compiling entry function '(\w+)' for 'sm_90'", line)
        if m:
            demangled = subprocess.run(["c++filt", m.group(1)], capture_output=True,
                                       text=True, check=False).stdout.strip()
            k = re.search(r"cuda_entry<tandem::(?:\w+::)?(\w+)>", demangled)
            name = k.group(1) if k else demangled
            stack = spill_st = spill_ld = 0
            continue
        if name is None:
            continue
        m = re.search(r"(\d+) bytes stack frame, (\d+) bytes spill stores, (\d+) bytes spill loads",
                      line)
        if m:
            stack, spill_st, spill_ld = map(int, m.groups())
        m = re.search(r"Used (\d+) registers", line)
        if m:
            s = re.search(r"(\d+) bytes smem", line)
            rows.append((name, int(m.group(1)), spill_st, spill_ld, stack, int(s.group(1)) if s else 0))
            name = None
    return rows


def read_budget(path):
    budget = {}
    for line in open(path, encoding="utf-8"):
        line = line.split("#")[0].split()
        if not line:
            continue
        kernel, regs, spill_st, spill_ld, stack, occ = line
        budget[kernel] = (int(regs), int(spill_st), int(spill_ld), int(stack), float(occ.rstrip("%")))
    return budget


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--check", action="store_true")
    parser.add_argument("--budget", default=os.path.join(ROOT, "tools/gpu/kernel_budget.txt"))
    parser.add_argument("--jobs", type=int, default=os.cpu_count() or 1)
    parser.add_argument("build")
    parser.add_argument("files", nargs="*")
    args = parser.parse_args()
    files = args.files or sorted(
        os.path.join("backends/cuda", f) for f in os.listdir(os.path.join(ROOT, "backends/cuda"))
        if f.endswith(".cu"))
    bounds = launch_bounds()
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        reports = list(pool.map(lambda f: report(os.path.abspath(args.build), f), files))
    rows = sorted((r for rep in reports for r in rep), key=lambda r: r[0])
    print(f"{'kernel':16s} {'block':>9s} {'regs':>5s} {'spill_st':>8s} {'spill_ld':>8s} "
          f"{'stack':>6s} {'smem':>5s} {'occupancy':>9s}")
    measured = {}
    for name, regs, spill_st, spill_ld, stack, smem in rows:
        threads, min_blocks = bounds.get(name, (128, 0))
        occ = occupancy(threads, regs, smem)
        measured[name] = (regs, spill_st, spill_ld, stack, 100.0 * occ)
        print(f"{name:16s} {threads:5d} x{min_blocks:2d} {regs:5d} {spill_st:8d} {spill_ld:8d} "
              f"{stack:6d} {smem:5d} {occ:9.1%}")
    if not args.check:
        return
    budget = read_budget(args.budget)
    problems = []
    for name, (regs, spill_st, spill_ld, stack, occ) in measured.items():
        if name not in budget:
            problems.append(f"{name}: no budget in {os.path.relpath(args.budget, ROOT)}")
            continue
        b_regs, b_st, b_ld, b_stack, b_occ = budget[name]
        for what, value, limit in (("registers", regs, b_regs), ("spill stores", spill_st, b_st),
                                   ("spill loads", spill_ld, b_ld), ("stack bytes", stack, b_stack)):
            if value > limit:
                problems.append(f"{name}: {value} {what}, budget {limit}")
        if occ < b_occ - 1e-6:
            problems.append(f"{name}: occupancy {occ:.1f}%, budget {b_occ:.1f}%")
    if not args.files:
        problems += [f"{name}: in the budget but not compiled" for name in budget
                     if name not in measured]
    for p in problems:
        print("kernel_resources: regression: " + p)
    print(f"kernel_resources: {len(measured)} kernels, {len(problems)} over budget")
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()
