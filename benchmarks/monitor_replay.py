"""Replay recorded runs through the collision monitor's check: were the contacts seen coming?

A monitor rule is a trade: every contact it foresees is a collision saved,
and every stop it makes where nothing was hit costs time and can leave a
behaviour held.  Closed-loop runs answer both at once but slowly and with
the noise of whole trajectories diverging; this replays the sonar and
odometry that runs recorded (``semmap sweep`` folders, each run's
``sonar.npz`` and ``trajectory.csv``) through
:class:`~blocks.navigate.collision_monitor.EchoMemory`, tick by tick, and
asks of each rule:

contacts foreseen
    contacts (run.json ``world.collision_log``) before which, 0.3 to 0.8 s
    ahead, the command recorded would have reached a remembered echo within
    the monitor's horizon: the monitor would have begun slowing in time;
stopped elsewhere
    the share of moving ticks (every 7th, away from contacts) whose command
    the monitor would have stopped outright.

The commands are the ones recorded, so a rule is judged on what the robot
did, not on what it would have done instead.

    semmap sweep graphs/semantic_mapping.yaml --worlds gen:any:0-9 --seeds 0 --steps 6000 \
        --set collision_monitor=false --set retry_frontiers=0 --out runs/dev
    python benchmarks/monitor_replay.py runs/dev

Runs with the monitor on (the default) can be replayed too: their contacts
are the ones it let through, and their commands the ones it passed.
"""
from __future__ import annotations

import argparse
import json
import math
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.navigate.collision_monitor import EchoMemory, MonitorParams  # noqa: E402
from blocks.navigate.guard import SonarGuard  # noqa: E402

DT = 0.1


def replay_run(run: Path, params: MonitorParams, every: int = 7) -> dict[str, int]:
    """Counts of one run: contacts foreseen and missed, moving ticks sampled and stopped."""
    metrics = json.loads((run / "run.json").read_text())["metrics"]
    sonar = np.load(run / "sonar.npz")
    ranges = sonar["robot@ranges"]
    guard = SonarGuard(sonar["robot@mounts"], cone_deg=float(sonar["robot@cone_deg"]),
                       max_range=float(sonar["robot@max_range"]))
    # tick, odometry x, y, theta, commanded v, w
    track = np.loadtxt(run / "trajectory.csv", delimiter=",", skiprows=1,
                       usecols=(0, 6, 7, 8, 9, 10))
    contacts = sorted(int(round(c["t"] / DT)) for c in metrics["world"].get("collision_log") or [])
    wanted = {k for c in contacts for k in range(c - 8, c - 2)}
    sampled = {k for k in range(10, len(track) - 1, every)
               if all(abs(k - c) >= 30 for c in contacts)}
    memory = EchoMemory(guard, params)
    warned: set[int] = set()
    counts = {"foreseen": 0, "missed": 0, "moving": 0, "stopped": 0}
    for k in range(min(len(track) - 1, len(ranges))):
        pose = track[k, 1:4]
        memory.add(k * DT, pose, ranges[k])
        if k not in wanted and k not in sampled:
            continue
        v, w = float(track[k + 1, 4]), float(track[k + 1, 5])
        t = memory.collision_time(pose, v, w)
        if k in wanted and t < params.time_before_collision:
            warned.add(k)
        if k in sampled and (abs(v) >= 0.05 or abs(w) >= 0.05):
            counts["moving"] += 1
            counts["stopped"] += t <= params.step
    for c in contacts:
        seen = any(k in warned for k in range(c - 8, c - 2))
        counts["foreseen" if seen else "missed"] += 1
    return counts


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("sweeps", nargs="+", type=Path, help="semmap sweep output folders")
    args = parser.parse_args(argv)
    runs = sorted(p.parent for sweep in args.sweeps for p in sweep.glob("runs/*/sonar.npz"))
    if not runs:
        print(f"no recorded runs (runs/*/sonar.npz) under {', '.join(map(str, args.sweeps))}",
              file=sys.stderr)
        return 2
    alone = replace(MonitorParams(), near_memory=0.0)  # every echo kept as long
    rules = {"arcs, 1 s of echoes, near ones 30 s (the monitor's default)": MonitorParams(),
             "arcs, 1 s of echoes": alone,
             "arcs + triangulated echoes, 1 s": replace(alone, triangulate=True),
             "arcs, 3 s of echoes": replace(alone, memory=3.0),
             "arcs, 6 s of echoes": replace(alone, memory=6.0)}
    print(f"{len(runs)} runs")
    print("| rule | contacts foreseen | stopped elsewhere |")
    print("| --- | --- | --- |")
    for name, params in rules.items():
        total = {"foreseen": 0, "missed": 0, "moving": 0, "stopped": 0}
        for run in runs:
            for key, value in replay_run(run, params).items():
                total[key] += value
        contacts = total["foreseen"] + total["missed"]
        share = total["stopped"] / max(total["moving"], 1)
        print(f"| {name} | {total['foreseen']} of {contacts} | {100 * share:.2f} % "
              f"of {total['moving']} moving ticks |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
