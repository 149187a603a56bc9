#!/usr/bin/env bash
# Peak resident memory of `slam2world convert` on the demo-size log and on
# simulated logs FACTORS times as long (frames, keyframes, path; default 10),
# by /usr/bin/time -v. Issue 20's goal: the 10x log's peak within 1.3x of the
# demo's; a second factor (FACTORS="10 20") shows what still grows with length.
#
#   benches/memory.sh                  # paper-size demo (slow to simulate: use a release binary)
#   REDUCED=4 benches/memory.sh        # every log divided by 4 (frames, keyframes, image side)
#   FACTORS="10 20" benches/memory.sh  # the 10x and the 20x log
#   SLAM2WORLD=target/debug/slam2world OCTREE=0.2 benches/memory.sh
#
# Prints one line per log (keyframes, points, peak RSS in MiB, convert seconds)
# and the ratio of each long log to the demo. Logs and outputs go under $WORK
# (default a temp dir).
set -euo pipefail

BIN=${SLAM2WORLD:-target/release/slam2world}
REDUCED=${REDUCED:-1}
OCTREE=${OCTREE:-}
FACTORS=${FACTORS:-10}
WORK=${WORK:-$(mktemp -d)}
mkdir -p "$WORK"

if [ ! -x /usr/bin/time ]; then
    # GNU time (Debian's `time`): the shell keyword has no -v.
    apt-get install -y time >/dev/null || { apt-get update >/dev/null && apt-get install -y time >/dev/null; }
fi
[ -x "$BIN" ] || { echo "no binary at $BIN (cargo build --release, or set SLAM2WORLD)" >&2; exit 1; }

simulate() { # NAME FACTOR
    local log="$WORK/$1.mcap"
    if [ ! -f "$log" ]; then
        local f=$2
        "$BIN" simulate -o "$log" --reduced "$REDUCED" \
            --set "n_frames=$((7000 * f / REDUCED))" --set "n_keyframes=$((123 * f / REDUCED))" \
            --set "path_length=$(echo "195.12 * $f / $REDUCED" | bc -l)" \
            --set "slam_path_length=$(echo "12.6 * $f / $REDUCED" | bc -l)" >/dev/null
    fi
    echo "$log"
}

measure() { # NAME LOG -> "name keyframes points rss_mib seconds"
    local out="$WORK/out-$1" err="$WORK/time-$1.txt"
    local opts=(--quiet)
    [ -n "$OCTREE" ] && opts+=(--octree "$OCTREE")
    /usr/bin/time -v "$BIN" convert "$2" -o "$out" "${opts[@]}" 2>"$err"
    local kb secs
    kb=$(awk -F': ' '/Maximum resident set size/ {print $2}' "$err")
    secs=$(awk -F': ' '/Elapsed \(wall clock\)/ {print $2}' "$err")
    python3 - "$out/report.json" "$1" "$kb" "$secs" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print(f"{sys.argv[2]} {r['keyframes']} {r['points']} {int(sys.argv[3]) / 1024:.1f} {sys.argv[4]}")
PY
}

demo=$(simulate demo 1) || exit 1
echo "# log keyframes points peak_rss_MiB wall (reduced $REDUCED, octree ${OCTREE:-none}, $BIN)"
a=$(measure demo "$demo")
echo "$a"
for f in $FACTORS; do
    long=$(simulate "long$f" "$f") || exit 1
    b=$(measure "long$f" "$long")
    echo "$b"
    python3 -c "import sys; a, b = float(sys.argv[1]), float(sys.argv[2]); print(f'ratio long${f}/demo {b / a:.2f} (goal for 10x: <= 1.3)')" \
        "$(echo "$a" | cut -d' ' -f4)" "$(echo "$b" | cut -d' ' -f4)"
done
