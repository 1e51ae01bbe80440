"""A picture of a plan: its legs over the map, numbered steps, and the path driven."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from blocks.core.atomic import atomic_write_figure

from .mapsource import QueryMap
from .tasks import TaskPlan

__all__ = ["draw_plan"]

_COLOURS = {"go to": "#1f5fa8", "pick up": "#2e8b57", "hand over": "#b03a2e",
            "look for": "#8e44ad"}


def draw_plan(path: str | Path, plan: TaskPlan, qm: QueryMap, *,
              driven: np.ndarray | None = None, size_px: int = 1200) -> Path:
    """Write a PNG (atomically): the map, place names, the planned path (blue), each
    step numbered at its place, and, if given, the path driven (N, 2) in orange."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    m = qm.occupancy
    p = np.asarray(m.occupancy, dtype=np.float64)
    occupied, free, _ = m.classes()
    rgb = np.full(p.shape + (3,), 0.82)
    rgb[free] = 1.0
    rgb[occupied] = 0.0
    h, w = p.shape
    ox, oy = float(m.origin[0]), float(m.origin[1])
    extent = (ox, ox + w * m.resolution, oy, oy + h * m.resolution)
    aspect = (extent[3] - extent[2]) / (extent[1] - extent[0])
    from blocks.maps.mapio import display_sized
    fig_h = max(3.0, size_px / 100 * aspect) + 0.8
    fig, ax = plt.subplots(figsize=(size_px / 100, fig_h), dpi=100)
    try:
        ax.imshow(display_sized(rgb, size_px, 100 * fig_h), origin="lower", extent=extent,
                  interpolation="nearest", zorder=0)
        for info in qm.places.values():
            if info.name and info.centre:
                ax.text(*info.centre, info.name, fontsize=7, ha="center", va="center",
                        color="#555555", zorder=2)
        route = plan.path
        if len(route):
            ax.plot(route[:, 0], route[:, 1], "-", color="#1f5fa8", lw=2, zorder=4,
                    label=f"plan ({plan.path_length:.1f} m)")
        if driven is not None and len(driven):
            ax.plot(driven[:, 0], driven[:, 1], "-", color="#e67e22", lw=1.2, zorder=5,
                    label="driven")
        ax.plot(*qm.home[:2], "o", color="black", ms=6, zorder=6, label="start")
        for k, step in enumerate(plan.steps, start=1):
            if step.action == "go to":
                continue
            ax.plot(step.x, step.y, "o", color=_COLOURS.get(step.action, "black"), ms=9, zorder=7)
            ax.annotate(f"{k}. {step.action} {step.object or ''}".strip(), (step.x, step.y),
                        xytext=(6, 6), textcoords="offset points", fontsize=8, zorder=8,
                        bbox={"boxstyle": "round,pad=0.2", "fc": "white", "alpha": 0.85})
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(f'"{plan.grounding.request.text}"')
        ax.legend(loc="upper right", fontsize=7)
        fig.tight_layout()
        return atomic_write_figure(path, fig)
    finally:
        plt.close(fig)
