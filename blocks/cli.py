"""The ``semmap`` command: run, check, list and draw graphs.

User errors print one paragraph and exit 2; a block's crash prints one
paragraph pointing at ``error.log`` and exits 1; Ctrl-C exits 130 after
writing ``run.json`` and every output produced so far.
"""
from __future__ import annotations

import json
import os
import sys
import time
from pathlib import Path
from typing import Any

import click

from .core.atomic import atomic_write_text
from .core.errors import SemmapError


def in_ci() -> bool:
    """Whether this runs under CI (``CI`` set and not false): no progress displays there."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def _progress_enabled(quiet: bool) -> bool:
    return not quiet and not in_ci() and sys.stderr.isatty()


def _load(graph: str, overrides: tuple[str, ...] = (), world: str | None = None):
    from .core.loader import load_graph
    return load_graph(graph, list(overrides), roles={"world": world} if world else None)


class ToolboxCommands(click.Group):
    """A group that also offers the toolboxes' commands (entry points ``semmap.commands``),
    importing each only when it is used."""

    def _entry_points(self) -> dict[str, Any]:
        from importlib.metadata import entry_points
        return {ep.name: ep for ep in entry_points(group="semmap.commands")}

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(set(super().list_commands(ctx)) | set(self._entry_points()))

    def get_command(self, ctx: click.Context, name: str) -> click.Command | None:
        command = super().get_command(ctx, name)
        if command is not None:
            return command
        ep = self._entry_points().get(name)
        if ep is None:
            return None
        try:
            return ep.load()
        except Exception as exc:  # a broken toolbox must not break the other commands
            raise SemmapError(f"the command '{name}' from {ep.value} failed to load: "
                              f"{type(exc).__name__}: {exc}") from None


@click.group(cls=ToolboxCommands, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="semmap", prog_name="semmap")
def cli() -> None:
    """semmap: compose blocks into YAML graphs and run them."""


@cli.command()
@click.argument("graph", type=click.Path(dir_okay=False))
@click.option("--set", "overrides", multiple=True, metavar="NODE.PARAM=VALUE",
              help="Override a parameter; dotted paths reach into subgraphs. Repeatable.")
@click.option("--steps", type=click.IntRange(min=0), help="Ticks to run (default: the graph's).")
@click.option("--seed", type=int, default=0, show_default=True, help="Run seed.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False),
              help="Output folder (default: runs/GRAPH_NAME).")
@click.option("--record", "records", multiple=True, metavar="NODE.PORT",
              help="Probe a port every tick into probes.npz. Repeatable.")
@click.option("--strict", is_flag=True, help="Check every value against its port schema.")
@click.option("--world", metavar="FILE|NAME",
              help="Set the world of every node that takes one (parameters with role 'world').")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar or summary.")
def run(graph: str, overrides: tuple[str, ...], steps: int | None, seed: int,
        out_dir: str | None, records: tuple[str, ...], strict: bool, world: str | None,
        quiet: bool) -> None:
    """Run GRAPH in lockstep and write run.json and the blocks' outputs."""
    from .core.runner import BlockFailure
    from .core.session import run_graph

    flat = _load(graph, overrides, world)
    out = Path(out_dir) if out_dir else Path("runs") / flat.name
    n_steps = steps if steps is not None else flat.steps
    bar = _make_bar(n_steps, flat.dt) if _progress_enabled(quiet) else None
    try:
        outcome = run_graph(flat, out, seed=seed, steps=n_steps, records=records,
                            strict=strict, on_tick=bar.tick if bar else None,
                            on_ticks_end=bar.close if bar else None)
    finally:
        if bar:
            bar.close()  # also when the graph could not be built
    failure = outcome.failure
    if isinstance(failure, BlockFailure):
        raise _Failure(f"{failure}. Outputs written so far are in {out}/; the full traceback "
                       f"is in {out / 'error.log'}.", 1)
    if failure is not None:
        raise failure
    for message in outcome.finish_errors:
        click.echo(f"warning: {message}", err=True)
    if outcome.status == "interrupted":
        click.echo(f"interrupted at tick {outcome.summary['ticks']}; outputs so far are in "
                   f"{out}/", err=True)
        raise _Failure("", 130)
    if not quiet:
        _print_summary(outcome.summary, out)
    else:
        click.echo(str(out))


class _Failure(Exception):
    """Exit with a message and code (raised inside commands, handled in main)."""

    def __init__(self, message: str, code: int) -> None:
        super().__init__(message)
        self.code = code


class _Bar:
    """tqdm bar showing ticks and the x-real-time ratio."""

    def __init__(self, total: int | None, dt: float) -> None:
        from tqdm import tqdm
        self.bar = tqdm(total=total, unit="tick", dynamic_ncols=True, leave=False)
        self.dt = dt
        self.start = time.perf_counter()
        self.last = 0

    def tick(self, t: int) -> None:
        self.bar.update(t - self.last)
        self.last = t
        if t % 50 == 0:
            wall = time.perf_counter() - self.start
            if wall > 0:
                self.bar.set_postfix_str(f"{t * self.dt / wall:.1f}x real time", refresh=False)

    def close(self) -> None:
        self.bar.close()


def _make_bar(total: int | None, dt: float) -> _Bar:
    return _Bar(total, dt)


def _print_summary(s: dict[str, Any], out: Path) -> None:
    ratio = f"{s['x_real_time']}x real time" if s["x_real_time"] else ""
    reason = f" ({s['stop_reason']})" if s["stop_reason"] else ""
    click.echo(f"{s['status']}{reason}: {s['ticks']} ticks, {s['sim_time_s']:.3f} s simulated "
               f"in {s['wall_time_s']:.3f} s {ratio}")
    slowest = [r for r in s["profile"][:5] if r["calls"]]
    if slowest:
        click.echo("slowest blocks: " + ", ".join(
            f"{r['node']} {r['mean_us']:.1f} us/call" for r in slowest))
    click.echo(f"outputs: {out}/ (run.json" + (", probes" if s["records"] else "") +
               (f", {len(s['outputs'])} files" if s["outputs"] else "") + ")")


@cli.command()
@click.argument("graph", type=click.Path(dir_okay=False))
@click.option("--set", "overrides", multiple=True, metavar="NODE.PARAM=VALUE")
@click.option("--schedule", "show_schedule", is_flag=True, help="Print the static schedule.")
@click.option("--params", "show_params", is_flag=True, help="List every settable parameter.")
def check(graph: str, overrides: tuple[str, ...], show_schedule: bool, show_params: bool) -> None:
    """Validate GRAPH without running it (exit 0 valid, 2 invalid)."""
    from .core.validate import check_graph, schedule

    flat = _load(graph, overrides)
    check_graph(flat)
    tasks = schedule(flat)
    click.echo(f"ok: {graph}: {len(flat.nodes)} nodes, {len(flat.edges)} edges, "
               f"{len(tasks)} scheduled tasks, dt {flat.dt} s")
    if show_schedule:
        for i, task in enumerate(tasks):
            node = flat.nodes[task.node]
            gate = []
            if node.period > 1:
                gate.append(f"every {node.period} ticks from {node.offset}")
            for group in node.triggers:
                gate.append("when " + " or ".join(str(s) for s in group))
            phase = "" if task.phase == "step" else f" [{task.phase}]"
            click.echo(f"{i:4d}  {task.node}{phase}  ({node.type_name})"
                       + (f"  {'; '.join(gate)}" if gate else ""))
    if show_params:
        for key, value in flat.params.items():
            click.echo(f"{key} = {value!r}  ({flat.param_sources.get(key)})")
        for key, (value, source) in flat.subgraph_params.items():
            click.echo(f"{key} = {value!r}  ({source})")
        for node in flat.nodes.values():
            if node.implicit:
                continue
            for key, value in node.params.items():
                click.echo(f"{node.path}.{key} = {value!r}  ({node.param_sources.get(key)})")


@cli.command(name="blocks")
@click.argument("type_name", required=False)
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output.")
@click.option("--markdown", is_flag=True, help="The reference docs in Markdown.")
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write to a file.")
def blocks_cmd(type_name: str | None, as_json: bool, markdown: bool, output: str | None) -> None:
    """List the block palette, or describe one block TYPE."""
    from .core.palette import describe, palette, to_markdown, to_text
    from .core.registry import REGISTRY

    REGISTRY.ensure_loaded()
    for warning in REGISTRY.load_warnings:
        click.echo(f"warning: {warning}", err=True)
    if type_name:
        try:
            entry = describe(type_name)
        except KeyError:
            close = REGISTRY.closest(type_name)
            raise SemmapError(f"unknown block type '{type_name}'",
                              hint=(f"Did you mean {' or '.join(map(repr, close))}?" if close
                                    else "Run 'semmap blocks' to list them.")) from None
        text = json.dumps(entry, indent=2, default=str) + "\n" if as_json else to_text(entry)
    else:
        entries = palette(published_only=markdown)
        if as_json:
            text = json.dumps(entries, indent=2, default=str) + "\n"
        elif markdown:
            text = to_markdown(entries)
        else:
            rows = []
            for category in sorted({e["category"] for e in entries}):
                rows.append(f"{category}:")
                for e in (x for x in entries if x["category"] == category):
                    rows.append(f"  {e['type']:<24} {e['summary']}")
            text = "\n".join(rows) + "\n"
    _emit(text, output)


@cli.command()
@click.argument("graph", type=click.Path(dir_okay=False))
@click.option("--format", "fmt", type=click.Choice(["mermaid", "dot", "png"]), default="mermaid",
              show_default=True)
@click.option("-o", "--output", type=click.Path(dir_okay=False), help="Write to a file.")
@click.option("--set", "overrides", multiple=True, metavar="NODE.PARAM=VALUE")
def graph(graph: str, fmt: str, output: str | None, overrides: tuple[str, ...]) -> None:
    """Draw GRAPH as Mermaid, Graphviz DOT or a PNG picture."""
    from .core.render import to_dot, to_mermaid, to_png
    from .core.validate import check_graph

    flat = _load(graph, overrides)
    check_graph(flat)
    if fmt == "png":
        if not output:
            raise SemmapError("--format png needs -o FILE.png")
        to_png(flat, output)
        click.echo(output)
        return
    _emit(to_mermaid(flat) if fmt == "mermaid" else to_dot(flat), output)


@cli.command()
@click.argument("graph", type=click.Path(dir_okay=False))
@click.option("--set", "overrides", multiple=True, metavar="NODE.PARAM=VALUE")
@click.option("--seed", type=int, default=0, show_default=True)
def debug(graph: str, overrides: tuple[str, ...], seed: int) -> None:
    """Step through GRAPH tick by tick and inspect ports (type 'help')."""
    from .core.debugger import Debugger
    from .core.runner import Runner

    Debugger(Runner(_load(graph, overrides), seed=seed)).loop()


@cli.command()
@click.argument("run_dir", type=click.Path(file_okay=False))
@click.option("-o", "--output", type=click.Path(dir_okay=False),
              help="Picture to write (default: RUN_DIR/profile.png).")
@click.option("--top", type=click.IntRange(min=1), help="Show only the N slowest blocks.")
def profile(run_dir: str, output: str | None, top: int | None) -> None:
    """Print where RUN_DIR's time went, slowest block first, and draw it to a PNG."""
    from .core.atomic import ensure_writable_dir
    from .core.profile_report import draw_profile, load_profile, profile_text

    summary = load_profile(run_dir)
    click.echo(profile_text(summary, top), nl=False)
    target = Path(output) if output else Path(run_dir) / "profile.png"
    ensure_writable_dir(target.parent, what="-o")
    click.echo(str(draw_profile(summary, target)))


def _emit(text: str, output: str | None) -> None:
    if output:
        atomic_write_text(output, text)
        click.echo(output, err=True)
    else:
        click.echo(text, nl=False)


def main(argv: list[str] | None = None) -> int:
    """Console entry point: never shows a traceback for a user error."""
    try:
        cli.main(args=argv, prog_name="semmap", standalone_mode=False)
        return 0
    except SemmapError as exc:
        click.echo(f"error: {exc}", err=True)
        return exc.exit_code
    except _Failure as exc:
        if str(exc):
            click.echo(f"error: {exc}", err=True)
        return exc.code
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        return 130
    except click.ClickException as exc:
        exc.show()
        return 2
    except KeyboardInterrupt:
        click.echo("interrupted", err=True)
        return 130
    except BrokenPipeError:
        return 0
    except Exception as exc:  # from the loader or a block's construction
        from .core.runner import BlockFailure
        if isinstance(exc, BlockFailure):
            click.echo(f"error: {exc}", err=True)
            return 1
        raise


if __name__ == "__main__":
    sys.exit(main())
