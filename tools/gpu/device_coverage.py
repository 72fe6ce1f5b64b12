#!/usr/bin/env python3
"""Line coverage of the device code on the simulated device, from gcov data.

usage: device_coverage.py BUILD_DIR [--list FILE]

The device code is every .cu/.cuh file of backends/cuda, the execution
policy (backends/cuda/device_exec.h), and the device-only code of
core/kernel: the lines nvcc's device pass compiles and the host build does
not, and the functions only the GPU runs (GPU_ONLY_FUNCTIONS: its BVH loops
and its path loop; the host has its own). A line counts when it is code: gcov calls it executable in the
emulated build, or it is compiled by nvcc alone (the CUDA half of the
policy, the __device__ tables), where no CPU can run it and it counts as not
run. Prints a table by file, the lines not run, and last
`device coverage: N of M lines (P%)`. Needs the .gcda files of a build
configured with -DTANDEM_DEVICE_COVERAGE=ON after the simulated-device tests
ran (tools/gpu/device_coverage.sh does both).
"""
import argparse
import collections
import glob
import gzip
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

# The three ways the kernel code is compiled, as the macros they define.
NVCC_DEVICE = {"__CUDACC__": 1, "__CUDA_ARCH__": 900, "TANDEM_GPU_CODE": 1,
               "TANDEM_HAS_DEVICE_TABLES": 1}
EMULATED = {"TANDEM_EMULATED_GPU": 1, "TANDEM_GPU_CODE": 1, "TANDEM_HAS_DEVICE_TABLES": 1,
            "__GNUC__": 12}
HOST = {"TANDEM_GPU_CODE": 0, "TANDEM_HAS_DEVICE_TABLES": 0, "__GNUC__": 12,
        "TANDEM_BVH_HOST_TRAVERSAL": 1}


def evaluate(expr, macros):
    """The value of a #if expression over `macros` (the forms the kernel code uses)."""
    expr = re.sub(r"//.*", "", expr)
    expr = re.sub(r"defined\s*\(\s*(\w+)\s*\)", lambda m: str(int(m.group(1) in macros)), expr)
    expr = re.sub(r"defined\s+(\w+)", lambda m: str(int(m.group(1) in macros)), expr)
    expr = re.sub(r"__has_feature\s*\([^)]*\)", "0", expr)
    expr = expr.replace("&&", " and ").replace("||", " or ")
    expr = re.sub(r"!(?!=)", " not ", expr)
    expr = re.sub(r"\b([A-Za-z_]\w*)\b",
                  lambda m: m.group(1) if m.group(1) in ("and", "or", "not")
                  else str(macros.get(m.group(1), 0)), expr)
    return bool(eval(expr))  # noqa: S307 - the expression is ours


def active_lines(lines, macros):
    """For each line, whether the preprocessor keeps it under `macros`."""
    active, stack = [], []  # stack: (parent active, branch taken so far, this branch active)
    on = True
    for line in lines:
        m = re.match(r"\s*#\s*(if|ifdef|ifndef|elif|else|endif)\b(.*)", line)
        if not m:
            active.append(on)
            continue
        kind, rest = m.group(1), m.group(2)
        active.append(False)  # directives are not code
        if kind in ("if", "ifdef", "ifndef"):
            if kind == "ifdef":
                value = rest.strip() in macros
            elif kind == "ifndef":
                value = rest.strip() not in macros
            else:
                value = evaluate(rest, macros)
            stack.append((on, value))
            on = on and value
        elif kind == "elif":
            parent, taken = stack[-1]
            value = not taken and evaluate(rest, macros)
            stack[-1] = (parent, taken or value)
            on = parent and value
        elif kind == "else":
            parent, taken = stack[-1]
            stack[-1] = (parent, True)
            on = parent and not taken
        else:
            on = stack.pop()[0]
    return active


def is_code(text):
    """A statement or declaration: not blank, a comment, a preprocessor line or a brace."""
    t = text.strip()
    if not t or t.startswith("//") or t.startswith("#"):
        return False
    return t not in ("{", "}", "};", "})", "});")


# Functions of core/kernel that only the GPU runs: the host renders with its
# own BVH loops (bvh_traverse_host.h) and its own path loop.
GPU_ONLY_FUNCTIONS = ("trace_two_level_binary", "trace_two_level_wide", "wide_child_box",
                      "render_pixel_sample_one_trace_site")


def function_lines(lines, names):
    """Indices of the lines of the definitions of `names` (signature to closing brace)."""
    inside = set()
    for i, text in enumerate(lines):
        if not re.match(r"^TANDEM_HD\b.*\b(" + "|".join(names) + r")\(", text):
            continue
        depth, j, opened = 0, i, False
        while j < len(lines):
            depth += lines[j].count("{") - lines[j].count("}")
            opened = opened or "{" in lines[j]
            inside.add(j)
            if opened and depth == 0:
                break
            j += 1
    return inside


def device_files():
    files = sorted(glob.glob(os.path.join(ROOT, "backends/cuda/*.cu")) +
                   glob.glob(os.path.join(ROOT, "backends/cuda/*.cuh")))
    files.append(os.path.join(ROOT, "backends/cuda/device_exec.h"))
    return [(f, True) for f in files] + [
        (f, False) for f in sorted(glob.glob(os.path.join(ROOT, "core/kernel/*.h")))]


def gcov_lines(build):
    """source path -> {line: executed count} over every .gcda of the build."""
    counts = collections.defaultdict(dict)
    for gcda in glob.glob(os.path.join(os.path.abspath(build), "**", "*.gcda"), recursive=True):
        out = subprocess.run(["gcov", "--json-format", "--stdout", gcda], cwd=os.path.dirname(gcda),
                             capture_output=True, check=False)
        for chunk in out.stdout.splitlines():
            if not chunk.strip():
                continue
            data = json.loads(chunk)
            cwd = data.get("current_working_directory", "")
            for f in data.get("files", []):
                path = os.path.realpath(os.path.join(cwd, f["file"]))
                lines = counts[path]
                for ln in f.get("lines", []):
                    n = ln["line_number"]
                    lines[n] = lines.get(n, 0) + ln["count"]
    return counts


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("build")
    parser.add_argument("--list", help="also write the lines not run to this file")
    args = parser.parse_args()
    counts = gcov_lines(args.build)
    if not counts:
        sys.exit("device_coverage: no gcov data under " + args.build)
    total_n = total_m = 0
    rows, missed = [], []
    for path, whole_file in device_files():
        lines = open(path, encoding="utf-8").read().split("\n")
        nvcc = active_lines(lines, NVCC_DEVICE)
        emulated = active_lines(lines, EMULATED)
        host = active_lines(lines, HOST)
        gpu_only = function_lines(lines, GPU_ONLY_FUNCTIONS)
        executed = counts.get(os.path.realpath(path), {})
        n = m = 0
        for i, text in enumerate(lines):
            number = i + 1
            if not nvcc[i] or (not whole_file and host[i] and i not in gpu_only):
                continue  # not device code, or code the host runs too
            if emulated[i]:
                if number not in executed:
                    continue  # gcov: no code on this line
                m += 1
                if executed[number] > 0:
                    n += 1
                else:
                    missed.append((path, number, text.strip(), "not reached"))
            elif is_code(text):
                m += 1
                missed.append((path, number, text.strip(), "nvcc only"))
        if m:
            rows.append((os.path.relpath(path, ROOT), n, m))
        total_n += n
        total_m += m
    print(f"{'file':44s} {'run':>5s} {'lines':>6s}")
    for name, n, m in rows:
        print(f"{name:44s} {n:5d} {m:6d}")
    report = [f"{os.path.relpath(p, ROOT)}:{ln}: [{why}] {text}" for p, ln, text, why in missed]
    print("\nlines not run:")
    for r in report:
        print("  " + r)
    if args.list:
        with open(args.list, "w", encoding="utf-8") as out:
            out.write("\n".join(report) + "\n")
    pct = 100.0 * total_n / total_m if total_m else 0.0
    print(f"device coverage: {total_n} of {total_m} lines ({pct:.1f}%)")


if __name__ == "__main__":
    main()
