#!/usr/bin/env bash
# Runs ON the GPU machine, from the project root there, with .gpu/ (made by
# tools/gpu/make_bundle.sh) in it:   bash .gpu/run_on_gpu.sh
# Unpacks the bundle and checks that this machine's glibc is as new as it needs, then runs
# the steps below in the order of what they tell: nvidia-smi; every GPU test (a skip counts
# as a failure); a 1080p CUDA render against the host backend (the same kernels on the CPU);
# compute-sanitizer memcheck and racecheck of a small render with both kernels; `tandem
# bench --gpu`; a cuda+cpu render of a textured model against the CPU backend; the
# wavefront against the megakernel; a cuda+cpu bench. Every step has a time limit and the
# limits add up to the budget (BUDGET_S, default 340 s), so the whole run, start-up
# excluded, ends within 6 minutes; a step the budget leaves no time for is a SKIP.
# STEPS=a,b,... runs only the named steps (a rerun of what failed; the bundle step always
# runs): STEPS=tests_cuda,memcheck bash .gpu/run_on_gpu.sh.
# Logs go to $OUT (default /tmp/tandem-gpu), copied to .gpu/out; the compared .exr renders
# to $IMAGES_DIR (default /tmp/tandem-gpu-images), not to $OUT. A summary table (step,
# PASS/FAIL/SKIP, seconds, key figure) is printed last. Exit code: 0 when every step run
# passed, else 1.
set -uo pipefail # no -e: every step runs, and the table tells which failed

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
OUT=${OUT:-/tmp/tandem-gpu}
bundle=${BUNDLE_DIR:-/tmp/tandem-bundle}
images=${IMAGES_DIR:-/tmp/tandem-gpu-images}
budget=${BUDGET_S:-340}
selected=",${STEPS:-},"
t_start=$(date +%s.%N)
mkdir -p "$OUT" "$images"
# Nothing of an earlier run may pass for this one's.
rm -f "$OUT"/*.log "$OUT"/*.xml "$OUT"/*.png "$OUT"/bench_gpu.json "$images"/*.exr
rows=()
step_rc=0 step_s=0 step_skipped=0

elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
row() { rows+=("$1|$2|$3|$4"); } # step, status, seconds, key figure
# wanted NAME: whether STEPS (when set) names the step.
wanted() { [ "$selected" = ",," ] || [[ $selected == *",$1,"* ]]; }

finish() {
  local failed=0 r step status secs figure
  mkdir -p "$here/out" && cp -r "$OUT"/. "$here/out/" 2>/dev/null
  echo
  echo "== summary ($(elapsed "$t_start") s in all; logs in $OUT and $here/out)"
  printf '%-22s %-6s %8s  %s\n' step result seconds "key figure"
  for r in "${rows[@]}"; do
    IFS='|' read -r step status secs figure <<<"$r"
    printf '%-22s %-6s %8s  %s\n' "$step" "$status" "$secs" "$figure"
    [ "$status" = PASS ] || failed=1
  done
  exit "$failed"
}
trap finish EXIT

# run_step NAME LIMIT CMD...: runs CMD under a timeout (LIMIT, or what is left of the budget)
# with its output in $OUT/NAME.log; sets step_rc and step_s, and prints the log's last lines.
run_step() {
  local name=$1 limit=$2 left t0
  shift 2
  left=$(awk -v b="$budget" -v e="$(elapsed "$t_start")" 'BEGIN { printf "%d", b - e }')
  step_skipped=0
  if [ "$left" -lt 5 ]; then
    echo "not run: the budget of ${budget} s is used up" >"$OUT/$name.log"
    step_rc=125 step_s=0 step_skipped=1
    return
  fi
  [ "$limit" -le "$left" ] || limit=$left
  echo "== $name (timeout ${limit} s): $*"
  t0=$(date +%s.%N)
  timeout --kill-after=5 "$limit" "$@" </dev/null >"$OUT/$name.log" 2>&1
  step_rc=$?
  step_s=$(elapsed "$t0")
  tail -n 4 "$OUT/$name.log" | cut -c1-160 | sed 's/^/   /'
}
timed_out() { [ "$step_rc" = 124 ] || [ "$step_rc" = 137 ]; }
# skipped_row NAME: records a SKIP (and succeeds) when run_step had no time left for NAME.
skipped_row() {
  [ "$step_skipped" = 1 ] || return 1
  row "$1" SKIP 0 "not run: budget of ${budget} s used up"
}
# last_line NAME: the log's last non-empty line, shortened, for the key figure.
last_line() { grep -v '^\s*$' "$OUT/$1.log" | tail -n 1 | cut -c1-70; }
# simple_row NAME: PASS on exit code 0, the last output line as the key figure.
simple_row() {
  if skipped_row "$1"; then
    return
  elif [ "$step_rc" = 0 ]; then
    row "$1" PASS "$step_s" "$(last_line "$1")"
  elif timed_out; then
    row "$1" FAIL "$step_s" "timed out (exit $step_rc)"
  else
    row "$1" FAIL "$step_s" "exit $step_rc: $(last_line "$1")"
  fi
}

# --- the bundle, and whether this machine can load it ------------------------------------------
t0=$(date +%s.%N)
rm -rf "$bundle" && mkdir -p "$bundle"
if ! tar -xJf "$here/bundle.tar.xz" -C "$bundle" 2>"$OUT/bundle.log"; then
  row bundle FAIL "$(elapsed "$t0")" "cannot unpack $here/bundle.tar.xz"
  exit 1
fi
B=$bundle/bin
export LD_LIBRARY_PATH=$bundle/lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
# The bundled libstdc++ only where the system's is too old for the binaries.
if ldd "$B/tandem" 2>&1 | grep 'not found' >/dev/null; then
  export LD_LIBRARY_PATH=$bundle/lib:$bundle/lib-old-system
fi
export TANDEM_SHARED_DIR=$bundle/shared TANDEM_REQUIRE_GPU=1
export TANDEM_BVH_CACHE=/tmp/tandem-bvh-cache
export PATH=$PATH:/usr/local/cuda/bin
{
  cat "$bundle/BUNDLE_INFO"
  echo "this machine: $(getconf GNU_LIBC_VERSION 2>/dev/null || echo 'glibc unknown')"
  for b in "$B"/*; do ldd "$b" 2>&1; done
} >>"$OUT/bundle.log"
need=$(sed -n 's/^glibc needed: \([0-9.]*\).*/\1/p' "$bundle/BUNDLE_INFO")
have=$(getconf GNU_LIBC_VERSION 2>/dev/null | awk '{print $2}')
if [ -n "$need" ] && [ -n "$have" ] &&
  [ "$(printf '%s\n%s\n' "$need" "$have" | sort -V | head -n 1)" != "$need" ]; then
  row bundle FAIL "$(elapsed "$t0")" "glibc $have here, the bundle needs $need: nothing can load"
  exit 1
elif grep -q 'not found' "$OUT/bundle.log"; then
  row bundle FAIL "$(elapsed "$t0")" "$(grep -m1 'not found' "$OUT/bundle.log" | cut -c1-70)"
  exit 1
fi
row bundle PASS "$(elapsed "$t0")" \
  "$(sed -n 's/^commit \(.\{12\}\).*/commit \1/p' "$bundle/BUNDLE_INFO"), glibc $have (needs $need)"

# --- the steps -------------------------------------------------------------------------------
step_nvidia_smi() {
  run_step nvidia_smi 10 bash -c 'nvidia-smi && nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv,noheader'
  if [ "$step_rc" = 0 ]; then
    row nvidia_smi PASS "$step_s" "$(last_line nvidia_smi)"
  else
    row nvidia_smi FAIL "$step_s" "no GPU or no driver: $(last_line nvidia_smi)"
  fi
}

# The GPU tests: a skip is a failure here.
step_tests_cuda() {
  local binary filter name figure
  while read -r binary filter; do
    [ -n "$binary" ] || continue
    name=tests_${binary%_tests}
    run_step "$name" 70 "$B/$binary" "--gtest_filter=$filter" "--gtest_output=xml:$OUT/$name.xml"
    figure="$(bash "$here/gtest_counts.sh" "$OUT/$name.log") ($filter)"
    if skipped_row "$name"; then
      :
    elif timed_out; then
      row "$name" FAIL "$step_s" "timed out after $figure"
    elif [ "$step_rc" = 0 ] && [[ $figure == *" 0 skipped, 0 failed"* ]] && [[ $figure != "0 passed"* ]]; then
      row "$name" PASS "$step_s" "$figure"
    else
      row "$name" FAIL "$step_s" "$figure, exit $step_rc"
    fi
  done <"$bundle/gpu_tests.txt"
}

# render_row NAME LIMIT ARGS...: a render step; the key figure is tandem's throughput summary.
render_row() {
  local name=$1 limit=$2
  shift 2
  run_step "$name" "$limit" "$B/tandem" render "$@"
  if [ "$step_rc" = 0 ]; then
    row "$name" PASS "$step_s" "$(grep -oE '[0-9.]+ M samples/s.*Mrays/s' "$OUT/$name.log" | tail -n 1)"
  else
    simple_row "$name"
  fi
}
# compare_row NAME A B: PASS when `tandem compare` says AGREE, or when the images differ by
# less than 1e-4 of their mean (same-seed renders of the same kernels differ in the last bits
# only, where the block test's noise estimate means little).
compare_row() {
  local name=$1 a=$2 b=$3 json verdict rmse mean rel
  run_step "$name" 5 "$B/tandem" compare "$a" "$b" --json
  json=$(tail -n 1 "$OUT/$name.log")
  verdict=$(echo "$json" | grep -oE '"verdict": "[A-Z]+"' | tail -n 1 | grep -oE '[A-Z]+')
  rmse=$(echo "$json" | grep -oE '"rmse": [-0-9.e+]+' | grep -oE '[-0-9.e+]+$')
  mean=$(echo "$json" | grep -oE '"mean_a": \[[^]]*\]' | grep -oE '[-0-9.e+]+' |
    awk '{ s += $1 } END { if (NR) printf "%.9g", s / NR }')
  if [ "$step_skipped" = 1 ] || [ "$step_rc" != 0 ] || [ -z "$verdict" ]; then
    simple_row "$name"
    return
  fi
  rel=$(awk -v r="$rmse" -v m="$mean" 'BEGIN { printf "%.2g", (m > 0 ? r / m : r) }')
  if [ "$verdict" = AGREE ] || awk -v x="$rel" 'BEGIN { exit !(x < 1e-4) }'; then
    row "$name" PASS "$step_s" "$verdict, rmse/mean $rel"
  else
    row "$name" FAIL "$step_s" "$verdict, rmse/mean $rel"
  fi
}

hd=(builtin:cornell --width 1920 --height 1080 --spp 8 --seed 7)
step_compare_cuda_host() {
  render_row render_cuda_1080p 15 "${hd[@]}" --backend cuda --output "$images/cornell_cuda.exr"
  render_row render_host_1080p 25 "${hd[@]}" --backend host --output "$images/cornell_host.exr"
  compare_row compare_cuda_host "$images/cornell_host.exr" "$images/cornell_cuda.exr"
}

# compute-sanitizer on a small render, each kernel.
small=(render builtin:cornell --backend cuda --width 64 --height 64 --spp 2 --quiet)
sanitizer_row() {
  local name=$1 limit=$2 tool=$3 summary
  shift 3
  if ! command -v compute-sanitizer >/dev/null; then
    row "$name" FAIL 0.0 "compute-sanitizer not found"
    return
  fi
  run_step "$name" "$limit" compute-sanitizer --tool "$tool" "$@" --error-exitcode 99 \
    "$B/tandem" "${small[@]}" --output "$OUT/$name.png"
  summary=$(grep -E '(ERROR|RACECHECK) SUMMARY' "$OUT/$name.log" | tail -n 1 | sed 's/^=* *//')
  if skipped_row "$name"; then
    :
  elif [ "$step_rc" = 0 ] && [ -n "$summary" ]; then
    row "$name" PASS "$step_s" "$summary"
  elif timed_out; then
    row "$name" FAIL "$step_s" "timed out"
  else
    row "$name" FAIL "$step_s" "exit $step_rc: ${summary:-$(last_line "$name")}"
  fi
}
step_memcheck() { sanitizer_row memcheck 35 memcheck --leak-check full; }
step_racecheck() { sanitizer_row racecheck 35 racecheck; }
step_memcheck_wavefront() {
  small+=(--kernel wavefront)
  sanitizer_row memcheck_wavefront 25 memcheck
}

step_bench_gpu() {
  run_step bench_gpu 35 "$B/tandem" bench builtin:cornell --gpu --json "$OUT/bench_gpu.json"
  if [ "$step_rc" = 0 ] && [ ! -s "$OUT/bench_gpu.json" ]; then
    row bench_gpu FAIL "$step_s" "exit 0 but no $OUT/bench_gpu.json"
  else
    simple_row bench_gpu
  fi
}

duck=("$bundle/shared/scenes/gltf/Duck/glTF-Binary/Duck.glb" --width 960 --height 540 --spp 16
  --seed 11 --env-color 1)
step_compare_duck() {
  render_row render_duck_cuda_cpu 15 "${duck[@]}" --backend cuda+cpu --output "$images/duck_cuda_cpu.exr"
  render_row render_duck_cpu 15 "${duck[@]}" --backend cpu --output "$images/duck_cpu.exr"
  compare_row compare_duck "$images/duck_cpu.exr" "$images/duck_cuda_cpu.exr"
}

step_compare_wave_mega() {
  [ -f "$images/cornell_cuda.exr" ] ||
    render_row render_cuda_1080p 15 "${hd[@]}" --backend cuda --output "$images/cornell_cuda.exr"
  render_row render_wave_1080p 15 "${hd[@]}" --backend cuda --kernel wavefront \
    --output "$images/cornell_wave.exr"
  compare_row compare_wave_mega "$images/cornell_cuda.exr" "$images/cornell_wave.exr"
}

step_bench_hetero() {
  run_step bench_hetero 30 "$B/tandem" bench builtin:procedural --hetero cuda+cpu
  simple_row bench_hetero
}

# In the order of what a step tells, with limits that add up to the budget (10 + 70 + 45 +
# 35 + 35 + 25 + 35 + 35 + 20 + 30 = 340 s): a first run that runs out of time loses the
# least valuable steps, and STEPS reruns any of them.
for step in nvidia_smi tests_cuda compare_cuda_host memcheck racecheck memcheck_wavefront \
  bench_gpu compare_duck compare_wave_mega bench_hetero; do
  wanted "$step" && "step_$step"
done
