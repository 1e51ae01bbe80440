"""A finished run's semantic map and command score again, with today's code, without driving.

The semantic map is built once the robot stops, from what the run saved: the
offline map, its corrected path, the signs read and the objects seen.  A change
to how places are made, named or scored leaves the robot's path alone, so the
runs need not be driven again to measure it: this rebuilds each run's
semantic map from those files (the objects from the ``semantic_map.ttl`` it
wrote), asks the world's commands on it and sets the score beside the one
the run reported.  Unchanged code gives the run's own answers (checked on the
development runs); the rebuilt folders go under ``--out``.

    python benchmarks/rescore_commands.py runs/eval_hour [--out /tmp/rescored] [--list]
"""
from __future__ import annotations

import argparse
import json
import shutil
import sys
import tempfile
from pathlib import Path

from blocks.maps.mapio import read_map
from blocks.maps.pathio import read_path_csv
from blocks.semantic.blocks import Knowledge
from semantic.kb import INDOOR, KnowledgeBase
from semantic.query import load_run_map
from semantic.query.exam import load_commands, score_commands
from semantic.query.mapsource import _run_world
from semantic.semantic_map import build_semantic_map, write_semantic_map
from semantic.timetable import load_timetable
from sim2d.world import load_world

#: The files of a run the rebuild reads (the rest is not copied).
NEEDED = ("run.json", "signs.json", "semantic_map.ttl", "maps/offline.yaml",
          "maps/offline.pgm", "maps/offline_path.csv")


def observed_objects(kb: KnowledgeBase) -> list[dict]:
    """The objects a run saw, in the order it saw them (``object_N``), as the knowledge
    block was given them: ``{label, x, y}``."""
    facts = kb.facts
    ids = [o for o in facts.subjects_with(INDOOR.source) if kb._id(o).startswith("object_")]
    out = []
    for o in sorted(ids, key=lambda o: int(kb._id(o).rsplit("_", 1)[1])):
        cls = kb._most_specific(o, INDOOR.PhysicalObject)
        out.append({"label": kb._id(cls), "x": float(facts.one(o, INDOOR.x)),
                    "y": float(facts.one(o, INDOOR.y))})
    return out


def rescore(run: Path, out: Path) -> tuple[dict, dict] | None:
    """(the run's own knowledge metrics, the score on its rebuilt semantic map), or None
    when its world has no commands."""
    meta = json.loads((run / "run.json").read_text())
    world_file = _run_world(run)  # as `semmap ask --map RUN` finds it
    world = load_world(world_file) if world_file is not None else None
    if world is None or world.commands is None:
        return None
    for name in NEEDED:
        (out / name).parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(run / name, out / name)
    objects = observed_objects(KnowledgeBase.load(run / "semantic_map.ttl"))
    signs = json.loads((run / "signs.json").read_text())
    occupancy = read_map(run / "maps" / "offline.yaml")
    _, poses = read_path_csv(run / "maps" / "offline_path.csv")
    timetable = load_timetable(world.timetable) if world.timetable is not None else None
    options = {key: Knowledge.params[key].default for key in ("door_width_max", "min_place_area")}
    sm = build_semantic_map(occupancy, signs, objects, timetable=timetable,
                            segment_options=options, path=poses[:, :2])
    write_semantic_map(out, sm, occupancy, signs=signs, objects=objects)
    score = score_commands(load_run_map(out), *load_commands(world.commands), world=world)
    return meta["metrics"]["knowledge"], score


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("runs", help="a sweep's folder (its runs/*) or one run's folder")
    ap.add_argument("--out", help="where the rebuilt run folders go (default: a temporary one)")
    ap.add_argument("--list", action="store_true", help="print every command whose score changed")
    args = ap.parse_args(argv)
    root = Path(args.runs)
    runs = sorted(p for p in (root / "runs").glob("*") if p.is_dir()) if (root / "runs").is_dir() \
        else [root]
    out = Path(args.out or tempfile.mkdtemp(prefix="rescored_"))
    before = after = total = 0
    print("| run | commands right as run | rebuilt today | of |\n| --- | --- | --- | --- |")
    for run in runs:
        if not all((run / name).exists() for name in NEEDED):
            continue  # unfinished, or not a semantic mapping run
        scored = rescore(run, out / run.name)
        if scored is None:
            print(f"| {run.name} | its world has no commands | | |")
            continue
        saved, score = scored
        before += saved["commands_right"]
        after += score["right"]
        total += score["total"]
        print(f"| {run.name} | {saved['commands_right']} | {score['right']} | {score['total']} |")
        if args.list:
            for was, now in zip(saved["commands_cases"], score["cases"]):
                if was["right"] != now["right"]:
                    print(f"    {was['command']!r}: {was['got'][:70]!r} -> {now['got'][:110]!r}")
    print(f"| **all** | {before} | {after} | {total} |")
    print(f"rebuilt runs in {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
