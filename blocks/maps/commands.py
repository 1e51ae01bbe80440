"""The maps toolbox's command-line additions (registered under ``semmap.commands``)."""
from __future__ import annotations

import json
from pathlib import Path

import click

#: One line per metric in the table: (key, label, format).
_ROWS = (
    ("precision", "wall precision", "{:.3f}"),
    ("recall", "wall recall", "{:.3f}"),
    ("f1", "wall F1", "{:.3f}"),
    ("free_coverage", "free coverage", "{:.3f}"),
    ("false_free", "false free", "{:.3f}"),
    ("map_occupied_cells", "map occupied cells", "{:d}"),
    ("map_free_cells", "map free cells", "{:d}"),
    ("facing_wall_cells", "facing wall cells", "{:d}"),
    ("reachable_free_cells", "reachable free cells", "{:d}"),
    ("tolerance_m", "tolerance", "{:g} m"),
    ("map_resolution_m", "map resolution", "{:g} m"),
    ("world_resolution_m", "world resolution", "{:g} m"),
)

#: Extra lines with ``--path``: the scores restricted to what the run could see.
_VISIBLE_ROWS = (
    ("recall_visible", "visible wall recall", "{:.3f}"),
    ("f1_visible", "visible wall F1", "{:.3f}"),
    ("free_coverage_visible", "visible free coverage", "{:.3f}"),
    ("false_free_visible", "visible false free", "{:.3f}"),
    ("visible_wall_cells", "visible wall cells", "{:d}"),
    ("visible_free_cells", "visible free cells", "{:d}"),
)


def _shown(path: Path) -> str:
    """A path relative to the current folder when it is below it (shorter, machine-independent)."""
    try:
        return str(Path(path).resolve().relative_to(Path.cwd().resolve()))
    except ValueError:
        return str(path)


@click.command(name="score")
@click.argument("map_yaml", metavar="MAP.yaml", type=click.Path(dir_okay=False))
@click.option("--world", "world_name", required=True, metavar="WORLD",
              help="World library name (e.g. office) or world YAML path: the ground truth.")
@click.option("--tolerance", type=click.FloatRange(min=0.0), default=0.25, show_default=True,
              help="How far (m) a map wall may be from the true wall and still count.")
@click.option("--path", "path_csv", metavar="trajectory.csv", type=click.Path(dir_okay=False),
              default=None, help="A run's trajectory.csv: also score against what its true "
                                 "path could see (the *_visible metrics).")
@click.option("--robot", default=None, metavar="NAME",
              help="Which robot's path to read from --path (default: the file's first).")
@click.option("--seen-by", "seen_by", type=click.Choice(["sonar", "sight"]), default="sonar",
              show_default=True,
              help="What the path could see: the robot's sonar cones replayed on the true "
                   "floor plan (ideal sonar), or every cell in line of sight within --range "
                   "(an upper bound).")
@click.option("--model", default="atrv_mini", show_default=True, metavar="ROBOT",
              help="Robot model (name or YAML) whose sonar ring --seen-by sonar replays.")
@click.option("--range", "max_range", type=click.FloatRange(min=0.0, min_open=True),
              default=4.0, show_default=True,
              help="Sensor range (m) for --seen-by sight.")
@click.option("--json", "as_json", is_flag=True, help="Print the scores as JSON.")
def score(map_yaml: str, world_name: str, tolerance: float, path_csv: str | None,
          robot: str | None, seen_by: str, model: str, max_range: float, as_json: bool) -> None:
    """Score a map_server map against a world's floor plan (wall precision/recall, coverage).

    With --path, also score it against the part of the building the run's
    true path could see (by default, what its sonar ring would sweep). See docs/maps.md, "Scoring a map",
    for the definitions.
    """
    import math

    from blocks.core.errors import SemmapError
    from sim2d.blocks import resolve_world
    from sim2d.world import load_world

    from .mapio import read_map
    from .score import read_path_csv, score_map, visible_from_path

    for name, value in (("--tolerance", tolerance), ("--range", max_range)):
        if not math.isfinite(value):
            raise SemmapError(f"{name} must be a finite number of metres, got {value}")
    if robot is not None and path_csv is None:
        raise SemmapError("--robot chooses a robot of --path; give --path trajectory.csv too")
    m = read_map(map_yaml)  # first: the map is the likelier typo, and quick to read
    path_xy = None if path_csv is None else read_path_csv(path_csv, robot, ("x", "y", "theta"))
    world_path = resolve_world(world_name)
    world = load_world(world_path)
    shown = _shown(world_path)
    visible = None
    if path_xy is not None and seen_by == "sight":
        visible = visible_from_path(world, path_xy[:, :2], max_range)
    elif path_xy is not None:
        from sim2d.robot import load_robot

        from .features import sensor_poses_along
        from .visibility import sonar_visible
        spec = load_robot(model)
        max_range = spec.sonar.max_range
        visible = sonar_visible(world, sensor_poses_along(path_xy, spec.sonar_mounts)
                                .reshape(-1, 3), spec.sonar.cone_deg, max_range)
    result = score_map(m, world, tolerance, visible=visible)
    rows = _ROWS + (_VISIBLE_ROWS if visible is not None else ())
    if as_json:
        doc: dict[str, object] = {"map": str(map_yaml), "world": world.name, "world_file": shown}
        if path_csv is not None:
            doc.update({"path": str(path_csv), "path_points": len(path_xy),
                        "seen_by": seen_by, "range_m": float(max_range)})
        click.echo(json.dumps({**doc, **result}, indent=2))
        return
    click.echo(f"map    {map_yaml}")
    click.echo(f"world  {world.name} ({shown})")
    if path_csv is not None:
        click.echo(f"path   {path_csv} ({len(path_xy)} poses, seen by {seen_by}, "
                   f"range {max_range:g} m)")
    width = max(len(label) for _, label, _ in rows)
    for key, label, fmt in rows:
        click.echo(f"  {label:<{width}}  {fmt.format(result[key])}")
