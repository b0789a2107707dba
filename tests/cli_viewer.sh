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
# Record in the window: open the synthetic OpenNI2 camera (frames from `synth --frames`),
# record until stopped, and while it records (c1 is written with the recording still on)
# the previews go on: `wait-frames 4` waits for 4 more frames from the source, however
# slowly a busy machine delivers them. Then open the recording for replay: it holds the
# frames its side file counts.
"$exe" synth one-light --frames 8 --width 640 --height 480 --spp 1 --out "$out/frames" >"$out/synth" 2>&1 ||
  fail "synth frames: $(tail -2 "$out/synth")"
printf 'open camera:lpsynth://%s\nwait-open 60\nrecord %s 0\nstate %s\nwait-frames 4 300\nstate %s\nstop-recording\nwait-record 300\nstate %s\nopen %s\nwait-open 60\nscreenshot %s\nstate %s\nquit\n' \
  "$out/frames" "$out/rec.oni" "$out/c0state.json" "$out/c1state.json" "$out/cstate.json" "$out/rec.oni" "$out/rec.png" \
  "$out/rstate.json" >"$out/r.txt"
xvfb-run -a -s "-screen 0 1280x720x24 -noreset" "$exe" view --script "$out/r.txt" >"$out/rlog" 2>&1 ||
  fail "record: $(tail -5 "$out/rlog")"
[ -s "$out/rec.oni" ] && [ -s "$out/rec.oni.json" ] || fail "no recording and side file: $(ls "$out")"
for f in c0state c1state; do
  grep -q '"recording": true' "$out/$f.json" || fail "not recording in $f: $(cat "$out/$f.json")"
done
grep -q '"source": "OpenNI2 device lpsynth' "$out/cstate.json" || fail "the camera closed: $(cat "$out/cstate.json")"
grep -q '"message": "recorded' "$out/cstate.json" || fail "no 'recorded' message: $(cat "$out/cstate.json")"
grep -q '"recording": false' "$out/cstate.json" || fail "still recording: $(cat "$out/cstate.json")"
before=$(sed -n 's/.*"frames_read": \([0-9]*\).*/\1/p' "$out/c0state.json")
reads=$(sed -n 's/.*"frames_read": \([0-9]*\).*/\1/p' "$out/c1state.json")
[ "${reads:-0}" -ge $(( ${before:-0} + 4 )) ] ||
  fail "the previews did not go on while recording: frames_read ${before:-none} -> ${reads:-none}"
# The recording's frame count: the message's, its side file's, and OpenNI2's index as the
# replay reports it (the frame pairs: the fewer of depth and colour).
depth=$(sed -n 's/.*"depth_frames": \([0-9]*\).*/\1/p' "$out/rec.oni.json")
color=$(sed -n 's/.*"color_frames": \([0-9]*\).*/\1/p' "$out/rec.oni.json")
grep -q "\"message\": \"recorded ${depth:-none} depth frames" "$out/cstate.json" ||
  fail "the message does not give the side file's ${depth:-none} depth frames: $(cat "$out/cstate.json")"
pairs=$(( ${depth:-0} < ${color:-0} ? ${depth:-0} : ${color:-0} ))
grep -q "\"source\": \".oni file .*rec.oni, ${pairs} frames\"" "$out/rstate.json" ||
  fail "the recording does not open with its ${pairs} frames: $(cat "$out/rstate.json")"
[ -s "$out/rec.png" ] || fail "no screenshot"
echo "cli_viewer: ok (frames read while recording: ${before:-none} -> ${reads:-none}; recorded ${depth:-none} depth frames)"
