"""Pictures of worlds: one floor with its ground truth, or a sheet of many.

The floor plan is drawn in world metres (axes in m, a scale given by the
axes), each place tinted and named, doors as green bars (red crosses when
shut), signs as short red bars with their text, objects as blue dots, the
start as a green arrow; a legend says which is which.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from sim2d.world import World

__all__ = ["draw_world", "show_world", "show_worlds"]


def draw_world(ax, world: World, *, labels: bool = True, title: str | None = None) -> None:
    """Draw one world into a matplotlib axes (metres, y up)."""
    from matplotlib.patches import Polygon
    h, w = world.occupied.shape
    ox, oy = world.origin[:2]
    extent = (ox, ox + w * world.resolution, oy, oy + h * world.resolution)
    ax.imshow(np.where(world.occupied, 0.15, 1.0), cmap="gray", vmin=0, vmax=1, extent=extent,
              interpolation="nearest")
    colours = __import__("matplotlib").colormaps["tab20"]
    for i, place in enumerate(world.places):
        ax.add_patch(Polygon(place.polygon, closed=True, facecolor=colours(i % 20), alpha=0.35,
                             edgecolor="none"))
        if labels:
            cx, cy = np.asarray(place.polygon).mean(axis=0)
            ax.text(cx, cy, place.name, fontsize=4, ha="center", va="center", color="0.2")
    for d in world.doors:
        if d.closed:
            ax.plot(d.x, d.y, "x", color="red", ms=4, mew=1.2)
        else:
            ax.plot(d.x, d.y, "s", color="green", ms=2.5)
    for s in world.signs:
        tx, ty = -math.sin(s.facing) * s.width / 2, math.cos(s.facing) * s.width / 2
        ax.plot([s.x - tx, s.x + tx], [s.y - ty, s.y + ty], color="red", lw=2)
        if labels:
            ax.text(s.x + 0.6 * math.cos(s.facing), s.y + 0.6 * math.sin(s.facing), s.text,
                    fontsize=3.5, color="darkred", ha="center", va="center")
    if world.objects:
        ax.plot([o.x for o in world.objects], [o.y for o in world.objects], "o",
                color="royalblue", ms=2.5)
    x, y, th = world.start
    ax.annotate("", xy=(x + 1.2 * math.cos(th), y + 1.2 * math.sin(th)), xytext=(x, y),
                arrowprops={"arrowstyle": "->", "color": "green", "lw": 1.5})
    ax.plot(x, y, "o", color="green", ms=4)
    ax.set_aspect("equal")
    ax.set_xlabel("x (m)", fontsize=6)
    ax.set_ylabel("y (m)", fontsize=6)
    ax.tick_params(labelsize=5)
    if title:
        ax.set_title(title, fontsize=7)


def _legend(fig) -> None:
    from matplotlib.lines import Line2D
    handles = [Line2D([], [], color="red", lw=2, label="sign plate"),
               Line2D([], [], marker="s", color="green", ls="", label="open door"),
               Line2D([], [], marker="x", color="red", ls="", label="closed door"),
               Line2D([], [], marker="o", color="royalblue", ls="", label="object"),
               Line2D([], [], marker=">", color="green", ls="", label="start pose"),
               Line2D([], [], color="0.15", lw=4, label="wall, furniture")]
    fig.legend(handles=handles, loc="lower center", ncol=6, fontsize=7, frameon=False)


def _title(world: World) -> str:
    gen = world.generator
    head = f"{gen['kind']} seed {gen['seed']}" if gen else world.name
    x0, y0, x1, y1 = world.bounds()
    return f"{head} ({x1 - x0:.0f} x {y1 - y0:.0f} m, {len(world.signs)} signs)"


def show_world(world: World, path: str | Path, *, dpi: int = 200) -> Path:
    """Draw one world with its ground truth into a PNG (written atomically)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from blocks.core.atomic import atomic_write_figure
    x0, y0, x1, y1 = world.bounds()
    aspect = (y1 - y0) / max(x1 - x0, 1e-6)
    fig, ax = plt.subplots(figsize=(9, max(3.5, 9 * aspect) + 0.8))
    draw_world(ax, world, title=_title(world) + (f"\n{world.extra.get('doc', '')}"
                                                 if world.extra.get("doc") else ""))
    _legend(fig)
    fig.tight_layout(rect=(0, 0.05, 1, 1))
    return atomic_write_figure(path, fig)


def show_worlds(worlds: list[World], path: str | Path, *, columns: int = 4) -> Path:
    """A sheet of small pictures of several worlds (one per panel), written atomically."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from blocks.core.atomic import atomic_write_figure
    rows = math.ceil(len(worlds) / columns)
    fig, axes = plt.subplots(rows, columns, figsize=(4.2 * columns, 3.4 * rows + 0.5),
                             squeeze=False)
    for ax, world in zip(axes.flat, worlds):
        draw_world(ax, world, labels=False, title=_title(world))
    for ax in list(axes.flat)[len(worlds):]:
        ax.axis("off")
    _legend(fig)
    fig.tight_layout(rect=(0, 0.04, 1, 1))
    return atomic_write_figure(path, fig)
