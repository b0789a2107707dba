#!/usr/bin/env bash
# The window from the command line: no display says so and points to --headless; with no
# input and no camera it opens the bundled demo recording; a bad script is one clear line.
set -u
exe=$1; src=$2
out=$(mktemp -d); trap 'rm -rf "$out"' EXIT
fail() { echo "FAIL: $*"; exit 1; }

# No display: exit 2, one line naming --headless.
env -u DISPLAY -u WAYLAND_DISPLAY "$exe" >"$out/nodisplay" 2>&1; rc=$?
[ "$rc" -eq 2 ] || fail "no display: exit $rc"; grep -q -- "--headless" "$out/nodisplay" || fail "no --headless hint: $(cat "$out/nodisplay")"
[ "$(wc -l <"$out/nodisplay")" -eq 1 ] || fail "more than one line: $(cat "$out/nodisplay")"

# No input, no camera: the demo recording (under Xvfb).
printf 'wait-open 60\nstate %s\nquit\n' "$out/state.json" >"$out/s.txt"
xvfb-run -a -s "-screen 0 1280x720x24 -noreset" "$exe" view --script "$out/s.txt" >"$out/log" 2>&1 || fail "view: $(tail -5 "$out/log")"
grep -q 'demo.oni' "$out/state.json" || fail "did not open the demo: $(cat "$out/state.json")"
grep -q 'no camera found' "$out/state.json" || fail "did not say why the demo: $(cat "$out/state.json")"

# A script with an unknown command: checked before the window opens anything.
printf 'wait-open\nfly-away\n' >"$out/bad.txt"
xvfb-run -a -s "-screen 0 1280x720x24 -noreset" "$exe" view --script "$out/bad.txt" >"$out/bad" 2>&1; rc=$?
[ "$rc" -eq 2 ] || fail "bad script: exit $rc"; grep -q "line 2: unknown command fly-away" "$out/bad" || fail "$(cat "$out/bad")"
echo "cli_viewer: ok"
