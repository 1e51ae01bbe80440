"""Where a run's time went: the per-block profile in run.json as a sorted table and a
picture (``semmap profile RUN_DIR``).

The runner times every block call (``Runner.profile_table``) and run.json keeps
the table under ``profile``; this module only reads and presents it.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .atomic import atomic_write_figure
from .errors import SemmapError

__all__ = ["draw_profile", "load_profile", "profile_text"]

SHOWN = 12  # blocks named in the picture; the rest are summed as "the other N blocks"


def load_profile(run_dir: str | Path) -> dict[str, Any]:
    """A run's run.json, checked to hold a profile.

    Raises
    ------
    SemmapError
        When the folder has no readable run.json or it has no profile (a run
        made with profiling off).
    """
    path = Path(run_dir) / "run.json"
    try:
        summary = json.loads(path.read_text())
    except OSError:
        raise SemmapError(f"no run.json in {run_dir}", file=str(run_dir),
                          hint="Give the --out folder of a `semmap run`.") from None
    except ValueError as exc:
        raise SemmapError(f"run.json cannot be read: {exc}", file=str(path)) from None
    if not isinstance(summary, dict) or not summary.get("profile"):
        raise SemmapError("run.json has no per-block profile", file=str(path),
                          hint="It was made with profiling off, or before any tick ran.")
    return summary


def _rows(summary: dict[str, Any]) -> list[dict[str, Any]]:
    return sorted(summary["profile"], key=lambda r: -float(r["total_s"]))


def profile_text(summary: dict[str, Any], top: int | None = None) -> str:
    """The profile as a table, slowest block first by total time.

    Examples
    --------
    >>> s = {"wall_time_s": 2.0, "x_real_time": 5.0, "ticks": 100, "profile": [
    ...     {"node": "a", "type": "t", "calls": 100, "total_s": 0.5, "mean_us": 5000.0},
    ...     {"node": "b", "type": "u", "calls": 50, "total_s": 1.0, "mean_us": 20000.0}]}
    >>> print(profile_text(s).splitlines()[3])
    b     u          50      1.000    50.0 %   20000.0
    """
    rows = _rows(summary)
    wall = float(summary.get("wall_time_s") or 0.0)
    blocks_total = sum(float(r["total_s"]) for r in rows)
    shown = rows if top is None else rows[:top]
    name_w = max(4, *(len(r["node"]) for r in shown))
    type_w = max(4, *(len(r["type"]) for r in shown))
    head = (f"{'node':<{name_w}}  {'type':<{type_w}}  {'calls':>7}  {'total s':>9}  "
            f"{'share':>8}  {'mean us':>8}")
    lines = [f"{summary.get('ticks', '?')} ticks in {wall:.3f} s of wall time "
             f"({summary.get('x_real_time')}x real time); blocks took {blocks_total:.3f} s, "
             "sorted by total time:", "", head]
    for r in shown:
        share = float(r["total_s"]) / wall if wall > 0 else 0.0
        lines.append(f"{r['node']:<{name_w}}  {r['type']:<{type_w}}  {int(r['calls']):>7}  "
                     f"{float(r['total_s']):>9.3f}  {100 * share:>6.1f} %  "
                     f"{float(r['mean_us']):>8.1f}")
    if top is not None and len(rows) > top:
        rest = sum(float(r["total_s"]) for r in rows[top:])
        lines.append(f"(the other {len(rows) - top} blocks: {rest:.3f} s)")
    return "\n".join(lines) + "\n"


def draw_profile(summary: dict[str, Any], path: str | Path, *, title: str = "") -> Path:
    """A flame-style picture of the profile: one bar of the run's wall time split into its
    blocks (widest first), and a bar per block with its calls and mean time per call."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _rows(summary)
    named, rest = rows[:SHOWN], rows[SHOWN:]
    wall = float(summary.get("wall_time_s") or 0.0)
    parts = [(r["node"], float(r["total_s"])) for r in named]
    if rest:
        parts.append((f"the other {len(rest)} blocks", sum(float(r["total_s"]) for r in rest)))
    engine = max(0.0, wall - sum(t for _, t in parts))
    colours = plt.get_cmap("tab20").colors
    fig, (top, bars) = plt.subplots(2, 1, figsize=(10, 2.2 + 0.38 * len(parts)),
                                    gridspec_kw={"height_ratios": [1, max(2, len(parts) / 2)]})
    left = 0.0
    for i, (name, seconds) in enumerate(parts + [("engine and the rest", engine)]):
        colour = colours[i % len(colours)] if i < len(parts) else "lightgrey"
        top.barh(0, seconds, left=left, color=colour, edgecolor="white", label=name)
        if wall > 0 and seconds / wall > 0.06:
            top.text(left + seconds / 2, 0, name, ha="center", va="center", fontsize=8)
        left += seconds
    top.set_yticks([])
    top.set_xlim(0, max(wall, left))
    top.set_xlabel("wall time of the ticks (s)")
    top.set_title(title or f"{summary.get('ticks')} ticks in {wall:.1f} s "
                           f"({summary.get('x_real_time')}x real time)")
    y = range(len(parts))
    bars.barh(list(y), [t for _, t in parts], color=[colours[i % len(colours)] for i in y])
    bars.set_yticks(list(y), [name for name, _ in parts], fontsize=8)
    bars.invert_yaxis()
    for i, r in enumerate(named):
        bars.text(float(r["total_s"]), i, f"  {int(r['calls'])} calls, "
                  f"{float(r['mean_us']) / 1000:.2f} ms each", va="center", fontsize=7)
    bars.set_xlabel("total time per block (s)")
    bars.set_xlim(0, max(t for _, t in parts) * 1.45 if parts else 1)
    bars.grid(axis="x", alpha=0.3)
    fig.tight_layout()
    try:
        return atomic_write_figure(path, fig)
    finally:
        plt.close(fig)
