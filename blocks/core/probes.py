"""Probes: record a port's values per tick, and read them back into numpy.

Numeric values (scalars and same-shaped arrays) go to ``probes.npz`` as a
``(ticks, *shape)`` array under the port's name, with the ticks under
``NAME@tick``. Anything else (messages, ragged arrays) goes to
``probes/NAME.jsonl``, one ``{"tick": t, "value": ...}`` line per tick.
"""
from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from .atomic import atomic_writer
from .jsonable import to_jsonable
from .npzio import save_npz


@dataclass
class Probe:
    """Values of one port, appended on the ticks the port was written."""

    name: str
    ticks: list[int] = field(default_factory=list)
    values: list[Any] = field(default_factory=list)

    def append(self, tick: int, value: Any) -> None:
        self.ticks.append(tick)
        self.values.append(value.copy() if isinstance(value, np.ndarray) else value)

    def as_array(self) -> np.ndarray | None:
        """The values stacked into one array, or None when they do not stack."""
        if not self.values:
            return np.zeros((0,))
        try:
            arr = np.asarray(self.values)
        except ValueError:
            return None
        return None if arr.dtype == object else arr


def save_probes(probes: list[Probe], out_dir: Path) -> list[str]:
    """Write every probe; return the files written."""
    arrays: dict[str, np.ndarray] = {}
    written = []
    for probe in probes:
        arr = probe.as_array()
        if arr is not None:
            arrays[probe.name] = arr
            arrays[probe.name + "@tick"] = np.asarray(probe.ticks, dtype=np.int64)
            continue
        path = out_dir / "probes" / f"{probe.name}.jsonl"
        path.parent.mkdir(parents=True, exist_ok=True)
        with atomic_writer(path, "w") as fh:
            for tick, value in zip(probe.ticks, probe.values):
                fh.write(json.dumps({"tick": tick, "value": to_jsonable(value)}) + "\n")
        written.append(str(path))
    if arrays:
        path = out_dir / "probes.npz"
        save_npz(path, arrays)
        written.insert(0, str(path))
    return written


def load_probes(run_dir: str | Path) -> dict[str, tuple[np.ndarray, Any]]:
    """Read a run's probes back: ``{name: (ticks, values)}``.

    Numeric probes give a numpy array of values; others a list.
    """
    run_dir = Path(run_dir)
    result: dict[str, tuple[np.ndarray, Any]] = {}
    npz = run_dir / "probes.npz"
    if npz.exists():
        with np.load(npz) as data:
            for key in data.files:
                if not key.endswith("@tick"):
                    result[key] = (data[key + "@tick"], data[key])
    for path in sorted((run_dir / "probes").glob("*.jsonl")):
        rows = [json.loads(line) for line in path.read_text().splitlines() if line]
        result[path.stem] = (np.asarray([r["tick"] for r in rows], dtype=np.int64),
                             [r["value"] for r in rows])
    return result
