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
#                 Tandem's builtin:cornell-spheres) | helmet (a glTF model,
#                 GLTF=path, default the shared FlightHelmet, under Tandem's
#                 built-in sky, through cycles_gltf.py)
#   CYCLES_CONTROL=1  also render Cycles with seed 1, so that Cycles' noise
#                 comes from two Cycles images instead of from the Tandem-
#                 Cycles RMSE (which would count any systematic difference
#                 between the two as noise); default 1 for helmet, else 0
#   SETUP=1       also time the fixed cost before the first sample (Tandem:
#                 a 1-spp render; Cycles: the log's first "Sample" line) and
#                 report samples/s of the sampling alone; default 1 for
#                 helmet (image loading and BVH build are seconds), else 0
#   VARIANT=many-lights  Tandem's builtin:many-lights (1,537 emissive
#                 instances, 8 points and spots), written by `tandem export`
#                 and imported into Cycles with its own camera, lights at
#                 Tandem's intensities and a black world (cycles_gltf.py);
#                 the noise is also compared relative to each image's mean,
#                 as the two BSDF models do not give the same brightness
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
cycles_script=$here/cycles_cornell.py
cycles_scene_args=(--variant "$variant")
default_extra=0
case "$variant" in
  cornell) scene=builtin:cornell ;;
  spheres) scene=builtin:cornell-spheres ;;
  helmet)
    scene=${GLTF:-$root/../shared/scenes/gltf/FlightHelmet/glTF/FlightHelmet.gltf}
    [[ -f "$scene" ]] || { echo "error: glTF file '$scene' not found (set GLTF=path)" >&2; exit 1; }
    cycles_script=$here/cycles_gltf.py
    cycles_scene_args=(--gltf "$scene" --sky "$root/data/env/sky.hdr")
    default_extra=1
    ;;
  many-lights)
    scene=builtin:many-lights
    cycles_script=$here/cycles_gltf.py
    default_extra=1
    ;;
  *) echo "error: VARIANT must be cornell, spheres, helmet or many-lights" >&2; exit 2 ;;
esac
cycles_control=${CYCLES_CONTROL:-$default_extra}
setup=${SETUP:-$default_extra}
out=${OUT_DIR:-$(mktemp -d "${TMPDIR:-/tmp}/tandem-cornell.XXXXXX")}

[[ -x "$tandem" ]] || { echo "error: tandem binary '$tandem' not found (build it or pass its path)" >&2; exit 1; }
command -v "$blender" >/dev/null || { echo "error: blender ('$blender') not found" >&2; exit 1; }
if [[ "$variant" == helmet ]]; then
  # Blender's glTF importer needs numpy in Blender's Python (Debian: the
  # python3-numpy package): say so now rather than after Tandem's render.
  # `|| probe=$?`: under set -e a bare non-zero status would end the script
  # here, silently, before the message below.
  probe=0
  "$blender" -b --factory-startup --python-expr \
    'import os, sys
try:
    import numpy
except ImportError:
    sys.stdout.flush(); os._exit(3)
os._exit(0)' >/dev/null 2>&1 || probe=$?
  case $probe in
    0) ;;
    3) echo "error: VARIANT=helmet needs numpy in Blender's Python for its glTF importer" \
            "(Debian/Ubuntu: apt-get install python3-numpy)" >&2; exit 1 ;;
    *) echo "error: blender ('$blender') failed to start" >&2; exit 1 ;;
  esac
fi
mkdir -p "$out"
if [[ "$variant" == many-lights ]]; then
  "$tandem" export "$scene" --output "$out/many-lights.gltf" >/dev/null
  cycles_scene_args=(--gltf "$out/many-lights.gltf" --sky none --gltf-camera)
fi
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
render_tandem() {  # seed output log [spp]
  local t0 t1
  t0=$(now)
  ${cpu_timer[@]:+"${cpu_timer[@]}" "$3.cpu"} "$tandem" render "$scene" --backend cpu --width "$width" --height "$height" --spp "${4:-$spp}" \
    --max-depth "$depth" --threads "$threads" --seed "$1" --output "$2" 2>"$3"
  t1=$(now)
  # "tandem: 256x256, 1024 spp, max depth 8 on cpu (2 threads): loaded in 0.01 s, rendered in 81.23 s, ..."
  local secs
  secs=$(sed -n 's/^tandem: .* rendered in \([0-9.]*\) s,.*/\1/p' "$3" | tail -n 1)
  [[ -n "$secs" ]] || { cat "$3" >&2; echo "error: no summary line from tandem" >&2; exit 1; }
  echo "$secs $(echo "$t1 - $t0" | bc -l) $(cpu_seconds "$3.cpu")"
}

tandem_exr="$out/tandem_${tag}.exr"
cycles_exr="$out/cycles_${tag}.exr"
control_exr="$out/tandem_${tag}_seed1.exr"

echo "rendering with Tandem ..."
read -r tandem_s tandem_wall tandem_cpu < <(render_tandem 0 "$tandem_exr" "$out/tandem.log")

render_cycles() {  # seed output log
  ${cpu_timer[@]:+"${cpu_timer[@]}" "$3.cpu"} "$blender" -b --factory-startup --python "$cycles_script" -- --spp "$spp" --max-depth "$depth" \
    --width "$width" --height "$height" --threads "$threads" --seed "$1" "${cycles_scene_args[@]}" \
    --output "$2" >"$3" 2>&1 || { tail -n 30 "$3" >&2; echo "error: blender failed" >&2; exit 1; }
}

echo "rendering with Cycles ..."
t0=$(now)
render_cycles 0 "$cycles_exr" "$out/cycles.log"
t1=$(now)
cycles_wall=$(echo "$t1 - $t0" | bc -l)
cycles_cpu=$(cpu_seconds "$out/cycles.log.cpu")
cycles_s=$(sed -n 's/^CYCLES_RENDER_SECONDS \([0-9.]*\)$/\1/p' "$out/cycles.log" | tail -n 1)
[[ -n "$cycles_s" && -f "$cycles_exr" ]] || { tail -n 30 "$out/cycles.log" >&2; exit 1; }

if [[ "$cycles_control" != 0 ]]; then
  echo "rendering the Cycles control (seed 1) ..."
  render_cycles 1 "$out/cycles_${tag}_seed1.exr" "$out/cycles_control.log"
fi
tandem_setup_s=nan cycles_setup_s=nan
if [[ "$setup" != 0 ]]; then
  echo "timing Tandem's fixed cost (1 spp) ..."
  read -r tandem_one_s _ _ < <(render_tandem 0 "$out/tandem_1spp.exr" "$out/tandem_1spp.log" 1)
  # The 1-spp render is the fixed cost plus one sample per pixel.
  tandem_setup_s=$(awk -v one="$tandem_one_s" -v all="$tandem_s" -v n="$spp" \
    'BEGIN { printf "%.3f", (n * one - all) / (n - 1) }')
  # Cycles' progress lines carry the time since the render started; the
  # first "Sample" line comes when sampling begins.
  cycles_setup_s=$(awk -F'Time:' '/\| Sample [0-9]+\// { split($2, f, " "); n = split(f[1], t, ":");
    s = 0; for (i = 1; i <= n; ++i) s = s * 60 + t[i]; printf "%.3f", s; exit }' "$out/cycles.log")
  [[ -n "$cycles_setup_s" ]] || cycles_setup_s=nan
fi

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

if [[ "$setup" != 0 ]]; then
  awk -v ts="$tandem_s" -v cs="$cycles_s" -v tsu="$tandem_setup_s" -v csu="$cycles_setup_s" -v n="$samples" 'BEGIN {
    printf "fixed cost before sampling: Tandem %.2f s, Cycles %.2f s\n", tsu, csu
    printf "sampling alone: Tandem %.3f M samples/s, Cycles %.3f M samples/s, ratio (Cycles / Tandem time) %.2fx\n",
      n / (ts - tsu) / 1e6, n / (cs - csu) / 1e6, (cs - csu) / (ts - tsu)
  }' | tee -a "$out/speed.txt"
fi

# Per-pixel noise sigma (the standard deviation of one pixel channel of the
# image), from RMSEs between renders: two seeds of one renderer differ by
# sqrt(2) sigma; Tandem and Cycles by sqrt(sigma_T^2 + sigma_C^2 + bias^2).
rmse_of() { "$tandem" compare "$1" "$2" --block "$block" --json | sed -n 's/.*"rmse": \([0-9.eE+-]*\).*/\1/p'; }
if [[ "$control" != 0 ]]; then
  rmse_tt=$(rmse_of "$tandem_exr" "$control_exr")
  rmse_tc=$(sed -n 's/.*"rmse": \([0-9.eE+-]*\).*/\1/p' "$out/compare.json")
  rmse_cc=nan
  [[ "$cycles_control" != 0 ]] && rmse_cc=$(rmse_of "$cycles_exr" "$out/cycles_${tag}_seed1.exr")
  echo
  echo "== per-pixel noise, $spp spp =="
  # Each image's mean over its channels: the noise relative to it compares
  # renderers whose materials differ in brightness.
  means=$(sed -n 's/.*"mean_a": \[\([^]]*\)\], "mean_b": \[\([^]]*\)\].*/\1,\2/p' "$out/compare.json" |
    awk -F, '{ printf "%.9g %.9g", ($1 + $2 + $3) / 3, ($4 + $5 + $6) / 3 }')
  read -r mean_t mean_c <<<"$means"
  awk -v tt="$rmse_tt" -v tc="$rmse_tc" -v cc="$rmse_cc" -v ts="$tandem_s" -v cs="$cycles_s" \
    -v mt="${mean_t:-nan}" -v mc="${mean_c:-nan}" \
    -v tcpu="$tandem_cpu" -v ccpu="$cycles_cpu" -v tsu="$tandem_setup_s" -v csu="$cycles_setup_s" 'BEGIN {
    st = tt / sqrt(2)
    if (cc != "nan") { sc = cc / sqrt(2); how = "two Cycles seeds" }
    else { v = tc * tc - st * st; sc = v > 0 ? sqrt(v) : 0; how = "Tandem-Cycles RMSE less Tandem noise" }
    printf "RMSE Tandem seeds %.6g, Tandem-Cycles %.6g", tt, tc
    if (cc != "nan") printf ", Cycles seeds %.6g", cc
    printf "\n"
    printf "sigma: Tandem %.6g, Cycles %.6g (%s); ratio Cycles / Tandem %.3f\n", st, sc, how, sc / st
    if (cc != "nan") {
      b = tc * tc - st * st - sc * sc
      d = (b > 0) ? sqrt(b) : 0
      printf "Tandem-Cycles difference beyond noise (RMS): %.6g (%.2f sigma_T)\n", d, d / st
    }
    r = sc * sc / (st * st)  # Tandem needs 1 / r times Cycles samples for equal noise
    printf "to equal noise (Cycles / Tandem time): render %.2fx", cs / ts * r
    if (tcpu + 0 > 0 && ccpu + 0 > 0) printf ", process CPU %.2fx", ccpu / tcpu * r
    if (tsu != "nan" && csu != "nan") printf ", sampling alone %.2fx", (cs - csu) / (ts - tsu) * r
    printf "\n"
    if (mt + 0 > 0 && mc + 0 > 0) {
      rr = (sc / mc) * (sc / mc) / ((st / mt) * (st / mt))
      printf "image means: Tandem %.6g, Cycles %.6g; relative sigma: Tandem %.6g, Cycles %.6g\n", mt, mc, st / mt, sc / mc
      printf "to equal relative noise (Cycles / Tandem time): render %.2fx", cs / ts * rr
      if (tsu != "nan" && csu != "nan") printf ", sampling alone %.2fx", (cs - csu) / (ts - tsu) * rr
      printf "\n"
    }
  }' | tee "$out/noise.txt"
fi
