"""A sweep's summary: for each declared score, the median, the 10th and 90th
percentiles, min, max and the worst runs by name, over all runs and per layout
kind (``summary.md``), and the same as a picture (``summary.png``), so the
worst building is one look away.

"Worst" follows the score's declared direction (:class:`blocks.core.scores.Score`):
the lowest runs of a higher-is-better score, the highest of a lower-is-better
one, and the *bad tail* is the 10th percentile on that side (p10 or p90).
A run counts when it ended as its graph meant (``done``, ``stopped``) or ran
out of time (``timeout``: its outputs are scored as they stood), and has the
metric; failed, interrupted and unrun runs are listed apart with their errors.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any, Iterable

import numpy as np

from blocks.core.atomic import atomic_write_figure, atomic_write_text
from blocks.core.scores import Score
from blocks.core.session import FINISHED

from .results import Flag

__all__ = ["Stats", "draw_summary", "is_yes_no", "score_stats", "summary_markdown", "write_summary"]

WORST_SHOWN = 3  # worst runs named per score
SCORED = FINISHED + ("timeout",)  # statuses of runs whose metrics count


@dataclass(frozen=True)
class Stats:
    """The distribution of one score over a set of runs.

    Attributes
    ----------
    runs : int
        Runs with a value.
    mean, median, p10, p90, min, max : float
        Of those values (NaN when there are none).
    bad_tail : float
        The 10th percentile on the bad side (p10 if higher is better, else p90).
    worst : list of (run, value)
        The worst runs, worst first (ties by name).
    """

    runs: int
    mean: float
    median: float
    p10: float
    p90: float
    min: float
    max: float
    bad_tail: float
    worst: list[tuple[str, float]]


def score_stats(rows: Iterable[dict[str, Any]], score: Score, *,
                worst: int = WORST_SHOWN) -> Stats:
    """The distribution of ``score.metric`` over ``rows``, as :func:`~.results.run_row`
    builds them from run.json (read back from results.csv, a flag is a plain number).

    Examples
    --------
    >>> s = score_stats([{"run": "a", "m": 3}, {"run": "b", "m": 1}, {"run": "c", "m": 2}],
    ...                 Score("m", "m", "higher"), worst=2)
    >>> s.median, s.min, s.worst
    (2.0, 1.0, [('b', 1.0), ('c', 2.0)])
    """
    pairs = [(str(r["run"]), float(r[score.metric])) for r in rows
             if _is_number(r.get(score.metric))]
    if not pairs:
        nan = float("nan")
        return Stats(0, nan, nan, nan, nan, nan, nan, nan, [])
    values = np.array([v for _, v in pairs])
    p10, median, p90 = (float(x) for x in np.percentile(values, [10, 50, 90]))
    sign = 1.0 if score.better == "higher" else -1.0
    ranked = sorted(pairs, key=lambda p: (sign * p[1], p[0]))
    return Stats(len(pairs), float(values.mean()), median, p10, p90, float(values.min()),
                 float(values.max()), p10 if score.better == "higher" else p90, ranked[:worst])


def is_yes_no(rows: Iterable[dict[str, Any]], metric: str) -> bool:
    """Whether ``metric`` is a flag (a boolean in run.json): its mean is a share of runs.

    A count that is 0 or 1 in every run is still a count.
    """
    values = [r[metric] for r in rows if _is_number(r.get(metric))]
    return bool(values) and all(isinstance(v, Flag) for v in values)


def _is_number(value: Any) -> bool:
    if isinstance(value, bool) or value is None or value == "":
        return False
    try:
        return bool(np.isfinite(float(value)))
    except (TypeError, ValueError):
        return False


def _fmt(value: float) -> str:
    if value != value:  # NaN
        return "–"
    if float(value).is_integer() and abs(value) < 1e6:
        return str(int(value))
    return f"{value:.3g}"


def _kinds(rows: list[dict[str, Any]]) -> list[str]:
    return sorted({str(r.get("kind") or "") for r in rows} - {""})


def summary_markdown(rows: list[dict[str, Any]], scores: list[Score], *,
                     title: str, note: str = "") -> str:
    """``summary.md``: at a glance per kind, each score in full, the runs that did not
    finish, and every metric's distribution."""
    scored = _scored(rows)
    groups = [("all", scored)] + [(k, [r for r in scored if r.get("kind") == k])
                                  for k in _kinds(rows)]
    statuses = _status_counts(rows)
    lines = [f"# {title}", ""]
    lines.append(f"{len(rows)} runs: " + ", ".join(f"{n} {s}" for s, n in statuses.items())
                 + (f". {note}" if note else "."))
    lines.append("")
    if scores:
        lines += _glance(groups, scores)
        for score in scores:
            lines += _score_section(groups, score)
    else:
        lines += ["The graph declares no `scores:`; every metric is tabulated below.", ""]
    lines += _unfinished(rows)
    lines += _every_metric(scored)
    return "\n".join(lines).rstrip() + "\n"


def _scored(rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    return [r for r in rows if r.get("status") in SCORED]


def _status_counts(rows: list[dict[str, Any]]) -> dict[str, int]:
    counts: dict[str, int] = {}
    for r in rows:
        counts[str(r.get("status"))] = counts.get(str(r.get("status")), 0) + 1
    return dict(sorted(counts.items(), key=lambda kv: (kv[0] not in FINISHED, kv[0])))


def _glance(groups, scores: list[Score]) -> list[str]:
    head = "| kind | runs | " + " | ".join(f"{s.name} ({s.better})" for s in scores) + " |"
    lines = ["## At a glance", "",
             "Runs that ended or timed out. Each cell: median · bad-side 10th percentile · "
             "worst run (higher or lower is better, as the graph declares); for a yes/no "
             "score, the share of runs saying yes.", "", head,
             "|" + " --- |" * (len(scores) + 2)]
    flags = {s.metric for s in scores if is_yes_no(groups[0][1], s.metric)}
    for name, rows in groups:
        cells = []
        for score in scores:
            st = score_stats(rows, score, worst=1)
            if score.metric in flags:
                cells.append(f"{st.mean:.0%} of runs" if st.runs else "–")
                continue
            worst = _fmt(st.worst[0][1]) if st.worst else "–"
            cells.append(f"{_fmt(st.median)} · {_fmt(st.bad_tail)} · {worst}")
        label = f"**{name}**" if name == "all" else name
        lines.append(f"| {label} | {len(rows)} | " + " | ".join(cells) + " |")
    return lines + [""]


def _score_section(groups, score: Score) -> list[str]:
    lines = [f"## {score.name}", ""]
    lines.append(f"`{score.metric}`, {score.better} is better"
                 + (f": {score.doc}" if score.doc else "") + ".")
    lines += ["", "| kind | runs | mean | median | p10 | p90 | min | max | worst runs |",
              "| --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name, rows in groups:
        st = score_stats(rows, score)
        worst = ", ".join(f"{run} ({_fmt(v)})" for run, v in st.worst) or "–"
        label = f"**{name}**" if name == "all" else name
        lines.append(f"| {label} | {st.runs} | {_fmt(st.mean)} | {_fmt(st.median)} | "
                     f"{_fmt(st.p10)} | {_fmt(st.p90)} | {_fmt(st.min)} | {_fmt(st.max)} | "
                     f"{worst} |")
    return lines + [""]


def _unfinished(rows: list[dict[str, Any]]) -> list[str]:
    bad = [r for r in rows if r.get("status") not in FINISHED]
    if not bad:
        return []
    lines = ["## Runs that did not finish", "",
             "Timed-out runs are scored above as their outputs stood; the others are not.", "",
             "| run | status | error |", "| --- | --- | --- |"]
    for r in bad:
        error = str(r.get("error") or "").replace("|", "\\|")
        lines.append(f"| {r['run']} | {r.get('status')} | {error[:300]} |")
    return lines + [""]


def _every_metric(rows: list[dict[str, Any]]) -> list[str]:
    from .results import FIXED_COLUMNS
    skip = set(FIXED_COLUMNS) - {"wall_time_s", "task_time_s", "x_real_time", "sim_time_s",
                                 "ticks"}
    names = sorted({k for r in rows for k in r} - skip)
    lines = ["## Every metric", "", "All runs with the metric; no direction is assumed.", "",
             "| metric | runs | mean | median | p10 | p90 | min | max |",
             "| --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name in names:
        st = score_stats(rows, Score(name, name, "higher"), worst=0)
        if st.runs:
            lines.append(f"| `{name}` | {st.runs} | {_fmt(st.mean)} | {_fmt(st.median)} | "
                         f"{_fmt(st.p10)} | {_fmt(st.p90)} | {_fmt(st.min)} | "
                         f"{_fmt(st.max)} |")
    return lines + [""]


def draw_summary(rows: list[dict[str, Any]], scores: list[Score], path: str | Path, *,
                 title: str) -> Path | None:
    """``summary.png``: one panel per score, runs as dots per layout kind over a box from
    p10 to p90 with the median, and the worst run named where it stands out (worse than
    the bad-side 10th percentile). None when there is nothing to draw."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rows = _scored(rows)
    drawable = [s for s in scores if score_stats(rows, s, worst=0).runs]
    if not drawable:
        return None
    groups = ["all"] + _kinds(rows)
    cols = min(3, len(drawable))
    nrows = -(-len(drawable) // cols)
    fig, axes = plt.subplots(nrows, cols, figsize=(4.6 * cols, 3.6 * nrows), squeeze=False)
    rng = np.random.default_rng(0)  # jitter only: the same picture for the same rows
    for ax, score in zip(axes.flat, drawable):
        _panel(ax, rows, score, groups, rng)
    for ax in list(axes.flat)[len(drawable):]:
        ax.set_visible(False)
    handles = [plt.Line2D([], [], color="tab:blue", marker="o", ls="", alpha=0.6, label="a run"),
               plt.Rectangle((0, 0), 1, 1, fc="lightsteelblue", ec="steelblue",
                             label="p10 to p90"),
               plt.Line2D([], [], color="navy", lw=2, label="median"),
               plt.Line2D([], [], color="tab:red", marker="x", ls="",
                          label="worst run (where it stands out)")]
    fig.legend(handles=handles, loc="lower center", ncol=4, frameon=False)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.06, 1, 0.96))
    try:
        return atomic_write_figure(path, fig)
    finally:
        plt.close(fig)


def _panel(ax, rows: list[dict[str, Any]], score: Score, groups: list[str], rng) -> None:
    from matplotlib.patches import Rectangle

    for i, group in enumerate(groups):
        members = rows if group == "all" else [r for r in rows if r.get("kind") == group]
        st = score_stats(members, score, worst=1)
        if not st.runs:
            continue
        values = [float(r[score.metric]) for r in members if _is_number(r.get(score.metric))]
        ax.add_patch(Rectangle((i - 0.3, st.p10), 0.6, st.p90 - st.p10, fc="lightsteelblue",
                               ec="steelblue", zorder=1))
        ax.plot([i - 0.3, i + 0.3], [st.median] * 2, color="navy", lw=2, zorder=3)
        ax.scatter(i + rng.uniform(-0.22, 0.22, len(values)), values, s=12, alpha=0.6,
                   color="tab:blue", zorder=2)
        run, value = st.worst[0]
        if value == st.bad_tail:
            continue  # tied with a tenth of the runs or more: naming one would mislead
        ax.scatter([i], [value], marker="x", color="tab:red", s=40, zorder=4)
        ax.annotate(run, (i, value), textcoords="offset points", xytext=(4, -10 if
                    score.better == "higher" else 4), fontsize=7, color="tab:red")
    ax.set_xticks(range(len(groups)), groups, rotation=30, ha="right")
    ax.set_xlim(-0.6, len(groups) - 0.4)
    ax.set_ylabel(score.metric, fontsize=8)
    ax.set_title(f"{score.name} ({score.better} is better)", fontsize=10)
    ax.grid(axis="y", alpha=0.3)


def write_summary(root: str | Path, rows: list[dict[str, Any]], scores: list[Score], *,
                  title: str, note: str = "") -> list[Path]:
    """Write ``DIR/summary.md`` and ``DIR/summary.png`` (when a score has values)."""
    root = Path(root)
    md = root / "summary.md"
    atomic_write_text(md, summary_markdown(rows, scores, title=title, note=note))
    png = draw_summary(rows, scores, root / "summary.png", title=title)
    return [md] + ([png] if png else [])
