#!/usr/bin/env bash
# The fuzz campaign (docs/reliability.md). Builds the libFuzzer targets with clang (ASan +
# UBSan) into ./build-fuzz and runs each for a bounded time from its corpus:
#   scripts/fuzz.sh [SECONDS] [TARGET ...]      (default 60 s each, every target)
#   LP_FUZZ_JOBS=2 scripts/fuzz.sh 600          (two targets at a time)
# Each run starts from tests/fuzz/corpus/<target> plus what earlier runs here found, and
# merges what it found into tests/fuzz/corpus/<target> (libFuzzer's -merge=1: only inputs
# that add coverage), so a campaign can go on in a later session from the committed corpus.
# A crash, leak, timeout (> 10 s) or out-of-memory input is copied to
# tests/fuzz/regressions/<target>/, where the normal test run (ctest:
# fuzz_<target>_regressions) replays it from then on. Then every target's corpus is
# replayed in the Release build (./build) and the slowest input is reported: inputs under
# 1 MB must be parsed or refused within 1 s there (a measurement, not a test).
# Nothing here runs in CI. A summary line per target goes to build-fuzz/runs/summary.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
shift || true
all=(ply scene_json image oni calibration poses side_file truth lights script)
[ $# -gt 0 ] && targets=("$@") || targets=("${all[@]}")
jobs="${LP_FUZZ_JOBS:-1}"
bash scripts/install-deps.sh
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLIGHTPROBE_BUILD_FUZZERS=ON -DLIGHTPROBE_BUILD_TESTS=OFF >/dev/null
cmake --build build-fuzz -j "$(nproc)" --target "${targets[@]/#/fuzz_}"
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release >/dev/null
# shellcheck disable=SC2046
cmake --build build -j "$(nproc)" --target $(printf 'fuzz_%s_replay ' "${targets[@]}")

fuzz_one() {
  local t="$1" seconds="$2" work="build-fuzz/runs/$1"
  mkdir -p "$work/corpus" "$work/crashes" "$work/merged"
  cp -n tests/fuzz/corpus/"$t"/* "$work/corpus/" 2>/dev/null || true
  local status=0
  # ASan: a corrupt header may not allocate more than 2 GiB.
  ASAN_OPTIONS=allocator_may_return_null=1:detect_leaks=1 \
    "build-fuzz/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -rss_limit_mb=4096 -malloc_limit_mb=2048 \
    -timeout=10 -print_final_stats=1 -artifact_prefix="$work/crashes/" "$work/corpus" >"$work/log.txt" 2>&1 ||
    status=1
  local found=0
  for f in "$work"/crashes/*; do
    [ -e "$f" ] || continue
    cp "$f" "tests/fuzz/regressions/$t/" && found=$((found + 1))
    echo "fuzz_$t: kept $(basename "$f") in tests/fuzz/regressions/$t/"
  done
  rm -f "$work"/crashes/*
  # The committed corpus gains what adds coverage.
  ASAN_OPTIONS=allocator_may_return_null=1:detect_leaks=0 \
    "build-fuzz/tests/fuzz/fuzz_$t" -merge=1 -timeout=10 -rss_limit_mb=4096 -malloc_limit_mb=2048 \
    "tests/fuzz/corpus/$t" "$work/corpus" >"$work/merge.txt" 2>&1 || true
  local execs cov corp slow
  execs=$(grep -E "^stat::number_of_executed_units:" "$work/log.txt" | awk '{print $2}' | tail -n 1)
  cov=$(grep -oE "cov: [0-9]+ ft: [0-9]+" "$work/log.txt" | tail -n 1)
  corp=$(find "tests/fuzz/corpus/$t" -type f | wc -l)
  slow=$("build/tests/fuzz/fuzz_${t}_replay" "$work/corpus" "tests/fuzz/regressions/$t" | grep '^slowest input' || echo "slowest input: none")
  local line
  line="fuzz_$t: ${seconds} s, ${execs:-?} executions, ${cov:-cov: ?}, corpus ${corp} files, findings ${found}, exit $([ $status = 0 ] && echo ok || echo FAILED); Release ${slow}"
  echo "$line" | tee -a build-fuzz/runs/summary.txt
  [ "$status" = 0 ] || tail -n 30 "$work/log.txt"
  return "$status"
}
export -f fuzz_one
mkdir -p build-fuzz/runs
echo "== $(date -u +%F' '%T) UTC: ${targets[*]} for ${seconds} s each, ${jobs} at a time" | tee -a build-fuzz/runs/summary.txt
printf '%s\n' "${targets[@]}" | xargs -P "$jobs" -I{} bash -c 'fuzz_one "$@"' _ {} "$seconds"
