#!/usr/bin/env bash
# Where a render's wall clock goes outside the trace (issue: the image
# leaves as fast as it is made). Two measurements, medians of RUNS:
#  1. test1 at 1920x1080 to .jpg, .png and .exr: each phase of `render -v`
#     and the share of the total that encoding and writing take;
#  2. 48 frames of `table` with moving lights at 1280x720 to JPEG: the whole
#     animation's wall clock (process start to the last frame written)
#     against 48 renders alone (`glint bench`, same round).
# Usage: benches/host_path.sh [--backend cpu|gpu] (GLINT=path, RUNS=5,
# CLASSIC=dir of the course's scenes, default ../shared/scenes/classic).
set -euo pipefail
cd "$(dirname "$0")/.."
glint=${GLINT:-target/release/glint}
runs=${RUNS:-5}
classic=${CLASSIC:-../shared/scenes/classic}
backend=(--backend cpu)
[ $# -gt 0 ] && backend=("$@")
[ -x "$glint" ] || { echo "build first: cargo build --release (or GLINT=path)"; exit 1; }
[ -f "$classic/test1.scene" ] || { echo "no $classic/test1.scene"; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
# The first `-v` line "  NAME   12.345 ms" (the stats repeat them).
phase() { grep -E "^  $1 +[0-9.]+ ms$" | head -1 | awk '{print $(NF-1)}'; }

echo "== test1 1920x1080, ${backend[*]}, median of $runs (ms)"
# enc+wr: encode and write's share of the total; after: everything after
# the render (the 8-bit conversion too).
printf '%-5s %10s %10s %10s %10s %10s %8s %8s\n' out render "to 8-bit" encode write total "enc+wr" after
for ext in jpg png exr; do
    : >"$work/r"
    for _ in $(seq "$runs"); do
        "$glint" render "$classic/test1.scene" "$work/o.$ext" --width 1920 --height 1080 \
            "${backend[@]}" -v >"$work/log" 2>&1
        r=$(phase "cpu render" <"$work/log" || true)
        [ -n "$r" ] || r=$(phase dispatch <"$work/log")
        t8=$(phase "to 8-bit" <"$work/log" || true)
        echo "$r ${t8:-0} $(phase encode <"$work/log") $(phase write <"$work/log") $(phase total <"$work/log")" >>"$work/r"
    done
    cols=()
    for c in 1 2 3 4 5; do cols+=("$(cut -d' ' -f$c "$work/r" | median)"); done
    share=$(awk -v e="${cols[2]}" -v w="${cols[3]}" -v t="${cols[4]}" 'BEGIN {printf "%.1f%%", 100 * (e + w) / t}')
    after=$(awk -v c="${cols[1]}" -v e="${cols[2]}" -v w="${cols[3]}" -v t="${cols[4]}" 'BEGIN {printf "%.1f%%", 100 * (c + e + w) / t}')
    printf '%-5s %10s %10s %10s %10s %10s %8s %8s\n' "$ext" "${cols[@]}" "$share" "$after"
done

echo "== 48 frames of table with moving lights, 1280x720, ${backend[*]}"
awk '$1 == "light" {l = 1} {print} l && $1 == "col:" {print "vel: -2 0 1"; l = 0}' \
    "$classic/table.scene" >"$work/moving.scene"
# Renders alone: 48 times `glint bench`'s median render of the scene (its
# first frame, prepared once, so a little less than a frame's render with
# its BVH and packing), measured in each round beside the animation.
only=(--no-gpu)
[[ " ${backend[*]} " == *" gpu "* ]] && only=(--no-cpu)
: >"$work/f"
for _ in $(seq "$runs"); do
    one=$("$glint" bench "$work/moving.scene" --width 1280 --height 720 "${only[@]}" --repeat 5 \
        --no-end-to-end 2>&1 |
        awk '/^moving: / {print $(NF-1); exit}')
    rm -rf "$work/frames"
    start=$(date +%s.%N)
    "$glint" render "$work/moving.scene" "$work/frames" --frames 48 --width 1280 --height 720 \
        "${backend[@]}" -v >"$work/log" 2>&1
    end=$(date +%s.%N)
    renders=$(awk '/^all frames, rendered:/ {f = 1} f && $1 == "total" {print $2; exit}' "$work/log")
    awk -v s="$start" -v e="$end" -v r="$renders" -v one="$one" \
        'BEGIN {printf "%.1f %.1f %.1f %.3f\n", (e - s) * 1e3, r, 48 * one, (e - s) * 1e3 / (48 * one)}' >>"$work/f"
done
printf 'whole run %s ms; its renders (-v) %s ms; 48 renders alone (bench) %s ms; run / renders alone %s (medians)\n' \
    "$(cut -d' ' -f1 "$work/f" | median)" "$(cut -d' ' -f2 "$work/f" | median)" \
    "$(cut -d' ' -f3 "$work/f" | median)" "$(cut -d' ' -f4 "$work/f" | median)"
