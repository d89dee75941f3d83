#!/usr/bin/env bash
# Fuzzes the scene and mesh readers with libFuzzer under AddressSanitizer and UBSan (issue 6,
# "Hostile input"). Installs the missing Debian packages (those of build.sh plus clang), builds
# the five targets of tests/fuzz in build-fuzz/, then runs them one after the other:
#   scripts/fuzz.sh                     each target for 600 s
#   scripts/fuzz.sh 60                  each target for 60 s
#   scripts/fuzz.sh 60 fuzz_msh         one target (fuzz_scene, fuzz_msh, fuzz_obj, fuzz_stl, fuzz_ply)
# Each run starts from the seed corpus kept in the repository (valid inputs in
# tests/data/fuzz/<target>/, nasty ones in tests/data/nasty/ and tests/data/meshes/) and writes the inputs it finds interesting to build-fuzz/corpus/<target>/
# (kept between runs, never in the repository). A finding (crash, sanitizer report, hang over
# 10 s, more than 2 GB, an escaped std::bad_alloc or a bad error message: tests/fuzz/
# fuzz_support.hpp) stops that target, its reproducer is saved in build-fuzz/findings/<target>/,
# and the script exits non-zero after the remaining targets. Replay one input with
#   build-fuzz/tests/<target> <file>
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=${1:-600}
shift || true
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=(fuzz_scene fuzz_msh fuzz_obj fuzz_stl fuzz_ply)

source scripts/install_packages.sh
install_missing "${nexdyn_packages[@]}" clang-14 libclang-rt-14-dev

build_dir=build-fuzz
# The targets live under tests/ (NEXDYN_TESTS on), but only they are built.
cmake -S . -B "$build_dir" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo \
      -DCMAKE_C_COMPILER=clang-14 -DCMAKE_CXX_COMPILER=clang++-14 \
      -DNEXDYN_FUZZ=ON -DNEXDYN_SANITIZE=address,undefined -DNEXDYN_TESTS=ON -DNEXDYN_BENCH=OFF >/dev/null
cmake --build "$build_dir" -j "$(nproc)" --target "${targets[@]}"

export UBSAN_OPTIONS=print_stacktrace=1
failed=()
for target in "${targets[@]}"; do
  corpus="$build_dir/corpus/$target"
  findings="$build_dir/findings/$target"
  mkdir -p "$corpus" "$findings"
  echo "fuzz.sh: $target for ${seconds} s (log: $build_dir/$target.log)"
  status=0
  # Seeds: the target's valid inputs, the nasty-input corpus of the regression tests, and for
  # the .msh reader the bad meshes of its own tests, for the STL and PLY readers the surface files
  # of theirs. Only "$corpus" is written to.
  seeds=("tests/data/fuzz/$target" tests/data/nasty)
  [ "$target" = fuzz_msh ] && seeds+=(tests/data/meshes)
  [ "$target" = fuzz_stl ] || [ "$target" = fuzz_ply ] && seeds+=(tests/data/meshes/surfaces)
  "$build_dir/tests/$target" "$corpus" "${seeds[@]}" -dict="tests/data/fuzz/$target.dict" \
      -max_total_time="$seconds" -rss_limit_mb=2048 -malloc_limit_mb=2048 -timeout=10 \
      -artifact_prefix="$findings/" -print_final_stats=1 >"$build_dir/$target.log" 2>&1 || status=$?
  if [ "$status" -eq 0 ]; then
    grep -E "^#[0-9]+[[:space:]]+DONE|^Done|^stat::" "$build_dir/$target.log" || true
  else
    tail -n 40 "$build_dir/$target.log"
    echo "fuzz.sh: $target FOUND A PROBLEM (exit $status); reproducer:" \
         "$(grep -o "$findings/[^ ]*" "$build_dir/$target.log" | tail -n 1)"
    failed+=("$target")
  fi
done
if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: findings in ${failed[*]} (see $build_dir/findings/)" >&2
  exit 1
fi
echo "fuzz.sh: no finding in ${targets[*]} after ${seconds} s each"
