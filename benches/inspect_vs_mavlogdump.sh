#!/usr/bin/env bash
# `mavtables inspect --json` against pymavlink's `mavlogdump.py --format json` on the
# same tlog, interleaved round by round; prints the median wall time of each and the ratio.
#
# usage: benches/inspect_vs_mavlogdump.sh [ROUNDS] [FILE]   (needs .venv from scripts/test)
# With MAVTABLES_BASELINE=/path/to/another/mavtables, that build runs in the same rounds
# too (to compare two versions of mavtables in one run).
set -euo pipefail
cd "$(dirname "$0")/.."
rounds="${1:-7}"
file="${2:-tests/data/flight/rural.tlog}"
cargo build --release --quiet
py=.venv/bin/python
dump=.venv/bin/mavlogdump.py
[ -x "$py" ] && [ -f "$dump" ] || { echo "run scripts/test first (it installs pymavlink into .venv)" >&2; exit 1; }

baseline="${MAVTABLES_BASELINE:-}"
ours=(); theirs=(); base=()
ms() { local s; s=$(date +%s%N); "$@" > /dev/null 2>&1; echo $(( ($(date +%s%N) - s) / 1000 )); }
for _ in $(seq "$rounds"); do
    ours+=("$(ms target/release/mavtables inspect --json "$file")")
    [ -n "$baseline" ] && base+=("$(ms "$baseline" inspect --json "$file")")
    theirs+=("$(ms "$py" "$dump" --format json "$file")")
done
median() { printf '%s\n' "$@" | sort -n | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}'; }
mo=$(median "${ours[@]}"); mt=$(median "${theirs[@]}")
frames=$(target/release/mavtables inspect --check "$file" | sed -n 's/.*(\([0-9]*\) frames).*/\1/p')
echo "file: $file ($frames frames), $rounds interleaved rounds, median wall time"
echo "  mavtables inspect --json        $(awk -v u="$mo" 'BEGIN {printf "%8.1f ms", u/1000}')"
echo "  mavlogdump.py --format json     $(awk -v u="$mt" 'BEGIN {printf "%8.1f ms", u/1000}')"
echo "  ratio (mavlogdump / mavtables)  $(awk -v a="$mt" -v b="$mo" 'BEGIN {printf "%.0fx", a/b}')"
if [ -n "$baseline" ]; then
    mb=$(median "${base[@]}")
    echo "  baseline $baseline inspect --json  $(awk -v u="$mb" 'BEGIN {printf "%8.1f ms", u/1000}')"
    echo "  ratio (baseline / mavtables)    $(awk -v a="$mb" -v b="$mo" 'BEGIN {printf "%.2fx", a/b}')"
fi
