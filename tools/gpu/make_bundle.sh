#!/usr/bin/env bash
# Builds and checks the GPU bundle HERE (Debian 12, no GPU), from the project root:
#   tools/gpu/make_bundle.sh [BUILD_DIR]        (default BUILD_DIR: build/gpu-bundle)
# Builds tandem and every test binary with GPU tests (Release, CUDA on, no MPI, ccache), packs
# them into .gpu/bundle.tar.xz with the shared libraries a bare GPU machine lacks, the test
# data the run needs and run_on_gpu.sh, then checks the bundle: no binary or library of it may
# need a glibc newer than GLIBC_MAX (default 2.35, older than the 2.36 of the Debian 12
# machine that builds it), and the bundled binaries must start in a chroot that holds only
# the bundle and the system C/C++ runtime. It fails if anything else is needed.
# On the GPU machine, with .gpu/ in the project root: bash .gpu/run_on_gpu.sh.
# Environment: JOBS (build jobs, default 2), TANDEM_SHARED_DIR (default ../shared),
# GLIBC_MAX (default 2.35).
set -euo pipefail

die() {
  echo "make_bundle: error: $*" >&2
  exit 1
}
note() { echo "make_bundle: $*"; }

if [ ! -f CMakeLists.txt ] || [ ! -f tools/gpu/run_on_gpu.sh ]; then die "run from the project root"; fi
src=$(pwd)
build=${1:-$src/build/gpu-bundle}
shared=${TANDEM_SHARED_DIR:-$src/../shared}
out=$src/.gpu
jobs=${JOBS:-2}
glibc_max=${GLIBC_MAX:-2.35}
[ -d "$shared/scenes/gltf" ] || die "$shared/scenes/gltf: test data not found (set TANDEM_SHARED_DIR)"
grep -qx '/.gpu/' .gitignore || die ".gitignore lacks /.gpu/: the bundle must never be committed"

# The C/C++ runtime every Linux machine has (glibc, libstdc++, libgcc_s): never bundled, and
# the only libraries besides the bundle's the check below lets the binaries see. The CUDA
# libraries must not appear at all: cudart is linked statically and opens the driver itself.
system_runtime='^(linux-vdso\.so\.1|ld-linux-x86-64\.so\.2|libc\.so\.6|libm\.so\.6|libstdc\+\+\.so\.6|libgcc_s\.so\.1|libpthread\.so\.0|libdl\.so\.2|librt\.so\.1)$'

# --- build ------------------------------------------------------------------------------------
export PATH=/usr/local/cuda/bin:$PATH
command -v nvcc >/dev/null || die "nvcc not found (looked on PATH and in /usr/local/cuda/bin)"
launcher=()
if command -v ccache >/dev/null; then
  launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache -DCMAKE_CUDA_COMPILER_LAUNCHER=ccache)
fi
# Test binaries with GPU tests: the areas tests/CMakeLists.txt declares with GPU_TESTS.
gpu_tests=()  # "binary gtest-filter"
while read -r area filter; do
  gpu_tests+=("${area}_tests $filter")
done < <(sed -n 's/^ *tandem_test_area(\([a-z]*\) [^)]*GPU_TESTS "\([^"]*\)".*/\1 \2/p' tests/CMakeLists.txt)
[ ${#gpu_tests[@]} -gt 0 ] || die "tests/CMakeLists.txt declares no GPU_TESTS area"
targets=(tandem)
for t in "${gpu_tests[@]}"; do targets+=("${t%% *}"); done

note "configuring $build (Release, CUDA on, no MPI)"
mkdir -p "$build"
# No MPI: Open MPI's libraries (libevent_core among them) need a newer glibc than the
# binaries do, and a GPU run never renders distributed.
cmake -S "$src" -B "$build" -G Ninja -DCMAKE_BUILD_TYPE=Release -DTANDEM_CUDA=ON -DTANDEM_MPI=OFF \
  "${launcher[@]}" >"$build/configure.log" 2>&1 || {
  tail -20 "$build/configure.log"
  die "configure failed (log: $build.configure.log)"
}
note "building ${targets[*]} with $jobs jobs"
cmake --build "$build" -j "$jobs" --target "${targets[@]}"

# --- stage ------------------------------------------------------------------------------------
stage=$(mktemp -d)
chroot_dir=""
cleanup() {
  rm -rf "$stage"
  [ -z "$chroot_dir" ] || rm -rf "$chroot_dir"
}
trap cleanup EXIT
mkdir -p "$stage/bin" "$stage/lib" "$stage/lib-old-system" "$stage/shared/scenes/gltf"
binaries=()
for t in "${targets[@]}"; do
  f=$(find "$build" -maxdepth 3 -type f -name "$t" -perm -u+x -print -quit)
  [ -n "$f" ] || die "built target $t not found under $build"
  cp "$f" "$stage/bin/"
  binaries+=("$stage/bin/$t")
done
printf '%s\n' "${gpu_tests[@]}" >"$stage/gpu_tests.txt"

# Every library the loader resolves for the binaries, except the system runtime.
# (Pipes end in programs that read all their input: with pipefail, an early exit such as
# grep -q's would fail the producer with SIGPIPE.)
for b in "${binaries[@]}"; do
  deps=$(ldd "$b")
  if grep -q 'not found' <<<"$deps"; then die "$b: libraries not found here: $deps"; fi
  while read -r name path; do
    case $name in libcudart* | libcuda.so*)
      die "$(basename "$b") needs $name: the CUDA runtime must be linked statically" ;;
    esac
    [[ $name =~ $system_runtime ]] || cp -L "$path" "$stage/lib/"
  done < <(awk '$2 == "=>" && $3 ~ /^\// {print $1, $3}' <<<"$deps")
done
# TBB opens its scalable allocator at run time when present (not a NEEDED entry).
system_lib() { ldconfig -p | awk -v lib="$1" '$1 == lib && /x86-64/ && !found {print $NF; found = 1}'; }
tbbmalloc=$(system_lib libtbbmalloc.so.2)
[ -z "$tbbmalloc" ] || cp -L "$tbbmalloc" "$stage/lib/"
# GCC 12's libstdc++, only for a GPU image older than Debian 12; run_on_gpu.sh adds it to the
# search path only if the system's is too old, so it never shadows a newer one (ncu and
# compute-sanitizer need the system's).
cp -L "$(system_lib libstdc++.so.6)" "$stage/lib-old-system/"

# Test data: BoxTextured and Duck (run_on_gpu.sh renders Duck), plus every shared glTF model a
# GPU test source names; the bundled tests find it through $TANDEM_SHARED_DIR.
models=(BoxTextured Duck)
for t in "${gpu_tests[@]}"; do
  area=${t%%_tests *}
  for dir in "$shared"/scenes/gltf/*/; do
    name=$(basename "$dir")
    if grep -qE "[\"/]$name/" tests/"${area}"_*_test.cpp 2>/dev/null; then models+=("$name"); fi
  done
done
mapfile -t models < <(printf '%s\n' "${models[@]}" | sort -u)
for m in "${models[@]}"; do cp -r "$shared/scenes/gltf/$m" "$stage/shared/scenes/gltf/"; done
[ "$(du -sm "$stage/shared" | cut -f1)" -lt 40 ] || die "test data over 40 MB: ${models[*]}"

cp tools/gpu/run_on_gpu.sh tools/gpu/gtest_counts.sh "$stage/"

# The newest glibc any binary or library of the bundle needs (its version references), and no
# newer than GLIBC_MAX: a symbol of a newer glibc fails here, naming the file and the symbol,
# instead of every step on the GPU machine.
glibc_needed_by() {
  objdump -p "$1" | grep -oE 'GLIBC_[0-9]+\.[0-9]+' | sed 's/GLIBC_//' | sort -V | tail -n 1
}
glibc_needed=0
for f in "$stage"/bin/* "$stage"/lib/*; do
  v=$(glibc_needed_by "$f")
  [ -n "$v" ] || continue
  if [ "$(printf '%s\n%s\n' "$v" "$glibc_max" | sort -V | tail -n 1)" != "$glibc_max" ]; then
    sym=$(objdump -T "$f" | grep -m1 "GLIBC_$v" | awk '{print $NF}')
    die "$(basename "$f") needs glibc $v (symbol $sym): newer than GLIBC_MAX=$glibc_max"
  fi
  glibc_needed=$(printf '%s\n%s\n' "$v" "$glibc_needed" | sort -V | tail -n 1)
done
note "the bundle needs glibc $glibc_needed (at most $glibc_max allowed)"
{
  echo "commit $(git rev-parse HEAD 2>/dev/null || echo unknown)"
  echo "uncommitted changes: $(git status --porcelain 2>/dev/null | grep -vc '^??' || true)"
  echo "built $(date -u +%Y-%m-%dT%H:%M:%SZ) on $(sed -n 's/^PRETTY_NAME="*\([^"]*\)"*$/\1/p' /etc/os-release)"
  echo "nvcc $(nvcc --version | sed -n 's/.*release \([0-9.]*\).*/\1/p')"
  echo "binaries: ${targets[*]}"
  echo "libraries: $(cd "$stage/lib" && echo *)"
  echo "models: ${models[*]}"
  echo "glibc needed: $glibc_needed (every binary of bin/ and library of lib/)"
  echo "lib-old-system/libstdc++.so.6 needs glibc $(glibc_needed_by "$stage/lib-old-system/libstdc++.so.6")"
} >"$stage/BUNDLE_INFO"

# --- check ------------------------------------------------------------------------------------
# The binaries must start with the bundle's libraries and the system runtime alone.
note "checking the bundle"
for b in "${binaries[@]}"; do
  while read -r name path; do
    if [[ $path == "$stage/lib/"* ]] || [[ $name =~ $system_runtime ]]; then continue; fi
    die "$(basename "$b") resolves $name to $path: neither bundled nor system runtime"
  done < <(LD_LIBRARY_PATH=$stage/lib ldd "$b" | awk '$2 == "=>" {print $1, $3}')
  if LD_LIBRARY_PATH=$stage/lib ldd "$b" | grep 'not found'; then die "$(basename "$b"): libraries missing"; fi
done
smoke=("bin/tandem --version" "bin/tandem info builtin:cornell")
for t in "${gpu_tests[@]}"; do smoke+=("bin/${t%% *} --gtest_list_tests"); done
if [ "$(id -u)" = 0 ] && command -v chroot >/dev/null; then
  # A root file system holding only the bundle and the system runtime: nothing else to find.
  chroot_dir=$(mktemp -d)
  mkdir -p "$chroot_dir/lib64" "$chroot_dir/lib/x86_64-linux-gnu" "$chroot_dir/tmp"
  cp -r "$stage" "$chroot_dir/b"
  cp -L /lib64/ld-linux-x86-64.so.2 "$chroot_dir/lib64/"
  for l in libc.so.6 libm.so.6 libstdc++.so.6 libgcc_s.so.1; do
    cp -L "/lib/x86_64-linux-gnu/$l" "$chroot_dir/lib/x86_64-linux-gnu/"
  done
  for cmd in "${smoke[@]}"; do
    read -r -a argv <<<"$cmd"
    if ! log=$(env -i LD_LIBRARY_PATH=/b/lib TANDEM_SHARED_DIR=/b/shared \
      "$(command -v chroot)" "$chroot_dir" "/b/${argv[0]}" "${argv[@]:1}" 2>&1); then
      echo "$log" | tail -20
      die "'$cmd' fails in a chroot with only the bundle and the C/C++ runtime"
    fi
    note "ok (chroot): $cmd: ${log%%$'\n'*}"
  done
else
  note "not root: starting the binaries with the bundle's libraries first (less strict than a chroot)"
  for cmd in "${smoke[@]}"; do
    read -r -a argv <<<"$cmd"
    log=$(LD_LIBRARY_PATH=$stage/lib "$stage/${argv[0]}" "${argv[@]:1}" 2>&1) ||
      die "'$cmd' fails: $(echo "$log" | tail -5)"
    note "ok: $cmd: ${log%%$'\n'*}"
  done
fi

# --- pack -------------------------------------------------------------------------------------
mkdir -p "$out"
rm -rf "$out/out"
tar -cJf "$out/bundle.tar.xz.tmp" -C "$stage" .
mv "$out/bundle.tar.xz.tmp" "$out/bundle.tar.xz"
cp tools/gpu/run_on_gpu.sh tools/gpu/gtest_counts.sh "$out/"
note "bundle ready: $out/bundle.tar.xz ($(du -h "$out/bundle.tar.xz" | cut -f1)); contents:"
sed 's/^/  /' "$stage/BUNDLE_INFO"
note "on the GPU machine, from the project root: bash .gpu/run_on_gpu.sh"
