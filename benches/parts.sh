#!/usr/bin/env bash
# What splitting a render into parts costs: for each scene, one render of
# the whole image against N parts (`render --part I/N`, run one after the
# other as N array tasks would run side by side), and checks that the
# stitched image equals the single render bit for bit.
#
#   benches/parts.sh [N] [backend] [WxH] [runs]   defaults: 16 cpu 1920x1080 5
#
# THREADS=k renders on k threads (default: all). Each figure is the fastest
# of `runs` renders, for the whole and for each part on its own (a shared
# machine only ever adds time; the fastest is the least disturbed).
# Columns, the parts summed against the whole render:
#   render + cut  the work split N ways: CPU time of the render's threads
#                 (CPU backend; dispatch and readback on the GPU) plus each
#                 part's cost probe and cut ("part cut");
#   process       each task's whole process, wall clock: parse, BVH, device
#                 and writing repeated N times, what a cluster pays in all;
#   balance       the costliest part's render + cut against the parts' mean:
#                 how much longer than an even share the array's last task
#                 renders.
# Scenes: the five classic ones (../shared/scenes/classic) and the 2M-triangle
# sphere grid (../shared/tools/gen_spheregrid.py --seg 100 --k 10).
set -euo pipefail
cd "$(dirname "$0")/.."
n=${1:-16}
backend=${2:-cpu}
size=${3:-1920x1080}
runs=${4:-5}
w=${size%x*} h=${size#*x}
cargo build --release --quiet
glint=$PWD/target/release/glint
classic=../shared/scenes/classic
[ -d "$classic" ] || { echo "no $classic: the classic scenes are needed"; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
python3 ../shared/tools/gen_spheregrid.py --seg 100 --k 10 >"$work/grid2m.scene"
scenes=("$classic"/{test1,test2,spheres,table,SIGGRAPH}.scene "$work/grid2m.scene")

case $backend in
cpu) phases=("cpu ns" "part cut") ;;
gpu) phases=(dispatch readback "part cut") ;;
*) echo "backend: cpu or gpu"; exit 2 ;;
esac

# The render's milliseconds in one log: its phases of the "timings:" block
# ("  name   1.234 ms", or "  cpu ns  123" in nanoseconds).
work_ms() {
    awk -v names="$(printf '%s\n' "${phases[@]}")" '
        BEGIN { split(names, want, "\n") }
        /^timings:/ { t = 1; next }
        /^[a-z]+:/ { t = 0 }
        !t { next }
        {
            line = $0; sub(/^ +/, "", line)
            for (k in want) if (index(line, want[k] " ") == 1) {
                if ($(NF) == "ms") s += $(NF - 1); else s += $(NF) / 1e6
            }
        }
        END { printf "%.3f", s }' "$1"
}
now_ms() { date +%s%3N; }
min() { awk -v a="$1" -v b="$2" 'BEGIN { print (b < a ? b : a) }'; }
add() { awk -v a="$1" -v b="$2" 'BEGIN { print a + b }'; }
pct() { awk -v a="$1" -v b="$2" 'BEGIN { printf "%+.1f%%", (a / b - 1) * 100 }'; }

# One render: prints "work_ms wall_ms".
render() {
    rm -f "$work"/r.part* "$work/r.png"
    local t0
    t0=$(now_ms)
    "$glint" render "$scene" "$work/r.png" "${common[@]}" "$@" >"$work/r.log"
    local wall=$(($(now_ms) - t0))
    echo "$(work_ms "$work/r.log") $wall"
}

echo "parts benchmark: N=$n, --backend $backend, ${w}x${h}, ${THREADS:-all} threads, fastest of $runs, $(nproc) cores, $(date -u +%Y-%m-%d), $(git describe --always --dirty)"
echo
echo "| scene | whole: render | $n parts: render + cut | process wall | balance | identical |"
echo "|---|---:|---:|---:|---:|---|"
for scene in "${scenes[@]}"; do
    name=$(basename "$scene" .scene)
    common=(${THREADS:+--threads "$THREADS"} --backend "$backend" --width "$w" --height "$h" -v)
    whole=1e18 whole_wall=1e18
    for ((r = 0; r < runs; r++)); do
        read -r a b < <(render)
        whole=$(min "$whole" "$a") whole_wall=$(min "$whole_wall" "$b")
    done
    cp "$work/r.png" "$work/whole.png"
    parts=0 parts_wall=0 costliest=0
    mkdir -p "$work/kept"
    rm -f "$work"/kept/*
    for ((i = 0; i < n; i++)); do
        best=1e18 best_wall=1e18
        for ((r = 0; r < runs; r++)); do
            read -r a b < <(render --part "$i/$n")
            best=$(min "$best" "$a") best_wall=$(min "$best_wall" "$b")
        done
        cp "$work"/r.part* "$work/kept/"
        parts=$(add "$parts" "$best") parts_wall=$(add "$parts_wall" "$best_wall")
        costliest=$(awk -v a="$costliest" -v b="$best" 'BEGIN { print (b > a ? b : a) }')
    done
    cp "$work"/kept/r.part* "$work/"
    "$glint" stitch "$work/r.png" --parts "$n" >/dev/null
    same=no
    cmp -s "$work/whole.png" "$work/r.png" && same=yes
    printf '| %s | %.1f ms | %.1f ms (%s) | %d → %d ms (%s) | %.2fx | %s |\n' \
        "$name" "$whole" "$parts" "$(pct "$parts" "$whole")" "$whole_wall" "$parts_wall" \
        "$(pct "$parts_wall" "$whole_wall")" "$(awk -v c="$costliest" -v s="$parts" -v n="$n" 'BEGIN { print c / (s / n) }')" "$same"
done
