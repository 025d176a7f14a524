#!/usr/bin/env bash
# `glint view`'s responsiveness on an X server of its own (Xvfb): time from the window opening
# to its first image, and images a second while refining, per scene and backend.
#   benches/view.sh [BACKENDS...]     (default: cpu gpu; needs Xvfb and xdotool)
set -euo pipefail
cd "$(dirname "$0")/.."
glint=target/release/glint
[ -x $glint ] || cargo build --release
backends=("${@:-cpu gpu}"); [ $# -eq 0 ] && backends=(cpu gpu)
display=:$((200 + $$ % 500))
Xvfb "$display" -screen 0 1280x1024x24 -nolisten tcp -noreset >/dev/null 2>&1 & xvfb=$!
trap 'kill $xvfb 2>/dev/null' EXIT
sleep 1
export DISPLAY=$display GLINT_PIPELINE_CACHE=off
classic=../shared/scenes/classic
scenes=()
[ -d $classic ] && scenes+=($classic/test1.scene $classic/table.scene $classic/SIGGRAPH.scene)
scenes+=(scenes/effects/soft_shadows.scene scenes/effects/all_effects.scene)
echo "| scene | backend | first image | images a second while refining |"
echo "|---|---|---:|---:|"
for b in "${backends[@]}"; do
  for s in "${scenes[@]}"; do
    log=$(mktemp)
    $glint view "$s" --backend "$b" --time-limit 4 2>"$log" >/dev/null & pid=$!
    for _ in $(seq 1 200); do
      w=$(xdotool search --name "glint view" 2>/dev/null | head -1 || true)
      [ -n "$w" ] && xdotool getwindowname "$w" 2>/dev/null | grep -q '\[done' && break
      sleep 0.1
    done
    [ -n "${w:-}" ] && { xdotool windowfocus --sync "$w"; xdotool key q; }
    wait $pid || true
    line=$(grep '^view:' "$log" || echo "view: no report")
    first=$(echo "$line" | sed -n 's/.*first image \([0-9]*\) ms.*/\1 ms/p')
    rate=$(echo "$line" | sed -n 's/.*(\([0-9.]*\) a second).*/\1/p')
    echo "| $(basename "$s" .scene) | $b | ${first:--} | ${rate:--} |"
    rm -f "$log"
  done
done
