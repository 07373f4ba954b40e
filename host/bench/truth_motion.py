#!/usr/bin/env python3
"""What the true body does between the part list and the last placement of simulated rounds.

Reads the JSON-lines logs `ratf sim` writes (one `tick` line per 20 ms with the true pose) and
splits each round's time, per round number, into: the heading turning (true yaw rate above
0.3 rad/s, as `ratf_host::apps::time_split::TURNING_RAD_S`), moving with the heading held
(above 0.02 m/s), and at rest; with the distance and mean speed of each, and the time spent
below 0.3 m/s while moving with the heading held.

usage:
    for s in $(seq 61 70); do
        ratf sim --round 1 --seed "$s" --calibrated --out out/motion
    done
    python3 host/bench/truth_motion.py out/motion/*.jsonl
"""

import collections
import json
import math
import re
import sys

TURNING_RAD_S = 0.3
MOVING_M_S = 0.02
SLOW_M_S = 0.3


def split(path):
    rows = [json.loads(line) for line in open(path, encoding="utf-8")]
    texts = [(r["t_s"], r.get("text", "")) for r in rows if r.get("type") == "event"]
    starts = [t for t, text in texts if "part list" in text]
    ends = [t for t, text in texts if text.startswith("placed")]
    if not starts or not ends:
        return None
    start, end = starts[0], ends[-1]
    ticks = [r for r in rows if r.get("type") == "tick" and start <= r["t_s"] <= end]
    out = collections.Counter()
    for a, b in zip(ticks, ticks[1:]):
        dt = b["t_s"] - a["t_s"]
        if dt <= 0:
            continue
        ta, tb = a["truth"], b["truth"]
        v = math.hypot(tb["x_m"] - ta["x_m"], tb["y_m"] - ta["y_m"]) / dt
        dyaw = (tb["yaw_deg"] - ta["yaw_deg"] + 180.0) % 360.0 - 180.0
        w = abs(math.radians(dyaw)) / dt
        if w > TURNING_RAD_S:
            kind = "turning"
        elif v >= MOVING_M_S:
            kind = "held"
            if v < SLOW_M_S:
                out["held_slow_s"] += dt
        else:
            kind = "rest"
        out[kind + "_s"] += dt
        out[kind + "_m"] += v * dt
    out["round_s"] = end - start
    return out


def main(paths):
    by_round = collections.defaultdict(list)
    for path in paths:
        match = re.search(r"round(\d)", path)
        result = split(path)
        if match and result:
            by_round[int(match.group(1))].append(result)
    if not by_round:
        sys.exit("no round with a part list and a placement in the files given")
    for rnd, runs in sorted(by_round.items()):
        mean = lambda key: sum(r[key] for r in runs) / len(runs)
        speed = lambda kind: mean(kind + "_m") / max(mean(kind + "_s"), 1e-9)
        print(
            f"round {rnd}, {len(runs)} runs: {mean('round_s'):.1f} s; heading turning "
            f"{mean('turning_s'):.1f} s over {mean('turning_m'):.2f} m ({speed('turning'):.2f} m/s); "
            f"moving with it held {mean('held_s'):.1f} s over {mean('held_m'):.2f} m "
            f"({speed('held'):.2f} m/s, {mean('held_slow_s'):.1f} s below {SLOW_M_S} m/s); "
            f"at rest {mean('rest_s'):.1f} s"
        )


if __name__ == "__main__":
    main(sys.argv[1:])
