#!/usr/bin/env bash
# Runs ON the GPU machine, from the project root there, with .gpu/ (made by
# tools/gpu/make_bundle.sh) in it:   bash .gpu/run_on_gpu.sh
# Unpacks the bundle, then: nvidia-smi; every GPU test (a skip counts as a failure);
# compute-sanitizer memcheck and racecheck of a small CUDA render; a 1080p CUDA render against
# the host backend (the same kernels on the CPU) and a cuda+cpu render of a textured model
# against the CPU backend, both through `tandem compare`; `tandem bench --gpu` and a cuda+cpu
# bench. Every step has a timeout and the whole run a budget (BUDGET_S, default 330 s), so it
# ends within 6 minutes. Logs go to $OUT (default /tmp/tandem-gpu), copied to .gpu/out; a
# summary table (step, PASS/FAIL/SKIP, seconds, key figure) is printed last. The compared
# .exr renders go to $IMAGES_DIR (default /tmp/tandem-gpu-images), not to $OUT.
# A step the budget leaves no time for is a SKIP. Exit code: 0 when every step passed, else 1.
set -uo pipefail # no -e: every step runs, and the table tells which failed

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
OUT=${OUT:-/tmp/tandem-gpu}
bundle=${BUNDLE_DIR:-/tmp/tandem-bundle}
# The large linear images stay out of $OUT, which should come back small.
images=${IMAGES_DIR:-/tmp/tandem-gpu-images}
budget=${BUDGET_S:-330}
t_start=$(date +%s.%N)
mkdir -p "$OUT" "$images"
# Nothing of an earlier run may pass for this one's.
rm -f "$OUT"/*.log "$OUT"/*.xml "$OUT"/*.png "$OUT"/bench_gpu.json "$images"/*.exr
rows=()
step_rc=0 step_s=0 step_skipped=0

elapsed() { awk -v a="$1" -v b="$(date +%s.%N)" 'BEGIN { printf "%.1f", b - a }'; }
row() { rows+=("$1|$2|$3|$4"); } # step, status, seconds, key figure

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

# --- the bundle -------------------------------------------------------------------------------
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
  for b in "$B"/*; do ldd "$b" 2>&1; done
} >>"$OUT/bundle.log"
if grep -q 'not found' "$OUT/bundle.log"; then
  row bundle FAIL "$(elapsed "$t0")" "$(grep -m1 'not found' "$OUT/bundle.log" | cut -c1-70)"
else
  row bundle PASS "$(elapsed "$t0")" "$(sed -n 's/^commit \(.\{12\}\).*/commit \1/p' "$bundle/BUNDLE_INFO")"
fi

# --- the machine ------------------------------------------------------------------------------
run_step nvidia_smi 20 bash -c 'nvidia-smi && nvidia-smi --query-gpu=name,driver_version,memory.total,clocks.max.sm --format=csv,noheader'
if [ "$step_rc" = 0 ]; then
  row nvidia_smi PASS "$step_s" "$(last_line nvidia_smi)"
else
  row nvidia_smi FAIL "$step_s" "no GPU or no driver: $(last_line nvidia_smi)"
fi

# --- the GPU tests: a skip is a failure here ----------------------------------------------------
while read -r binary filter; do
  [ -n "$binary" ] || continue
  name=tests_${binary%_tests}
  run_step "$name" 150 "$B/$binary" "--gtest_filter=$filter" "--gtest_output=xml:$OUT/$name.xml"
  log=$OUT/$name.log
  # One result line per test: "[       OK ] Suite.Name (12 ms)".
  n_ok=$(grep -cE '^\[ +OK \] .* \([0-9]+ ms\)$' "$log")
  n_skip=$(grep -cE '^\[ +SKIPPED \] .* \([0-9]+ ms\)$' "$log")
  n_fail=$(grep -cE '^\[ +FAILED \] .* \([0-9]+ ms\)$' "$log")
  figure="$n_ok passed, $n_skip skipped, $n_fail failed ($filter)"
  if skipped_row "$name"; then
    :
  elif timed_out; then
    row "$name" FAIL "$step_s" "timed out after $figure"
  elif [ "$step_rc" = 0 ] && [ "$n_skip" = 0 ] && [ "$n_ok" -gt 0 ]; then
    row "$name" PASS "$step_s" "$figure"
  else
    row "$name" FAIL "$step_s" "$figure, exit $step_rc"
  fi
done <"$bundle/gpu_tests.txt"

# --- compute-sanitizer on a small render ----------------------------------------------------------
small=(render builtin:cornell --backend cuda --width 64 --height 64 --spp 2 --quiet)
for tool in memcheck racecheck; do
  extra=()
  [ "$tool" = memcheck ] && extra=(--leak-check full)
  if ! command -v compute-sanitizer >/dev/null; then
    row "$tool" FAIL 0.0 "compute-sanitizer not found"
    continue
  fi
  run_step "$tool" 75 compute-sanitizer --tool "$tool" "${extra[@]}" --error-exitcode 99 \
    "$B/tandem" "${small[@]}" --output "$OUT/$tool.png"
  summary=$(grep -E '(ERROR|RACECHECK) SUMMARY' "$OUT/$tool.log" | tail -n 1 | sed 's/^=* *//')
  if skipped_row "$tool"; then
    :
  elif [ "$step_rc" = 0 ] && [ -n "$summary" ]; then
    row "$tool" PASS "$step_s" "$summary"
  elif timed_out; then
    row "$tool" FAIL "$step_s" "timed out"
  else
    row "$tool" FAIL "$step_s" "exit $step_rc: ${summary:-$(last_line "$tool")}"
  fi
done

# The wavefront's queue kernels under memcheck too (racecheck of the megakernel above).
if command -v compute-sanitizer >/dev/null; then
  run_step memcheck_wavefront 75 compute-sanitizer --tool memcheck --error-exitcode 99 \
    "$B/tandem" "${small[@]}" --kernel wavefront --output "$OUT/memcheck_wavefront.png"
  summary=$(grep -E 'ERROR SUMMARY' "$OUT/memcheck_wavefront.log" | tail -n 1 | sed 's/^=* *//')
  if skipped_row memcheck_wavefront; then
    :
  elif [ "$step_rc" = 0 ] && [ -n "$summary" ]; then
    row memcheck_wavefront PASS "$step_s" "$summary"
  else
    row memcheck_wavefront FAIL "$step_s" "exit $step_rc: ${summary:-$(last_line memcheck_wavefront)}"
  fi
fi

# --- renders compared ---------------------------------------------------------------------------
# render_row NAME ARGS...: a render step; the key figure is tandem's throughput summary.
render_row() {
  local name=$1
  shift
  run_step "$name" 60 "$B/tandem" render "$@"
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
  run_step "$name" 20 "$B/tandem" compare "$a" "$b" --json
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
render_row render_cuda_1080p "${hd[@]}" --backend cuda --output "$images/cornell_cuda.exr"
render_row render_host_1080p "${hd[@]}" --backend host --output "$images/cornell_host.exr"
compare_row compare_cuda_host "$images/cornell_host.exr" "$images/cornell_cuda.exr"
render_row render_wave_1080p "${hd[@]}" --backend cuda --kernel wavefront \
  --output "$images/cornell_wave.exr"
compare_row compare_wave_mega "$images/cornell_cuda.exr" "$images/cornell_wave.exr"

duck=("$bundle/shared/scenes/gltf/Duck/glTF-Binary/Duck.glb" --width 960 --height 540 --spp 16
  --seed 11 --env-color 1)
render_row render_duck_cuda_cpu "${duck[@]}" --backend cuda+cpu --output "$images/duck_cuda_cpu.exr"
render_row render_duck_cpu "${duck[@]}" --backend cpu --output "$images/duck_cpu.exr"
compare_row compare_duck "$images/duck_cpu.exr" "$images/duck_cuda_cpu.exr"

# --- benchmarks ---------------------------------------------------------------------------------
run_step bench_gpu 45 "$B/tandem" bench builtin:cornell --gpu --json "$OUT/bench_gpu.json"
if [ "$step_rc" = 0 ] && [ ! -s "$OUT/bench_gpu.json" ]; then
  row bench_gpu FAIL "$step_s" "exit 0 but no $OUT/bench_gpu.json"
else
  simple_row bench_gpu
fi
run_step bench_hetero 60 "$B/tandem" bench builtin:procedural --hetero cuda+cpu
simple_row bench_hetero
