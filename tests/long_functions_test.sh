#!/usr/bin/env bash
# No function over 80 lines outside tests (docs/architecture.md, Style): scripts/long-functions.py
# over the product's folders finds none; and it does find one, in a file made here with a
# function of 81 lines (signature to closing brace) beside one of 80 (so the check itself
# can fail).
set -u
root=$(cd "$(dirname "$0")/.." && pwd)
script="$root/scripts/long-functions.py"
fail=0
if ! python3 "$script" --max 80 "$root"/{app,calibration,capture,common,estimation,exports,reconstruction,scene,ui}; then
  echo "FAIL: functions over 80 lines (above)"; fail=1
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
{
  echo "int Short() {"; for i in $(seq 1 77); do echo "  int a$i = $i;"; done; echo "  return 0;"; echo "}"
  echo "int Long() {"; for i in $(seq 1 78); do echo "  int b$i = $i;"; done; echo "  return 0;"; echo "}"
} > "$tmp/sample.cpp"
out=$(python3 "$script" --max 80 "$tmp")
if [ $? -eq 0 ] || ! grep -q "Long" <<< "$out" || grep -q "Short" <<< "$out"; then
  echo "FAIL: long-functions.py did not flag exactly the 81-line function (and not the 80-line one): $out"; fail=1
fi
[ $fail -eq 0 ] && echo "1 passed, 0 failed" || echo "0 passed, 1 failed"
exit $fail
