"""Sinks: record values to a file, or log them as text."""
from __future__ import annotations

import csv
import io
from typing import Any

import numpy as np

from ..core import Block, Param, Port, block
from ..core.atomic import atomic_write_text
from ..core.npzio import save_npz


@block("recorder", category="sinks")
class Recorder(Block):
    """Keeps every value it receives and writes them to the run folder at the end.

    ``npz`` stores ``values`` (stacked) and ``time``; ``csv`` writes one row
    per run with the time and the flattened value.
    """

    inputs = {"x": Port(doc="value to record")}
    params = {"file": Param(str, "", "file name in the run folder (default: NODE.FORMAT)"),
              "format": Param(str, "npz", "file format", choices=("npz", "csv"))}

    def reset(self) -> None:
        self._times: list[float] = []
        self._values: list[Any] = []

    def step(self, x: Any) -> None:
        self._times.append(self.ctx.time)
        self._values.append(x.copy() if isinstance(x, np.ndarray) else x)

    def finish(self) -> None:
        if self.ctx.out_dir is None:
            return
        name = self.p.file or f"{self.name}.{self.p.format}"
        path = self.output_path(name)
        if self.p.format == "npz":
            values = np.asarray(self._values) if self._values else np.zeros((0,))
            save_npz(path, {"values": values, "time": np.asarray(self._times)})
        else:
            text = io.StringIO()
            writer = csv.writer(text)
            for t, v in zip(self._times, self._values):
                writer.writerow([f"{t:.9g}", *np.ravel(np.asarray(v)).tolist()])
            atomic_write_text(path, text.getvalue())
        self.report("samples", len(self._values))


@block("logger", category="sinks")
class Logger(Block):
    """Writes a line of text per run to NODE.log in the run folder."""

    inputs = {"x": Port(doc="value to log")}
    params = {"format": Param(str, "{time:.3f} s: {x}", "line format with {time}, {tick}, {x}")}

    def reset(self) -> None:
        self._lines: list[str] = []

    def step(self, x: Any) -> None:
        try:
            line = self.p.format.format(time=self.ctx.time, tick=self.ctx.tick, x=x)
        except (KeyError, IndexError, ValueError) as exc:
            from ..core import BlockError
            raise BlockError(f"bad log format {self.p.format!r}: {exc}",
                             field="param 'format'",
                             hint="Use the fields {time}, {tick} and {x}.") from None
        self._lines.append(line)

    def finish(self) -> None:
        if self.ctx.out_dir is not None:
            atomic_write_text(self.output_path(f"{self.name}.log"),
                              "\n".join(self._lines) + ("\n" if self._lines else ""))


def plot_series(times: np.ndarray, values: np.ndarray, path, *, title: str = "",
                ylabel: str = "", labels: list[str] | None = None) -> None:
    """Line plot of values (one line per column) against time, saved as PNG atomically."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..core.atomic import atomic_writer

    values = np.asarray(values, dtype=float)
    series = values.reshape(len(values), -1) if values.size else np.zeros((0, 1))
    fig, ax = plt.subplots(figsize=(8, 3.5))
    for column in range(series.shape[1]):
        label = labels[column] if labels and column < len(labels) else None
        ax.plot(times, series[:, column], lw=1.2, label=label)
    if labels:
        ax.legend(loc="best", fontsize=8)
    ax.set_xlabel("time [s]")
    ax.set_ylabel(ylabel)
    ax.set_title(title)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    with atomic_writer(path, "wb") as fh:
        fig.savefig(fh, format="png", dpi=100)
    plt.close(fig)


@block("plot", category="sinks")
class Plot(Block):
    """Plots a scalar or small vector against time into NODE.png at the end of the run."""

    inputs = {"x": Port(doc="number or 1-D array to plot")}
    params = {"title": Param(str, "", "plot title (default: the node name)"),
              "ylabel": Param(str, "", "y-axis label, e.g. 'v [m/s]'"),
              "labels": Param(list, [], "one legend label per column")}

    def reset(self) -> None:
        self._times: list[float] = []
        self._values: list[Any] = []

    def step(self, x: Any) -> None:
        if x is None:
            return
        self._times.append(self.ctx.time)
        self._values.append(np.array(x, dtype=float, copy=True))

    def finish(self) -> None:
        if self.ctx.out_dir is None:
            return
        try:
            values = np.asarray(self._values, dtype=float)
        except ValueError:
            from ..core import BlockError
            raise BlockError("plot input changed shape during the run", node=self.name) from None
        plot_series(np.asarray(self._times), values, self.output_path(f"{self.name}.png"),
                    title=self.p.title or self.name, ylabel=self.p.ylabel,
                    labels=[str(v) for v in self.p.labels] or None)
