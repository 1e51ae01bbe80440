"""Pictures of a run: the world, the robots' paths, sonar cones at a tick, the signs.

``draw_run`` makes one PNG; ``animate_run`` an animated GIF. Both read what a
run with a ``sim2d.world`` node wrote: run.json, trajectory.csv and sonar.npz.
"""
from __future__ import annotations

import csv
import io
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from blocks.core.errors import SemmapError

from .world import World, load_world


@dataclass
class RunRecord:
    """What a sim2d run left in its folder."""

    folder: Path
    world: World
    dt: float
    robots: list[dict]
    ticks: np.ndarray  # (T,)
    poses: dict[str, np.ndarray] = field(default_factory=dict)  # robot -> (T, 3) true
    odom: dict[str, np.ndarray] = field(default_factory=dict)  # robot -> (T, 3)
    sonar: dict[str, dict[str, np.ndarray]] = field(default_factory=dict)

    @property
    def last_tick(self) -> int:
        return int(self.ticks.max()) if len(self.ticks) else 0


def load_run(folder: str | Path) -> RunRecord:
    """Read a run folder; a folder without a sim2d world is a clear error."""
    folder = Path(folder)
    run_json = folder / "run.json"
    if not run_json.is_file():
        raise SemmapError("no run.json here", file=folder,
                          hint="Give the output folder of 'semmap run' (its --out).")
    try:
        summary = json.loads(run_json.read_text())
    except (OSError, ValueError) as exc:
        raise SemmapError(f"run.json cannot be read: {exc}", file=run_json) from None
    world_node = next((m for m in summary.get("metrics", {}).values()
                       if isinstance(m, dict) and "world" in m), None)
    trajectory = folder / "trajectory.csv"
    if world_node is None or not trajectory.is_file():
        raise SemmapError("this run has no simulated world (no sim2d.world node, or its "
                          "trajectory.csv is missing)", file=folder,
                          hint="Render the output of a graph with a sim2d.world node.")
    world = load_world(world_node["world"])
    rows = list(csv.DictReader(io.StringIO(trajectory.read_text())))
    robots = world_node.get("robots") or [{"name": r, "length": 0.5, "width": 0.5}
                                          for r in sorted({row["robot"] for row in rows})]
    record = RunRecord(folder=folder, world=world, dt=float(summary.get("dt", 0.1)),
                       robots=robots, ticks=np.array(sorted({int(r["tick"]) for r in rows})))
    for robot in robots:
        mine = [r for r in rows if r["robot"] == robot["name"]]
        record.poses[robot["name"]] = np.array([[float(r[k]) for k in ("x", "y", "theta")]
                                                for r in mine]).reshape(-1, 3)
        record.odom[robot["name"]] = np.array([[float(r[k]) for k in
                                                ("odom_x", "odom_y", "odom_theta")]
                                               for r in mine]).reshape(-1, 3)
    sonar_file = folder / "sonar.npz"
    if sonar_file.is_file():
        with np.load(sonar_file) as data:
            for key in data.files:
                name, what = key.rsplit("@", 1)
                record.sonar.setdefault(name, {})[what] = data[key]
    return record


def record_from_simulation(sim, rows: list[tuple], dt: float, folder: Path) -> RunRecord:
    """A RunRecord from a live simulation and the world block's trajectory rows."""
    robots = [{"name": r.name, "model": r.spec.name, "length": r.spec.length,
               "width": r.spec.width} for r in sim.robots.values()]
    record = RunRecord(folder=folder, world=sim.world, dt=dt, robots=robots,
                       ticks=np.array(sorted({row[0] for row in rows}), dtype=int))
    for robot in robots:
        mine = [row for row in rows if row[2] == robot["name"]]
        record.poses[robot["name"]] = np.array([row[3:6] for row in mine]).reshape(-1, 3)
        record.odom[robot["name"]] = np.array([row[6:9] for row in mine]).reshape(-1, 3)
    for robot in sim.robots.values():
        if robot.sonar_log:
            ticks, ranges, echo = zip(*robot.sonar_log)
            record.sonar[robot.name] = {
                "tick": np.asarray(ticks), "ranges": np.asarray(ranges), "echo": np.asarray(echo),
                "mounts": robot.spec.sonar_mounts, "cone_deg": np.asarray(robot.spec.sonar.cone_deg),
                "max_range": np.asarray(robot.spec.sonar.max_range)}
    return record


def _sonar_at(record: RunRecord, name: str, tick: int):
    log = record.sonar.get(name)
    if not log or "tick" not in log or not len(log["tick"]):
        return None
    index = int(np.searchsorted(log["tick"], tick, side="right")) - 1
    if index < 0:
        return None
    return log["ranges"][index], log["echo"][index], log["mounts"], float(log["cone_deg"]), \
        float(log["max_range"])


def _figure(world: World, size_px: int = 1000):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xmin, ymin, xmax, ymax = world.bounds()
    width, height = max(xmax - xmin, 1.0), max(ymax - ymin, 1.0)
    aspect = height / width
    fig, ax = plt.subplots(figsize=(size_px / 100, max(3.0, size_px / 100 * aspect) + 0.6),
                           dpi=100)
    if world.occupied is not None:
        h, w = world.occupied.shape
        ox, oy, _ = world.origin
        ax.imshow(np.where(world.occupied, 0.15, 0.97), cmap="gray", vmin=0, vmax=1,
                  extent=(ox, ox + w * world.resolution, oy, oy + h * world.resolution),
                  interpolation="nearest", zorder=0)
    else:
        from matplotlib.collections import LineCollection
        lines = world.segments[:, :4].reshape(-1, 2, 2)
        ax.add_collection(LineCollection(lines, colors="#222222", linewidths=2, zorder=1))
    for sign in world.signs:
        dx, dy = 0.5 * math.cos(sign.facing), 0.5 * math.sin(sign.facing)
        ax.annotate("", xy=(sign.x + dx, sign.y + dy), xytext=(sign.x, sign.y),
                    arrowprops={"arrowstyle": "->", "color": "#b03a2e", "lw": 1.2}, zorder=4)
        ax.plot(sign.x, sign.y, "s", color="#b03a2e", ms=4, zorder=4)
        ax.text(sign.x + 1.6 * dx, sign.y + 1.6 * dy, sign.text, fontsize=6, color="#b03a2e",
                ha="center", va="center", zorder=4)
    ax.set_xlim(xmin - 0.5, xmax + 0.5)
    ax.set_ylim(ymin - 0.5, ymax + 0.5)
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    return fig, ax


def _draw_robots(ax, record: RunRecord, tick: int, colors: list[str]) -> list:
    from matplotlib.patches import Polygon, Wedge

    artists = []
    index = int(np.searchsorted(record.ticks, tick, side="right")) - 1
    index = max(0, min(index, len(record.ticks) - 1))
    for k, robot in enumerate(record.robots):
        name = robot["name"]
        poses = record.poses[name]
        if not len(poses):
            continue
        x, y, th = poses[index]
        sonar = _sonar_at(record, name, tick)
        if sonar is not None:
            ranges, echo, mounts, cone, max_range = sonar
            c, s = math.cos(th), math.sin(th)
            for r, e, (mx, my, mt) in zip(ranges, echo, mounts):
                sx, sy = x + c * mx - s * my, y + s * mx + c * my
                heading = math.degrees(th + mt)
                wedge = Wedge((sx, sy), r if e else max_range, heading - cone / 2,
                              heading + cone / 2, alpha=0.25 if e else 0.08,
                              color="#e67e22" if e else "#7f8c8d", lw=0, zorder=2)
                ax.add_patch(wedge)
                artists.append(wedge)
        hl, hw = robot.get("length", 0.5) / 2, robot.get("width", 0.5) / 2
        corners = np.array([[hl, hw], [hl, -hw], [-hl, -hw], [-hl, hw]])
        rot = np.array([[math.cos(th), -math.sin(th)], [math.sin(th), math.cos(th)]])
        body = Polygon(corners @ rot.T + [x, y], closed=True, color=colors[k % len(colors)],
                       zorder=5)
        ax.add_patch(body)
        nose, = ax.plot([x, x + hl * 1.4 * math.cos(th)], [y, y + hl * 1.4 * math.sin(th)],
                        color="black", lw=1.5, zorder=6)
        artists += [body, nose]
    return artists


COLORS = ["#1f77b4", "#2ca02c", "#9467bd", "#d62728", "#17becf", "#8c564b"]


def draw_run(record: RunRecord, out: str | Path, tick: int | None = None,
             odometry: bool = True) -> Path:
    """One PNG: world, signs, every robot's true path (and odometry), cones at ``tick``."""
    import matplotlib.pyplot as plt

    from blocks.core.atomic import atomic_writer

    tick = record.last_tick if tick is None else tick
    fig, ax = _figure(record.world)
    for k, robot in enumerate(record.robots):
        name, color = robot["name"], COLORS[k % len(COLORS)]
        poses = record.poses[name]
        ax.plot(poses[:, 0], poses[:, 1], color=color, lw=1.4, label=f"{name} true", zorder=3)
        if odometry:
            odom = record.odom[name]
            ax.plot(odom[:, 0], odom[:, 1], color=color, lw=1.0, ls="--", alpha=0.8,
                    label=f"{name} odometry", zorder=3)
        if len(poses):
            ax.plot(*poses[0, :2], "o", color=color, ms=6, zorder=4)
    _draw_robots(ax, record, tick, COLORS)
    ax.legend(loc="upper right", fontsize=7)
    ax.set_title(f"{record.folder.name}: tick {tick} ({tick * record.dt:.1f} s)")
    fig.tight_layout()
    out = Path(out)
    with atomic_writer(out, "wb") as fh:
        fig.savefig(fh, format="png")
    plt.close(fig)
    return out


def animate_run(record: RunRecord, out: str | Path, frames: int = 60, fps: int = 10) -> Path:
    """An animated GIF of the run: paths growing, robots and cones moving."""
    import matplotlib.pyplot as plt
    from PIL import Image

    from blocks.core.atomic import atomic_writer

    fig, ax = _figure(record.world, size_px=700)
    ticks = np.unique(np.linspace(0, record.last_tick, max(2, frames)).astype(int))
    lines = {}
    for k, robot in enumerate(record.robots):
        lines[robot["name"]], = ax.plot([], [], color=COLORS[k % len(COLORS)], lw=1.4, zorder=3)
    images = []
    for tick in ticks:
        index = int(np.searchsorted(record.ticks, tick, side="right"))
        for name, line in lines.items():
            line.set_data(record.poses[name][:index, 0], record.poses[name][:index, 1])
        artists = _draw_robots(ax, record, int(tick), COLORS)
        ax.set_title(f"tick {tick} ({tick * record.dt:.1f} s)")
        fig.canvas.draw()
        rgba = np.asarray(fig.canvas.buffer_rgba())
        images.append(Image.fromarray(rgba[:, :, :3].copy()).quantize(colors=64))
        for artist in artists:
            artist.remove()
    plt.close(fig)
    out = Path(out)
    with atomic_writer(out, "wb") as fh:
        images[0].save(fh, format="GIF", save_all=True, append_images=images[1:],
                       duration=int(1000 / fps), loop=0)
    return out
