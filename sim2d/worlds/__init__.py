"""The world library: floor plans in ROS map_server format (YAML + PNG).

The files here are written by ``python -m sim2d.worlds.generate``; edit
``generate.py`` and re-run it rather than editing a world by hand.

Worlds
------
corridor
    A straight 20 m x 2 m corridor closed at both ends (the paper's test case 1).
complex
    An irregular perimeter with convex and concave corners, an alcove and a
    narrow dead-end corridor (the paper's test case 2).
office
    A 30 m x 20 m office floor: a corridor loop with 14 signed rooms.
hospital
    A 40 m x 16 m hospital floor: wards off a long corridor and a hall with a
    nurses' station island.
"""
from __future__ import annotations

from pathlib import Path

WORLDS_DIR = Path(__file__).parent


def available_worlds() -> list[str]:
    """Names of the worlds in the library, sorted.

    Returns
    -------
    list of str
        One name per ``NAME.yaml`` file in :data:`WORLDS_DIR`.
    """
    return sorted(path.stem for path in WORLDS_DIR.glob("*.yaml"))


def world_path(name: str) -> Path:
    """The YAML file of a library world.

    Parameters
    ----------
    name
        A world name such as ``"office"`` (a trailing ``.yaml`` is accepted).

    Returns
    -------
    Path
        ``WORLDS_DIR / f"{name}.yaml"``.

    Raises
    ------
    sim2d.world.WorldError
        If there is no such world; the message lists the available ones.
    """
    from sim2d.world import WorldError

    stem = name[:-5] if isinstance(name, str) and name.endswith(".yaml") else name
    names = available_worlds()
    if not isinstance(stem, str) or stem not in names:
        import difflib

        close = difflib.get_close_matches(str(stem), names, n=1)
        guess = f"Did you mean {close[0]!r}? " if close else ""
        raise WorldError(f"unknown world {name!r}", field="world",
                         hint=f"{guess}Available worlds: {', '.join(names) or '(none)'}.")
    return WORLDS_DIR / f"{stem}.yaml"
