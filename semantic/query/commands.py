"""``semmap ask``: English commands and questions to plans on a semantic map."""
from __future__ import annotations

import contextlib
import datetime as dt
import json
import sys
from pathlib import Path

import click

from blocks.core.atomic import atomic_write_json
from blocks.core.errors import SemmapError

from .mapsource import QueryMap, load_map
from .session import ask as plan_command
from .session import parse_now
from .tasks import TaskPlan

__all__ = ["ask", "format_plan"]


def format_plan(plan: TaskPlan) -> str:
    """The plan as a person reads it: objectives with their reasons, numbered steps with
    leg lengths and routes, the answer."""
    g = plan.grounding
    lines = []
    if g.objectives:
        lines.append("objectives:")
        for o in g.objectives:
            thing = f" {o.thing}" if o.thing else ""
            at = " " if o.action == "go to" else " at "
            lines.append(f"  - {o.action}{thing}{at}{o.target.label}  ({o.target.why})")
    if plan.steps:
        lines.append("plan:")
        for k, s in enumerate(plan.steps, start=1):
            if s.action == "go to":
                via = f"  via {' > '.join(s.route)}" if len(s.route) > 2 else ""
                lines.append(f"  {k}. go to {s.place} ({s.x:.2f}, {s.y:.2f}): "
                             f"{s.leg_m:.1f} m{via}")
            else:
                lines.append(f"  {k}. {s.action} {s.object or ''} at {s.place}".rstrip())
        lines.append(f"  total path: {plan.path_length:.1f} m")
    if g.answer:
        lines.append(f"answer: {g.answer}")
    return "\n".join(lines)


def _answer(command: str, qm: QueryMap, now: dt.datetime | None, as_json: bool,
            out: Path | None) -> TaskPlan:
    plan = plan_command(command, qm, now=now)
    if as_json:
        click.echo(json.dumps(plan.to_dict(), indent=2))
    else:
        click.echo(format_plan(plan))
    if out is not None:
        from .draw import draw_plan
        out.mkdir(parents=True, exist_ok=True)
        atomic_write_json(out / "plan.json", plan.to_dict())
        draw_plan(out / "plan.png", plan, qm)
        if not as_json:
            click.echo(f"wrote {out / 'plan.json'} and {out / 'plan.png'}")
    return plan


#: The graph ``--execute`` runs: the planner block feeding navigate.goto in sim2d.
EXECUTE_GRAPH = Path(__file__).resolve().parents[2] / "graphs" / "ask.yaml"


def _execute(ctx: click.Context, command: str, map_source: str, qm: QueryMap,
             now: dt.datetime | None, out: Path, as_json: bool) -> None:
    """Drive the plan in sim2d: ``semmap run graphs/ask.yaml`` with this command and map."""
    from blocks.cli import run
    if qm.world is None:
        raise SemmapError(f"cannot execute: the world of {qm.source} is not known", field="--map",
                          hint="Execute on a run made by this version of semmap, or on a world.")
    when = (now or dt.datetime.now()).isoformat(timespec="minutes")
    run_map = str(Path(map_source).resolve()) if Path(map_source).is_dir() else ""
    overrides = (f"command={json.dumps(command)}", f"map={json.dumps(run_map)}",
                 f"world={json.dumps(str(qm.world))}", f"now={when}")
    with contextlib.redirect_stdout(sys.stderr):  # stdout stays the plan (and its JSON)
        ctx.invoke(run, graph=str(EXECUTE_GRAPH), overrides=overrides, steps=None, seed=0,
                   out_dir=str(out), records=(), strict=False, world=None, quiet=True)
    metrics = json.loads((out / "run.json").read_text()).get("metrics", {})
    goals = metrics.get("goto", {}).get("goals", [])
    if as_json:
        return
    click.echo("executed in sim2d:")
    for g in goals:
        click.echo(f"  {g['name']}: {g['status']} after {g['finished']:.1f} s"
                   + (f" ({g['reason']})" if g.get("reason") else ""))
    visited = metrics.get("plan", {}).get("places_visited", [])
    click.echo(f"  places passed: {' > '.join(visited)}")
    click.echo(f"  collisions: {metrics.get('world', {}).get('collisions', '?')}")
    amcl = metrics.get("amcl", {})
    if "error_max_m" in amcl:
        click.echo(f"  pose on the map (Monte Carlo localisation): at most "
                   f"{amcl['error_max_m']:.2f} m from the truth, {amcl['error_final_m']:.2f} m "
                   f"at the end (odometry alone: {amcl['odometry_error_max_m']:.2f} m, "
                   f"{amcl['odometry_error_final_m']:.2f} m)"
                   + ("; on a mapping run's map these include the map's own drift"
                      if run_map else ""))
    click.echo(f"wrote {out}/ (plan.png: the plan and the path driven; run.json)")


def _interactive(qm: QueryMap, now: dt.datetime | None, as_json: bool) -> None:
    click.echo(f"semmap ask: {qm.source} ({len(qm.places)} places; known: "
               f"{qm.known_places()}). Type a command or a question; an empty line or "
               "Ctrl-D quits.")
    while True:
        try:
            line = input("> ")
        except EOFError:
            click.echo()
            return
        if not line.strip() or line.strip().lower() in ("quit", "exit", "bye"):
            return
        try:
            _answer(line, qm, now, as_json, None)
        except SemmapError as exc:
            click.echo(f"error: {exc}", err=True)


@click.command(name="ask")
@click.argument("command", required=False)
@click.option("--map", "map_source", required=True, metavar="RUN_DIR|WORLD",
              help="The output folder of a semantic mapping run, or a world (name or YAML) "
                   "to plan on its surveyed floor plan.")
@click.option("--json", "as_json", is_flag=True,
              help="Print {command, objectives, steps, answer, path_length_m} as JSON.")
@click.option("--out", "out_dir", type=click.Path(file_okay=False),
              help="Also write plan.json and plan.png (the plan drawn on the map) here.")
@click.option("--now", "now_text", metavar="WHEN",
              help='The moment asked at, for times and days the command leaves out: '
                   '"2026-11-23T10:30" or "monday 10:30" (default: the clock).')
@click.option("--execute", is_flag=True,
              help="Also drive the plan in sim2d (graphs/ask.yaml) and write the run, with "
                   "plan.png showing the path driven, to --out (default: runs/ask).")
@click.option("--interactive", "-i", is_flag=True, help="Ask one command after another.")
@click.pass_context
def ask(ctx: click.Context, command: str | None, map_source: str, as_json: bool,
        out_dir: str | None, now_text: str | None, execute: bool, interactive: bool) -> None:
    """Plan COMMAND ("fetch the manager's mail", "where is the shredder?") on a map.

    Prints the objectives (with the knowledge base's reasons), the steps with
    each leg's length, and the answer to a question. A command the map cannot
    ground exits with status 3 and says what is missing and what is known.

        semmap ask "fetch the manager's mail" --map office
        semmap ask "where is Dr Ada Lovelace at 10:30 on monday?" --map runs/demo
    """
    if command is None and not interactive:
        raise SemmapError("no command given", field="COMMAND",
                          hint='Give one, e.g. semmap ask "go to the kitchen" --map office, '
                               "or use --interactive.")
    now = parse_now(now_text) if now_text else None
    qm = load_map(map_source)
    if command is not None:
        _answer(command, qm, now, as_json, Path(out_dir) if out_dir and not execute else None)
        if execute:
            _execute(ctx, command, map_source, qm, now, Path(out_dir or "runs/ask"), as_json)
    if interactive:
        _interactive(qm, now, as_json)
