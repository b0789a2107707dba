#!/usr/bin/env bash
# The scripted checks' comparisons fail when their number is missing or not finite (a
# lost value must not pass as an empty string compared as text), and pass a real number.
set -u
. "$(dirname "$0")/check_number.sh"
fail=0
must_fail() { if "$@" >/dev/null; then echo "FAIL: passed: $*"; fail=1; fi; }
must_pass() { if ! "$@" >/dev/null; then echo "FAIL: failed: $*"; fail=1; fi; }
for bad in "" " " "nan" "NaN" "inf" "-inf" "abc" "1.2.3" "9 deg" "--" "1e" "e5"; do
  must_fail check_below "x" "$bad" 10
  must_fail check_between "x" "$bad" 0 10
done
must_pass check_below "x" 9.99 10
must_pass check_below "x" -3 10
must_pass check_below "x" 1.5e-3 10
must_pass check_below "x" .5 10
must_fail check_below "x" 10 10
must_fail check_below "x" 11 10
must_fail check_below "x" 1e2 10
must_pass check_between "x" 0 0 10
must_pass check_between "x" 10 0 10
must_fail check_between "x" 10.01 0 10
must_fail check_between "x" -0.01 0 10
# What it prints names the check and the value.
[ "$(check_below "light error (deg)" "" 10)" = "light error (deg): no number (got '')" ] || { echo "FAIL: message"; fail=1; }
[ "$fail" -eq 0 ] && echo "check_number ok"
exit "$fail"
