#!/usr/bin/env bash
# Builds the input-handling tests with AddressSanitizer + UBSan (into ./build-asan) and runs
# them: corrupt, truncated and empty .oni files, record/replay through OpenNI2, bad scene
# bundles and meshes, the stability cases, reconstruction (bad frames, real and synthetic
# sequences), calibration (malformed files, fits). Any memory error fails the run.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/install-deps.sh
cmake -S . -B build-asan -DCMAKE_BUILD_TYPE=RelWithDebInfo -DLIGHTPROBE_SANITIZE=ON >/dev/null
tests=(openni_test dir_source_test capture_thread_test io_test stability_test reconstruction_test calibration_test
       vertex_radiance_test albedo_test ui_session_test parallel_test)
cmake --build build-asan -j "$(nproc)" --target "${tests[@]}"
# OpenNI2 itself is not instrumented and leaks at exit by design: leak checks off.
export ASAN_OPTIONS=detect_leaks=0:abort_on_error=1 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1
for t in "${tests[@]}"; do
  echo "== $t (ASan + UBSan)"
  "build-asan/tests/$t" --gtest_brief=1
done
