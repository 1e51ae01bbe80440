"""Where the body met something, and how it was moving: every contact of a sweep, classified.

A collision count says how often; this says which part of the robot and
which motion, which is what decides the fix (a rear corner backing along a
wall wants a longer memory behind it; a front corner turning into a door
wants the jamb heard sooner).  Each contact of ``run.json``'s
``world.collision_log`` is put in the robot's frame at the true pose of that
tick (scoring only: the true pose is the simulator's) and named by the
part of the body it touched (front, rear or middle; left, right or centre)
and by the commands of the half second before it (``backing``, ``ahead``,
``turning`` on the spot, ``still``).

    python benchmarks/contacts.py runs/eval [--list]
"""
from __future__ import annotations

import argparse
import bisect
import csv
import json
import math
import sys
from collections import Counter
from pathlib import Path

#: Contacts this far (m) from the body's centre line are on a side, or a face.
SIDE = 0.15


def body_part(fx: float, fy: float) -> str:
    """The part of a 0.5 m body a contact at (fx, fy) in the robot frame touched.

    Examples
    --------
    >>> body_part(-0.25, -0.25), body_part(0.25, 0.02)
    ('rear-right', 'front-centre')
    """
    along = "front" if fx > SIDE else "rear" if fx < -SIDE else "middle"
    across = "left" if fy > SIDE else "right" if fy < -SIDE else "centre"
    return f"{along}-{across}"


def motion(vs: list[float], ws: list[float]) -> str:
    """What the commands before a contact were doing, on the whole (their mean).

    Examples
    --------
    >>> motion([-0.15, -0.15], [0.0, 0.0]), motion([0.0, 0.0], [0.6, 0.6])
    ('backing', 'turning')
    """
    v = sum(vs) / len(vs)
    if v < -0.02:
        return "backing"
    if v > 0.02:
        return "ahead"
    return "turning" if max(abs(w) for w in ws) > 0.05 else "still"


def contacts(run: Path) -> list[dict]:
    """One run's contacts, each with its time, body part and motion."""
    metrics = json.loads((run / "run.json").read_text()).get("metrics", {})
    log = metrics.get("world", {}).get("collision_log") or []  # none yet if still running
    if not log:
        return []
    with (run / "trajectory.csv").open() as f:
        track = [(float(r["time"]), float(r["x"]), float(r["y"]), float(r["theta"]),
                  float(r["v"]), float(r["w"])) for r in csv.DictReader(f)]
    times = [row[0] for row in track]
    out = []
    for c in log:
        i = min(bisect.bisect_left(times, c["t"]), len(track) - 1)
        _, x, y, th, _, _ = track[i]
        dx, dy = c["contact"][0] - x, c["contact"][1] - y
        fx = math.cos(th) * dx + math.sin(th) * dy
        fy = -math.sin(th) * dx + math.cos(th) * dy
        recent = track[max(0, i - 5):i + 1]
        out.append({"run": run.name, "t": c["t"], "part": body_part(fx, fy),
                    "motion": motion([r[4] for r in recent], [r[5] for r in recent])})
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweeps", nargs="+", type=Path, help="semmap sweep output folders")
    parser.add_argument("--list", action="store_true", help="also list every contact")
    args = parser.parse_args(argv)
    runs = sorted(p.parent for sweep in args.sweeps for p in sweep.glob("runs/*/run.json"))
    if not runs:
        print(f"no runs (runs/*/run.json) under {', '.join(map(str, args.sweeps))}",
              file=sys.stderr)
        return 2
    found = [c for run in runs for c in contacts(run)]
    hit = len({c["run"] for c in found})
    print(f"{len(found)} contacts in {len(runs)} runs ({len(runs) - hit} with none)")
    print("| part of the body | motion | contacts |")
    print("| --- | --- | --- |")
    for (part, how), n in Counter((c["part"], c["motion"]) for c in found).most_common():
        print(f"| {part} | {how} | {n} |")
    if args.list:
        for c in found:
            print(f"{c['run']:18s} t={c['t']:8.1f} {c['part']:13s} {c['motion']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
