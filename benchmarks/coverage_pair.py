"""Two runs of one world side by side: where each map calls the reachable floor free.

A coverage figure says how much of the floor a run mapped; a change that
moves it needs to be seen to be understood (which rooms it lost, which
corridor it gained).  Each panel is the world's floor plan with the floor the
robot could reach coloured by whether the run's map calls it free (the
``free_coverage`` of ``blocks.maps.score``, cell by cell) and the path driven.
The world is the one in the runs' ``run.json``.

    python benchmarks/coverage_pair.py RUN_A RUN_B [--map maps/probabilistic.yaml]
        [--labels "A,B"] [--out coverage_pair.png]

``docs/img/occlusion_hospital1022.png`` is this for hospital-1022 after an
hour, without and with ``--set explore_map.occlusion=1.5`` (docs/maps.md).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from blocks.core.errors import SemmapError  # noqa: E402
from blocks.maps.mapio import read_map  # noqa: E402
from blocks.maps.score import free_floor, read_path_csv  # noqa: E402
from sim2d.blocks import resolve_world  # noqa: E402
from sim2d.world import load_world  # noqa: E402

FREE = (0.75, 0.9, 0.75)
NOT_FREE = (0.95, 0.3, 0.3)


def world_of(run: Path) -> str:
    """The world a run's graph ran on (its ``world`` parameter)."""
    params = json.loads((run / "run.json").read_text())["graph"]["params"]
    return str(params["world"]["value"])


def panel(ax, run: Path, world, map_file: str, label: str) -> float:
    """Draw one run's panel; return its free coverage."""
    truth, reachable, free = free_floor(read_map(run / map_file), world)
    image = np.ones(truth.occupancy.shape + (3,))
    image[truth.occupancy > 0.5] = (0.0, 0.0, 0.0)
    image[reachable & free] = FREE
    image[reachable & ~free] = NOT_FREE
    res, (x0, y0) = truth.resolution, truth.origin[:2]
    height, width = truth.occupancy.shape
    ax.imshow(image, origin="lower", extent=[x0, x0 + width * res, y0, y0 + height * res])
    path = read_path_csv(run / "trajectory.csv")
    ax.plot(path[:, 0], path[:, 1], "-", lw=0.4, color="tab:blue")
    coverage = float(free.sum() / max(int(reachable.sum()), 1))
    ax.set_title(f"{label}: {coverage:.2f} of the floor free", fontsize=10)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return coverage


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs=2, type=Path, help="two run folders of the same world")
    parser.add_argument("--map", default="maps/probabilistic.yaml",
                        help="the map inside each run folder (default: the explorer's)")
    parser.add_argument("--labels", default="", help="the panels' titles, comma-separated")
    parser.add_argument("--out", type=Path, default=Path("coverage_pair.png"))
    args = parser.parse_args(argv)
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    for run in args.runs:
        missing = [name for name in ("run.json", "trajectory.csv", args.map)
                   if not (run / name).is_file()]
        if missing:
            print(f"error: {run} has no {', '.join(missing)}; give the folders of two "
                  "'semmap run' runs (or two runs of a sweep's runs/ folder)", file=sys.stderr)
            return 2
    names = [world_of(run) for run in args.runs]
    if names[0] != names[1]:
        print(f"error: the runs are of different worlds ({names[0]}, {names[1]}); "
              "give two runs of one world", file=sys.stderr)
        return 2
    world = load_world(resolve_world(names[0]))
    labels = [s.strip() for s in args.labels.split(",")] if args.labels else \
        [run.name for run in args.runs]
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.6))
    for ax, run, label in zip(axes, args.runs, labels):
        try:
            print(f"{run}: free coverage {panel(ax, run, world, args.map, label):.3f}")
        except SemmapError as error:
            print(f"error: {error}", file=sys.stderr)
            return 2
    axes[1].legend(handles=[Patch(color=FREE, label="reachable floor the map calls free"),
                            Patch(color=NOT_FREE, label="reachable floor it does not"),
                            Line2D([], [], color="tab:blue", lw=1, label="path (true pose)")],
                   loc="lower right", fontsize=8)
    fig.suptitle(f"{names[0]}: {args.map} against the floor plan", fontsize=11)
    fig.tight_layout()
    fig.savefig(args.out, dpi=70, bbox_inches="tight")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
