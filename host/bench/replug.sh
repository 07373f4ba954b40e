#!/usr/bin/env bash
# USB unplug and replug in pty mode (issue 17): `ratf run` drives round 1 against `ratf sim
# --serve-pty`, whose world pulls DEVICE's cable out at a random time for 1 s. Prints one line
# per run and a summary per device. Real time: each run takes about a minute.
#
# usage: host/bench/replug.sh [RUNS_PER_DEVICE] [DEVICE ...]    (default: 10 mega lidar)
# RATF=path/to/ratf overrides the binary (default: target/release/ratf, built first).
# The unplug times are drawn uniformly in [3, 35] s of world time with Python's
# random.Random(17), seeds 1..RUNS.
set -euo pipefail

repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)
runs=${1:-10}
shift || true
devices=("$@")
if ((${#devices[@]} == 0)); then devices=(mega lidar); fi
if [ -z "${RATF:-}" ]; then
    (cd "$repo" && cargo build --release --quiet -p ratf-host --bin ratf)
    RATF="$repo/target/release/ratf"
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

one() {
    local device=$1 seed=$2 at=$3 dir="$work/$1-$2"
    mkdir -p "$dir"
    "$RATF" sim --round 1 --seed "$seed" --wait-for-robot-s 60 --serve-pty "$dir/dev" \
        --unplug "$device" --unplug-at-s "$at" --unplug-for-s 1 > "$dir/world.out" 2> "$dir/world.err" &
    local world=$!
    for _ in $(seq 100); do grep -q "^server port" "$dir/world.out" 2>/dev/null && break; sleep 0.1; done
    local port
    port=$(awk '/^server port/{print $3}' "$dir/world.out")
    printf '[link]\nmega_port = "%s/dev/mega"\nlidar_port = "%s/dev/lidar"\nimu = "none"\n\n[referee]\nserver_port = %s\n' \
        "$dir" "$dir" "$port" > "$dir/robot.toml"
    local code=0
    timeout 200 "$RATF" run --config "$dir/robot.toml" --out "$dir/out" --status-hz 0 \
        > "$dir/run.out" 2> "$dir/run.err" || code=$?
    wait "$world" || true
    local summary points collisions
    summary=$(grep '^round 1:' "$dir/world.out" || echo "round 1: 0 points; 0 collisions;")
    points=$(sed -E 's/round 1: ([0-9]+) points.*/\1/' <<< "$summary")
    collisions=$(sed -E 's/.*; ([0-9]+) collisions;.*/\1/' <<< "$summary")
    echo "$device seed=$seed unplug_at_s=$at exit=$code points=$points collisions=$collisions"
}

python3 -c "
import random
r = random.Random(17)
for device in ('mega', 'lidar'):
    for seed in range(1, $runs + 1):
        print(device, seed, round(r.uniform(3, 35), 1))
" | while read -r device seed at; do
    if [[ " ${devices[*]} " == *" $device "* ]]; then one "$device" "$seed" "$at"; fi
done | tee "$work/lines"
for device in "${devices[@]}"; do
    awk -v d="$device" '$1 == d {
        n++; split($5, p, "="); split($6, c, "=");
        full += (p[2] == 4); points += p[2]; coll += c[2]; clean += (c[2] == 0)
    } END { if (n) printf "%s: %d runs, full score %d/%d, points %d/%d, collisions %d (%d runs without)\n",
        d, n, full, n, points, 4 * n, coll, clean }' "$work/lines"
done
