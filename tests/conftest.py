"""Shared helpers: write graph files, run the CLI in-process, define test blocks."""
from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest

from blocks.cli import main

ROOT = Path(__file__).resolve().parents[1]


class CliResult:
    def __init__(self, code: int, out: str, err: str) -> None:
        self.code, self.out, self.err = code, out, err

    def __repr__(self) -> str:
        return f"CliResult(code={self.code}, out={self.out!r}, err={self.err!r})"


@pytest.fixture
def cli(capsys):
    """Run ``semmap ARGS`` in-process; return exit code and captured text."""

    def invoke(*args: Any) -> CliResult:
        code = main([str(a) for a in args])
        captured = capsys.readouterr()
        return CliResult(code, captured.out, captured.err)

    return invoke


@pytest.fixture
def write(tmp_path):
    """Write a dedented YAML file under tmp_path and return its path."""

    def writer(name: str, text: str) -> Path:
        path = tmp_path / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text).lstrip("\n"))
        return path

    return writer


def floor_plan(width: float, height: float, res: float = 0.05, margin: float = 0.3):
    """Cell-centre coordinates (x, y) of a map ``width`` x ``height`` m with ``margin`` m
    round it (image row 0 at the top, as a map_server PNG), for drawing test worlds."""
    import numpy as np
    h, w = int(round((height + 2 * margin) / res)), int(round((width + 2 * margin) / res))
    y, x = np.mgrid[0:h, 0:w]
    return (x + 0.5) * res - margin, (h - y - 0.5) * res - margin


def write_world(folder: Path, name: str, walls, *, start, doc: str, res: float = 0.05,
                margin: float = 0.3, extra: str = "signs: []") -> Path:
    """A world file from a wall mask drawn on :func:`floor_plan`'s cells (PNG + YAML)."""
    import cv2
    import numpy as np
    img = np.full(walls.shape, 254, np.uint8)
    img[walls] = 0
    cv2.imwrite(str(folder / f"{name}.png"), img)
    (folder / f"{name}.yaml").write_text(textwrap.dedent(f"""\
        name: {name}
        doc: {doc}
        image: {name}.png
        resolution: {res}
        origin: [{-margin}, {-margin}, 0.0]
        negate: 0
        occupied_thresh: 0.65
        free_thresh: 0.196
        start: {list(start)}
    """) + textwrap.dedent(extra))
    return folder / f"{name}.yaml"
