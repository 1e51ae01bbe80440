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
