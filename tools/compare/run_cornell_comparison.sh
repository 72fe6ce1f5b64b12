#!/usr/bin/env bash
# Renders the Cornell box with Tandem and with Blender Cycles at identical
# settings, checks that the images agree (`tandem compare`), and compares
# the CPU render times.
#
#   tools/compare/run_cornell_comparison.sh [path/to/tandem]
#
# The tandem binary defaults to build/release/app/tandem. Settings come from
# the environment:
#   WIDTH=256 HEIGHT=256 SPP=1024 MAX_DEPTH=8 THREADS=2 BLOCK=16
#   CONTROL=1     also render Tandem with a second seed and pass it to
#                 `tandem compare --reference-noise` (a control test; 0 = skip)
#   OUT_DIR=DIR   where the EXRs go (default: a new temporary directory)
#   BLENDER=blender
#   VARIANT=cornell | spheres (no blocks; a mirror and a glass sphere:
#                 Tandem's builtin:cornell-spheres)
# MAX_DEPTH uses Tandem's convention (1 = direct light only); the Cycles
# script maps it to max_bounces = MAX_DEPTH - 1.
set -euo pipefail

here=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
root=$(cd "$here/../.." && pwd)
tandem=${1:-$root/build/release/app/tandem}
blender=${BLENDER:-blender}
width=${WIDTH:-256}
height=${HEIGHT:-256}
spp=${SPP:-1024}
depth=${MAX_DEPTH:-8}
threads=${THREADS:-2}
block=${BLOCK:-16}
control=${CONTROL:-1}
variant=${VARIANT:-cornell}
case "$variant" in
  cornell) scene=builtin:cornell ;;
  spheres) scene=builtin:cornell-spheres ;;
  *) echo "error: VARIANT must be cornell or spheres" >&2; exit 2 ;;
esac
out=${OUT_DIR:-$(mktemp -d "${TMPDIR:-/tmp}/tandem-cornell.XXXXXX")}

[[ -x "$tandem" ]] || { echo "error: tandem binary '$tandem' not found (build it or pass its path)" >&2; exit 1; }
command -v "$blender" >/dev/null || { echo "error: blender ('$blender') not found" >&2; exit 1; }
mkdir -p "$out"
tag="${variant}_${width}x${height}_${spp}spp_d${depth}"
echo "settings: ${width}x${height}, $spp spp, max depth $depth (Cycles max_bounces $((depth - 1))), $threads threads"
echo "output:   $out"
load_before=$(cut -d' ' -f1-3 /proc/loadavg)

now() { date +%s.%N; }
# Process CPU time (user + system) as a second, load-insensitive measure: on
# a shared machine other processes stretch wall times but not CPU seconds.
cpu_timer=()
[[ -x /usr/bin/time ]] && cpu_timer=(/usr/bin/time -f "%U %S" -o)
cpu_seconds() {  # file written by /usr/bin/time
  [[ -s "$1" ]] && awk 'END { printf "%.2f", $1 + $2 }' "$1" || echo "nan"
}

# Runs Tandem; echoes its own render time (from the summary line on stderr).
render_tandem() {  # seed output log
  local t0 t1
  t0=$(now)
  ${cpu_timer[@]:+"${cpu_timer[@]}" "$3.cpu"} "$tandem" render "$scene" --backend cpu --width "$width" --height "$height" --spp "$spp" \
    --max-depth "$depth" --threads "$threads" --seed "$1" --output "$2" 2>"$3"
  t1=$(now)
  # "tandem: 256x256, 1024 spp, max depth 8 on cpu (2 threads): 81.23 s, ..."
  local secs
  secs=$(sed -n 's/^tandem: .* threads): \([0-9.]*\) s,.*/\1/p' "$3" | tail -n 1)
  [[ -n "$secs" ]] || { cat "$3" >&2; echo "error: no summary line from tandem" >&2; exit 1; }
  echo "$secs $(echo "$t1 - $t0" | bc -l) $(cpu_seconds "$3.cpu")"
}

tandem_exr="$out/tandem_${tag}.exr"
cycles_exr="$out/cycles_${tag}.exr"
control_exr="$out/tandem_${tag}_seed1.exr"

echo "rendering with Tandem ..."
read -r tandem_s tandem_wall tandem_cpu < <(render_tandem 0 "$tandem_exr" "$out/tandem.log")

echo "rendering with Cycles ..."
t0=$(now)
${cpu_timer[@]:+"${cpu_timer[@]}" "$out/cycles.log.cpu"} "$blender" -b --factory-startup --python "$here/cycles_cornell.py" -- --spp "$spp" --max-depth "$depth" \
  --width "$width" --height "$height" --threads "$threads" --seed 0 --variant "$variant" --output "$cycles_exr" \
  >"$out/cycles.log" 2>&1 || { tail -n 30 "$out/cycles.log" >&2; echo "error: blender failed" >&2; exit 1; }
t1=$(now)
cycles_wall=$(echo "$t1 - $t0" | bc -l)
cycles_cpu=$(cpu_seconds "$out/cycles.log.cpu")
cycles_s=$(sed -n 's/^CYCLES_RENDER_SECONDS \([0-9.]*\)$/\1/p' "$out/cycles.log" | tail -n 1)
[[ -n "$cycles_s" && -f "$cycles_exr" ]] || { tail -n 30 "$out/cycles.log" >&2; exit 1; }

compare_args=(--block "$block")
if [[ "$control" != 0 ]]; then
  echo "rendering the control (Tandem, seed 1) ..."
  read -r _ _ _ < <(render_tandem 1 "$control_exr" "$out/tandem_control.log")
  compare_args+=(--reference-noise "$control_exr")
fi

echo
echo "== tandem compare (A = Tandem, B = Cycles) =="
"$tandem" compare "$tandem_exr" "$cycles_exr" "${compare_args[@]}" | tee "$out/compare.txt"
"$tandem" compare "$tandem_exr" "$cycles_exr" "${compare_args[@]}" --json >"$out/compare.json"

samples=$((width * height * spp))
echo
echo "== CPU speed, $threads threads, ${width}x${height}, $spp spp, max depth $depth =="
echo "load average before/after: $load_before / $(cut -d' ' -f1-3 /proc/loadavg)"
awk -v ts="$tandem_s" -v tw="$tandem_wall" -v tc="$tandem_cpu" -v cs="$cycles_s" -v cw="$cycles_wall" \
  -v cc="$cycles_cpu" -v n="$samples" 'BEGIN {
  printf "Tandem: render %8.2f s (%.3f M samples/s), process %8.2f s wall, %8s s CPU\n", ts, n / ts / 1e6, tw, tc
  printf "Cycles: render %8.2f s (%.3f M samples/s), process %8.2f s wall, %8s s CPU\n", cs, n / cs / 1e6, cw, cc
  printf "speed ratio (Cycles / Tandem): render time %.2fx, process wall %.2fx", cs / ts, cw / tw
  if (tc + 0 > 0 && cc + 0 > 0) printf ", process CPU %.2fx", cc / tc
  printf "\n"
}' | tee "$out/speed.txt"
