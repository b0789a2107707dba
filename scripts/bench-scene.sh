# Sourced by the bench scripts: bench_scene NAME EXE TMP prints the scene bundle's directory
# for NAME: a Cycles scene in tests/data/cycles, the bundled far-light demo, a bundle's
# directory as given (e.g. out/demo/scene, scripts/demo.sh's reconstruction), or a synthetic
# scene EXE synthesizes into TMP.
bench_scene() {
  local s=$1 exe=$2 tmp=$3 root
  root=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
  case "$s" in
    cornerbox_one_light|glow|screen) echo "$root/tests/data/cycles/$s" ;;
    demo) echo "$root/assets/demo" ;;
    */*) echo "$s" ;;
    *) "$exe" synth "$s" --out "$tmp/${s//\//_}" >/dev/null && echo "$tmp/${s//\//_}" ;;
  esac
}
