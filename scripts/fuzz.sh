#!/usr/bin/env bash
# Builds the libFuzzer targets with clang (ASan + UBSan) into ./build-fuzz and runs each
# for a bounded time (default 60 s per target; first argument overrides), starting from
# tests/fuzz/corpus/<target>. A crash input is copied to tests/fuzz/regressions/<target>/,
# where the normal test run (ctest: fuzz_<target>_regressions) replays it from then on.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds="${1:-60}"
targets=(ply scene_json image oni)
bash scripts/install-deps.sh
CC=clang CXX=clang++ cmake -S . -B build-fuzz -DCMAKE_BUILD_TYPE=RelWithDebInfo \
  -DLIGHTPROBE_BUILD_FUZZERS=ON -DLIGHTPROBE_BUILD_TESTS=OFF >/dev/null
cmake --build build-fuzz -j "$(nproc)" --target "${targets[@]/#/fuzz_}"
status=0
for t in "${targets[@]}"; do
  work="build-fuzz/runs/$t"
  rm -rf "$work" && mkdir -p "$work/corpus" "$work/crashes"
  cp tests/fuzz/corpus/"$t"/* "$work/corpus/"
  echo "== fuzz_$t for ${seconds} s"
  # ASan: a corrupt header may not allocate more than 2 GiB.
  if ! ASAN_OPTIONS=allocator_may_return_null=1:detect_leaks=1 \
      "build-fuzz/tests/fuzz/fuzz_$t" -max_total_time="$seconds" -rss_limit_mb=4096 -malloc_limit_mb=2048 \
      -timeout=20 -artifact_prefix="$work/crashes/" "$work/corpus" >"$work/log.txt" 2>&1; then
    status=1
    tail -n 40 "$work/log.txt"
    for f in "$work"/crashes/*; do
      [ -e "$f" ] || continue
      cp "$f" "tests/fuzz/regressions/$t/"
      echo "kept $(basename "$f") in tests/fuzz/regressions/$t/"
    done
  else
    grep -E "^(#[0-9]+ +DONE|Done)" "$work/log.txt" | tail -n 1 || true
  fi
done
exit $status
