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
@click.option("--json", "as_json", is_flag=True, help="Print the scores as JSON.")
def score(map_yaml: str, world_name: str, tolerance: float, as_json: bool) -> None:
    """Score a map_server map against a world's floor plan (wall precision/recall, coverage).

    See docs/maps.md, "Scoring a map", for the definitions.
    """
    import math

    from sim2d.blocks import resolve_world
    from sim2d.world import load_world

    from .mapio import read_map
    from .score import score_map

    if not math.isfinite(tolerance):
        from blocks.core.errors import SemmapError
        raise SemmapError(f"--tolerance must be a finite number of metres, got {tolerance}")
    m = read_map(map_yaml)  # first: the map is the likelier typo, and quick to read
    world_path = resolve_world(world_name)
    world = load_world(world_path)
    shown = _shown(world_path)
    result = score_map(m, world, tolerance)
    if as_json:
        doc = {"map": str(map_yaml), "world": world.name, "world_file": shown,
               **result}
        click.echo(json.dumps(doc, indent=2))
        return
    click.echo(f"map    {map_yaml}")
    click.echo(f"world  {world.name} ({shown})")
    width = max(len(label) for _, label, _ in _ROWS)
    for key, label, fmt in _ROWS:
        click.echo(f"  {label:<{width}}  {fmt.format(result[key])}")
