#!/usr/bin/env bash
# Runs glint's fuzz targets (cargo-fuzz, libFuzzer, no sanitizer: stable Rust).
#   tests/fuzz/run.sh smoke [SECONDS]     every target for SECONDS (default 20): CI's step
#   tests/fuzz/run.sh runs N [TARGET...]  N inputs per target (the long runs docs/testing.md reports)
# New inputs go to tests/fuzz/corpus-work/ (ignored); the committed seeds in
# tests/fuzz/corpus/ are only read. A crash, a hang (over 10 s on one input) or
# over 2 GiB of memory fails the run, with the input in tests/fuzz/artifacts/.
set -euo pipefail
cd "$(dirname "$0")/../.."
mode=${1:-smoke}; shift || true
targets=(scene obj mtl ply off stl gltf image cache)
case $mode in
    smoke) limit=(-max_total_time="${1:-20}") ;;
    runs) limit=(-runs="${1:?runs N}"); shift; (($#)) && targets=("$@") ;;
    *) sed -n '2,7p' "$0"; exit 2 ;;
esac
command -v cargo-fuzz >/dev/null || { echo "cargo-fuzz is not installed: cargo install cargo-fuzz"; exit 1; }
cargo fuzz build --fuzz-dir tests/fuzz -s none --release
for t in "${targets[@]}"; do
    work=tests/fuzz/corpus-work/$t
    mkdir -p "$work"
    start=$(date +%s)
    log=$(cargo fuzz run --fuzz-dir tests/fuzz -s none --release "$t" "$work" "tests/fuzz/corpus/$t" -- \
        "${limit[@]}" -timeout=10 -rss_limit_mb=2048 -malloc_limit_mb=2048 -print_final_stats=1 2>&1) || {
        echo "$log" | tail -40; echo "FUZZ FAILURE in $t"; exit 1; }
    runs=$(echo "$log" | sed -n 's/^stat::number_of_executed_units: *//p')
    echo "$t: $runs inputs in $(( $(date +%s) - start )) s, no crash, hang or memory blow-up"
done
