"""sim2d's command-line additions (registered under the ``semmap.commands`` entry points)."""
from __future__ import annotations

from pathlib import Path

import click


@click.command(name="render")
@click.argument("run_dir", type=click.Path(file_okay=False))
@click.option("--tick", type=int, help="Tick at which to draw the robots and sonar cones "
                                       "(default: the last).")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="PNG to write (default: RUN_DIR/render.png).")
@click.option("--gif", "gif", is_flag=True, help="Also write an animated RUN_DIR/run.gif.")
@click.option("--frames", type=click.IntRange(2, 500), default=60, show_default=True,
              help="GIF frames.")
@click.option("--no-odometry", is_flag=True, help="Leave out the odometry paths.")
def render(run_dir: str, tick: int | None, output: str | None, gif: bool, frames: int,
           no_odometry: bool) -> None:
    """Draw a simulated run: world, signs, paths, sonar cones at a tick (PNG, optional GIF)."""
    from blocks.core.errors import SemmapError

    from .render import animate_run, draw_run, load_run

    record = load_run(run_dir)
    if tick is not None and not 0 <= tick <= record.last_tick:
        raise SemmapError(f"--tick {tick} is outside the run (0..{record.last_tick})",
                          file=run_dir)
    png = draw_run(record, Path(output) if output else Path(run_dir) / "render.png", tick,
                   odometry=not no_odometry)
    click.echo(str(png))
    if gif:
        click.echo(str(animate_run(record, Path(run_dir) / "run.gif", frames=frames)))


@click.group(name="world")
def world() -> None:
    """Generate buildings, list their kinds, and draw worlds."""


@world.command(name="kinds")
def world_kinds() -> None:
    """List the building generator's layout kinds."""
    from .worlds.layouts import LAYOUTS
    for kind, (draw, domain) in LAYOUTS.items():
        summary = (draw.__module__ and __import__(draw.__module__, fromlist=["x"]).__doc__ or "")
        click.echo(f"{kind:<10} {summary.strip().splitlines()[0]}  (rooms: {domain})")


@world.command(name="generate")
@click.option("--kind", required=True, help="Layout kind (see `semmap world kinds`), or any.")
@click.option("--seed", type=click.IntRange(min=0), required=True, help="Generator seed.")
@click.option("--out", "out", type=click.Path(dir_okay=False), required=True,
              help="World YAML to write (its PNG, timetable and commands go beside it).")
@click.option("--show", "show", is_flag=True, help="Also draw it to OUT's stem + .preview.png.")
def world_generate(kind: str, seed: int, out: str, show: bool) -> None:
    """Draw a new building from KIND and SEED and write it as a world file."""
    from blocks.core.atomic import ensure_writable_dir
    from .world import load_world
    from .worlds.family import generated_world
    from .worlds.show import show_world

    path = Path(out)
    if path.suffix not in (".yaml", ".yml"):
        from blocks.core.errors import SemmapError
        raise SemmapError(f"--out {out!r} must be a world YAML file name (.yaml)",
                          field="--out", hint="For example --out worlds/ring-7.yaml.")
    ensure_writable_dir(path.parent, what="--out")
    written = generated_world(f"gen:{kind}:{seed}", path.parent, name=path.stem)
    click.echo(str(written))
    if show:
        click.echo(str(show_world(load_world(written), path.with_suffix(".preview.png"))))


@world.command(name="show")
@click.argument("world_spec", metavar="WORLD")
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="PNG to write (default: the world file's stem + .png in the current folder).")
def world_show(world_spec: str, output: str | None) -> None:
    """Draw WORLD (a file, a library name or gen:KIND:SEED) with its ground truth to a PNG."""
    from blocks.core.atomic import ensure_writable_dir
    from .blocks import resolve_world
    from .world import load_world
    from .worlds.show import show_world

    loaded = load_world(resolve_world(world_spec))
    target = Path(output) if output else Path(f"{loaded.name}.png")
    ensure_writable_dir(target.parent, what="-o")
    click.echo(str(show_world(loaded, target)))
