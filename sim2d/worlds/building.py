"""The building generator: ``generate_building(kind, seed, path)`` writes a new floor.

A layout (:mod:`sim2d.worlds.layouts`) draws a floor plan from a seeded
generator; rooms are named from the place vocabulary (:mod:`.names`),
furnished (:mod:`.furnish`), staffed (:mod:`.staff`) and given varied looks
(:mod:`.looks`); some floors are turned by 5-40 degrees, so their walls run at
angles the shipped worlds never have. The plan is drawn into a map_server
image (:mod:`.rasterize`), written as an ordinary world file beside its
timetable and its commands, loaded back and checked (:mod:`.checks`).
The same kind and seed give the same bytes on every machine.

Files written for ``path = DIR/NAME.yaml``: ``NAME.yaml``, ``NAME.png``,
``NAME.timetable.yaml`` and ``NAME.commands.yaml``.
"""
from __future__ import annotations

import math
import zlib
from pathlib import Path

import cv2
import numpy as np
import yaml

from blocks.core.atomic import atomic_write_bytes, atomic_write_text
from blocks.core.errors import SemmapError

from .checks import check_generated
from .floorplan import FloorPlan, snap
from .furnish import furnish
from .layouts import LAYOUTS
from .looks import building_colours
from .names import RoomNamer
from .rasterize import draw_plan, world_document
from .staff import timetable_document

__all__ = ["GENERATOR_VERSION", "GeneratorBug", "draw_building", "generate_building", "kinds"]

#: Bumped whenever the same kind and seed would draw a different floor.
GENERATOR_VERSION = 1
HEADER = ("# Drawn by semmap's building generator (`semmap world generate --kind {kind} --seed "
          "{seed}`, version {version}); regenerate it rather than editing it.\n")


class GeneratorBug(SemmapError):
    """A generated floor failed its own checks: a bug in the generator, not the user's."""

    exit_code = 1


def kinds() -> list[str]:
    """The layout kinds, in a fixed order (``gen:any`` cycles through them by seed)."""
    return list(LAYOUTS)


def _rng(kind: str, seed: int) -> np.random.Generator:
    return np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(kind.encode())]))


def draw_building(kind: str, seed: int) -> FloorPlan:
    """The floor plan of one building (not yet drawn into an image).

    Raises
    ------
    KeyError
        For an unknown kind.
    """
    draw, domain = LAYOUTS[kind]
    rng = _rng(kind, seed)
    plan = FloorPlan(kind=kind, seed=int(seed), wall=snap(rng.uniform(0.1, 0.3)), domain=domain)
    draw(plan, rng, RoomNamer(domain, rng))
    furnish(plan, rng)
    if rng.random() < 0.35:
        plan.rotation = math.radians(rng.uniform(5.0, 40.0)) * (1 if rng.random() < 0.5 else -1)
    return plan


def _dump(doc: dict) -> str:
    return yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100,
                          allow_unicode=True)


def generate_building(kind: str, seed: int, path: str | Path, *,
                      commands: bool = True) -> Path:
    """Draw one building and write it as a world file (and its side files).

    Parameters
    ----------
    kind : str
        One of :func:`kinds`.
    seed : int
        The generator seed; the same kind and seed give the same files.
    path : path
        The world YAML to write (``DIR/NAME.yaml``); the folder is created.
    commands : bool
        Also write the English commands with their right answers.

    Returns
    -------
    Path
        ``path``.

    Raises
    ------
    GeneratorBug
        If the floor fails :func:`sim2d.worlds.checks.check_generated`.
    """
    from sim2d.world import load_world
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    plan = draw_building(kind, seed)
    rng = _rng(kind + "/extras", seed)
    drawn = draw_plan(plan)
    stem = path.stem
    ok, png = cv2.imencode(".png", drawn.image, [cv2.IMWRITE_PNG_COMPRESSION, 9])
    atomic_write_bytes(path.with_suffix(".png"), png.tobytes())
    atomic_write_text(path.parent / f"{stem}.timetable.yaml",
                      _dump(timetable_document(plan, rng)))
    extra = {"timetable": f"{stem}.timetable.yaml", "colours": building_colours(rng),
             "generator": {"kind": kind, "seed": int(seed), "version": GENERATOR_VERSION}}
    doc = world_document(plan, drawn, stem, f"{stem}.png", extra)
    header = HEADER.format(kind=kind, seed=seed, version=GENERATOR_VERSION)
    atomic_write_text(path, header + _dump(doc))
    world = load_world(path)
    problems = check_generated(world)
    if problems:
        raise GeneratorBug(f"the generated {kind} building of seed {seed} fails its own "
                           f"checks: {'; '.join(problems[:5])}", file=path,
                           hint="This is a bug in the generator; please report the kind and "
                                "seed.")
    if commands:
        _write_commands(world, seed, path, doc, header)
    return path


def _write_commands(world, seed: int, path: Path, doc: dict, header: str) -> None:
    """The floor's English commands with their right answers, and the key that names them."""
    try:
        from semantic.query.exam import generate_commands, write_commands
    except ImportError:  # the query planner is optional for the simulator
        return
    from semantic.query.exam import DEFAULT_NOW
    cases = generate_commands(world, seed=seed)
    write_commands(path.parent / f"{path.stem}.commands.yaml", cases, DEFAULT_NOW)
    doc = {**doc}
    doc["commands"] = f"{path.stem}.commands.yaml"
    atomic_write_text(path, header + _dump(doc))
