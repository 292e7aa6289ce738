#!/usr/bin/env bash
# Compares two builds of the router on the forwarding benchmark, rounds interleaved
# (old, new, new, old, ...), so that the machine's drift hits both alike.
#
# usage: benches/compare_builds.sh OLD_BINARY NEW_BINARY [ROUNDS]
#   e.g. build the commit before a change in a worktree with `cargo build --release`,
#   then: benches/compare_builds.sh ../old/target/release/mavtables target/release/mavtables 5
# Each round runs `cargo bench --bench forwarding -- --quick` (zero-loss rates with 1 and
# 3 receivers, CPU per frame at 50k frames/s, latency at 10k frames/s, peak RSS) and
# `-- --cpu` (CPU per frame at 50k frames/s and working off a backlog) with each build;
# the raw outputs are kept in target/compare/ and the rows of each run printed.
set -euo pipefail
cd "$(dirname "$0")/.."
old="$(realpath "$1")"
new="$(realpath "$2")"
rounds="${3:-5}"
out=target/compare
mkdir -p "$out"
cargo bench --bench forwarding --no-run >/dev/null 2>&1
for r in $(seq 1 "$rounds"); do
    if [ $((r % 2)) = 1 ]; then order="old new"; else order="new old"; fi
    for which in $order; do
        bin="$old"; [ "$which" = new ] && bin="$new"
        for mode in quick cpu; do
            log="$out/$which.$mode.$r.txt"
            MAVTABLES_BENCH_ROUTER="$bin" cargo bench --bench forwarding -- "--$mode" >"$log" 2>&1
            echo "== round $r, $which, --$mode"
            grep -E '^\| router|router .*(CPU|cpu)|^router|backlog' "$log" || true
        done
    done
done
