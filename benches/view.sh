#!/usr/bin/env bash
# `glint view`'s responsiveness on an X server of its own (Xvfb): time from the window opening
# to its first image (a preview where the scene is heavier than one) and to its first pass, and
# images a second while refining, per scene and backend; then five drags, each 0.5 s after the
# last, so most land mid-pass: the time from each view change to its first image.
# On a Vulkan device that can present, the device draws the window; the last rows are the host
# drawing it (--host-draws) for comparison.
#   benches/view.sh [BACKENDS...]     (default: cpu gpu; needs Xvfb and xdotool; GLINT=path: that binary)
set -euo pipefail
cd "$(dirname "$0")/.."
glint=${GLINT:-target/release/glint}
[ -x $glint ] || cargo build --release
backends=("${@:-cpu gpu}"); [ $# -eq 0 ] && backends=(cpu gpu)
display=:$((200 + $$ % 500))
Xvfb "$display" -screen 0 1280x1024x24 -nolisten tcp -noreset >/dev/null 2>&1 & xvfb=$!
trap 'kill $xvfb 2>/dev/null' EXIT
sleep 1
export DISPLAY=$display GLINT_PIPELINE_CACHE=off
limit=4
classic=../shared/scenes/classic
scenes=()
[ -d $classic ] && scenes+=($classic/test1.scene $classic/table.scene $classic/SIGGRAPH.scene)
scenes+=(scenes/effects/soft_shadows.scene scenes/effects/all_effects.scene)
echo "| scene | backend | first image | first pass | images a second while refining | a view change to its image: median, most |"
echo "|---|---|---:|---:|---:|---:|"
# view SCENE BACKEND DRAGS [FLAGS...]: runs glint view until its first view is done, drags DRAGS
# times, quits; prints its report line.
view() {
  local log w scene=$1 backend=$2 drags=$3
  shift 3
  log=$(mktemp)
  $glint view "$scene" --backend "$backend" --time-limit "$limit" "$@" 2>"$log" >/dev/null & pid=$!
  for _ in $(seq 1 200); do
    w=$(xdotool search --name "glint view" 2>/dev/null | head -1 || true)
    [ -n "$w" ] && xdotool getwindowname "$w" 2>/dev/null | grep -q '\[done' && break
    sleep 0.1
  done
  if [ -n "${w:-}" ]; then
    for i in $(seq 1 "$drags"); do
      xdotool mousemove --window "$w" 300 200 mousedown 1
      for step in 1 2 3; do xdotool mousemove --window "$w" $((300 + 5 * step)) 200; sleep 0.03; done
      xdotool mouseup 1
      sleep 0.5
    done
    xdotool windowfocus --sync "$w"; xdotool key q
  fi
  wait $pid || true
  grep '^view:' "$log" || echo "view: no report"
  rm -f "$log"
}
# row SCENE BACKEND [FLAGS...]: one line of the table.
row() {
  local line first pass rate change extra="${*:3}"
  line=$(view "$1" "$2" 0 "${@:3}")
  first=$(echo "$line" | sed -n 's/.*first image \([0-9]*\) ms.*/\1 ms/p')
  pass=$(echo "$line" | sed -n 's/.*the first pass \([0-9]*\) ms.*/\1 ms/p')
  echo "$line" | grep -q 'no pass finished' && pass="none in $limit s"
  rate=$(echo "$line" | sed -n 's/.*(\([0-9.]*\) a second).*/\1/p')
  line=$(view "$1" "$2" 5 "${@:3}")
  # Each drag is three view changes; one that a later one overtakes before its image shows no image.
  change=$(echo "$line" | sed -n 's/.*; \([0-9]*\) view changes, each showing its first image in \([0-9]*\) ms (median), \([0-9]*\) ms at most.*/\2 ms, \3 ms (\1 shown)/p')
  echo "| $(basename "$1" .scene) | $2${extra:+ $extra} | ${first:--} | ${pass:-${first:--}} | ${rate:--} | ${change:--} |"
}
for b in "${backends[@]}"; do
  for s in "${scenes[@]}"; do
    row "$s" "$b"
  done
done
# The cancellation of a GPU pass waits for the tiles in flight; smaller tiles answer sooner.
# And the device presenting the window against the host drawing it (--host-draws).
for b in "${backends[@]}"; do
  if [ "$b" = gpu ]; then
    row scenes/effects/soft_shadows.scene gpu --tile 64
    for s in "${scenes[@]}"; do row "$s" gpu --host-draws; done
  fi
done
