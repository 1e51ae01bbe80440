"""A robot path as CSV (``tick,x,y,theta``, map frame, SI units): written by the offline
map with its drift-corrected poses, read by whoever plans on that map.

Why a file of its own: the map says where walls are, the path says where the robot
has been, which is where it provably fits (see :func:`blocks.navigate.grid.unblock_traversed`).
"""
from __future__ import annotations

import io
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from blocks.core.atomic import atomic_write_text
from blocks.core.errors import SemmapError

__all__ = ["read_path_csv", "write_path_csv"]

HEADER = "tick,x,y,theta"


def write_path_csv(path: str | Path, ticks: Sequence[int], poses: np.ndarray) -> Path:
    """Write poses (N, 3) with their ticks, atomically; returns the path written."""
    poses = np.asarray(poses, dtype=np.float64).reshape(-1, 3)
    if len(ticks) != len(poses):
        raise ValueError(f"{len(ticks)} ticks for {len(poses)} poses")
    buf = io.StringIO()
    buf.write(HEADER + "\n")
    for tick, (x, y, th) in zip(ticks, poses):
        buf.write(f"{int(tick)},{x:.4f},{y:.4f},{th:.5f}\n")
    path = Path(path)
    atomic_write_text(path, buf.getvalue())
    return path


def read_path_csv(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """The ticks (N,) and poses (N, 3) of a path CSV.

    Raises
    ------
    SemmapError
        The file is missing or not a ``tick,x,y,theta`` table (names the line).
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except OSError as exc:
        raise SemmapError(f"cannot read the path file: {exc.strerror}", file=path) from None
    if not lines or lines[0].strip() != HEADER:
        raise SemmapError(f"not a path file: the first line must be {HEADER!r}", file=path,
                          line=1, hint="Use a maps/offline_path.csv written by a mapping run.")
    ticks, poses = [], []
    for number, line in enumerate(lines[1:], start=2):
        if not line.strip():
            continue
        parts = line.split(",")
        try:
            if len(parts) != 4:
                raise ValueError
            ticks.append(int(parts[0]))
            poses.append([float(v) for v in parts[1:]])
        except ValueError:
            raise SemmapError(f"line {number} is not 'tick,x,y,theta' numbers: {line!r}",
                              file=path, line=number) from None
    return np.array(ticks, dtype=np.int64), np.array(poses, dtype=np.float64).reshape(-1, 3)
