"""The lockstep runner: one static schedule, run tick by tick.

Every tick calls the scheduled tasks in topological order. Nodes with a
period run when ``t % period == offset``; triggered nodes run only on ticks
when their trigger source was written with a true value. Outputs of a node
that does not run hold their last value (sample and hold).
"""
from __future__ import annotations

import platform
import sys
import time
import traceback
import zlib
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .block import Block, RunContext
from .codegen import FILENAME, NodeCall, SlotPlan, compile_tick, gate_expr, generate
from .errors import GraphError, SchemaViolation, SemmapError
from .model import Endpoint, FlatGraph
from .probes import Probe, save_probes
from .schema import Port, value_mismatch
from .validate import Task, check_graph, schedule


class BlockFailure(Exception):
    """A block raised an unexpected exception while running (a bug, not user error)."""

    def __init__(self, node: str, type_name: str, tick: int, exc: BaseException) -> None:
        super().__init__(f"node '{node}' ({type_name}) failed at tick {tick}: "
                         f"{type(exc).__name__}: {exc}")
        self.node = node
        self.tick = tick
        self.original = exc
        self.traceback = "".join(traceback.format_exception(exc))


def block_seed(seed: int, node_path: str) -> np.random.Generator:
    """A node's own RNG: independent of the other nodes and of the node order."""
    return np.random.default_rng(np.random.SeedSequence(
        entropy=seed, spawn_key=(zlib.crc32(node_path.encode()),)))


class Runner:
    """Builds blocks from a flat graph and runs them in lockstep.

    Parameters
    ----------
    graph
        A loaded graph (see ``load_graph``); it is validated here.
    seed
        The run seed; each block gets its own RNG derived from it.
    out_dir
        Folder for block outputs, probes and run.json (None: nothing written).
    records
        ``node.port`` names to probe.
    strict
        Check every value against its port schema (slower; for tests and debugging).
    profile
        Time every block call.
    """

    def __init__(self, graph: FlatGraph, *, seed: int = 0, out_dir: str | Path | None = None,
                 records: list[str] | tuple[str, ...] = (), strict: bool = False,
                 profile: bool = True) -> None:
        self.graph = graph
        self.seed = int(seed)
        self.out_dir = Path(out_dir) if out_dir is not None else None
        self.schemas = check_graph(graph)
        self.tasks: list[Task] = schedule(graph)
        self.ctx = RunContext(dt=graph.dt, seed=self.seed, out_dir=self.out_dir)
        self.strict = strict
        self.profile = profile
        self.tick = 0
        self.status = "ready"
        self.wall_time = 0.0
        self.nodes = list(graph.nodes.values())
        self.index = {n.path: i for i, n in enumerate(self.nodes)}
        self.blocks: list[Block] = [self._instantiate(n) for n in self.nodes]
        self.probes: dict[str, Probe] = {}
        self._build(records)
        self.reset()

    # ---- construction --------------------------------------------------------------
    def _instantiate(self, node: Any) -> Block:
        try:
            return node.cls(dict(node.params), name=node.path, ctx=self.ctx,
                            rng=block_seed(self.seed, node.path))
        except SemmapError as exc:
            exc.node = exc.node or node.path
            if exc.file is None:  # about the node itself: point at it in the graph
                exc.file, exc.line = node.origin.file, exc.line or node.origin.line
            raise  # about another file (a world, a knowledge base): its own place
        except Exception as exc:
            raise BlockFailure(node.path, node.type_name, -1, exc) from exc

    def _resolve_record(self, text: str) -> Endpoint:
        if "." not in text:
            raise GraphError(f"--record {text!r}: expected NODE.PORT",
                             hint="For example --record ctl.u or --record sub.inner.y.")
        node, port = text.rsplit(".", 1)
        if node not in self.graph.nodes:
            exposed = self._exposed_output(node, port)
            if exposed is not None:
                return exposed
            from .loader import _did_you_mean
            raise GraphError(f"--record {text!r}: no node '{node}'",
                             hint=_did_you_mean(node, self.graph.nodes) or
                             "Run 'semmap check GRAPH --schedule' to list the nodes.")
        if Endpoint(node, port) not in self.schemas:
            from .loader import _did_you_mean
            outputs = list(self.graph.nodes[node].outputs)
            raise GraphError(f"--record {text!r}: node '{node}' has no output '{port}'",
                             hint=_did_you_mean(port, outputs) or
                             f"Its outputs are: {', '.join(outputs) or 'none'}.")
        return Endpoint(node, port)

    def _exposed_output(self, group: str, port: str) -> Endpoint | None:
        """A subgraph instance's exposed output, found through the edge it feeds."""
        return self.graph.exposed_outputs.get(f"{group}.{port}")

    def _build(self, records: list[str] | tuple[str, ...]) -> None:
        plan = SlotPlan()
        initial: list[Any] = []
        for node in self.nodes:
            for port in node.outputs:
                plan.output_slot[(node.path, port)] = len(initial)
                initial.append(None)
        incoming = {e.dst: e.src for e in self.graph.edges}
        trigger_slots: dict[str, list[list[int]]] = {}
        for node in self.nodes:
            groups = [[plan.output_slot[(s.node, s.port)] for s in g] for g in node.triggers]
            trigger_slots[node.path] = groups
            plan.stamped.update(s for g in groups for s in g)
        namespace: dict[str, Any] = {}
        for text in records:
            ep = self._resolve_record(text)
            slot = plan.output_slot[(ep.node, ep.port)]
            if slot in plan.probes:
                continue
            probe = Probe(text)
            self.probes[text] = probe
            var = f"rec{len(plan.probes)}"
            plan.probes[slot] = var
            plan.stamped.add(slot)
            namespace[var] = probe.append
        calls = []
        for task in self.tasks:
            i = self.index[task.node]
            node, blk = self.nodes[i], self.blocks[i]
            args: list[int] = []
            if task.phase != "output":
                for name in node.cls._input_order:
                    src = incoming.get(Endpoint(node.path, name))
                    if src is not None:
                        args.append(plan.output_slot[(src.node, src.port)])
                    else:  # unconnected optional input: a constant slot
                        args.append(len(initial))
                        initial.append(node.inputs[name].default)
            outputs = [] if task.phase == "update" else [
                (p, plan.output_slot[(node.path, p)]) for p in node.outputs]
            func = f"{task.phase[0]}{i}"
            namespace[func] = getattr(blk, task.phase)
            calls.append(NodeCall(
                index=i, path=node.path, type_name=node.type_name, phase=task.phase,
                func=func, args=args, outputs=outputs,
                gate=gate_expr(node.period, node.offset, trigger_slots[node.path]),
                origin=str(node.origin), strict=self.strict))
        self._initial = initial
        self._plan = plan
        self.values: list[Any] = list(initial)
        self.stamps = [-1] * len(initial)
        self.times = [0] * len(self.nodes)
        self.calls = [0] * len(self.nodes)
        namespace.update(v=self.values, st=self.stamps, tm=self.times, nc=self.calls,
                         pc=time.perf_counter_ns, chk=self._check_value,
                         chk_keys=self._check_keys)
        self.tick_source, self._line_node = generate(calls, plan, self.profile)
        self._tick = compile_tick(self.tick_source, namespace)

    # ---- strict mode ----------------------------------------------------------------
    def _check_value(self, index: int, port: str, value: Any) -> None:
        node = self.nodes[index]
        schema: Port = self.schemas[Endpoint(node.path, port)]
        why = value_mismatch(schema, value)
        if why:
            raise SchemaViolation(f"output '{port}' broke its schema {schema.describe()}: {why}",
                             node=node.path, file=node.origin.file, line=node.origin.line,
                             hint="This is a bug in the block (strict mode found it).")

    def _check_keys(self, index: int, out: Any) -> None:
        node = self.nodes[index]
        if not isinstance(out, dict):
            raise SchemaViolation(f"step returned {type(out).__name__}, not a dict of outputs",
                             node=node.path, hint="This is a bug in the block.")
        unknown = set(out) - set(node.outputs)
        if unknown:
            raise SchemaViolation(f"step returned undeclared output(s) {sorted(unknown)}",
                             node=node.path, hint="This is a bug in the block.")

    # ---- running ---------------------------------------------------------------------
    def reset(self) -> None:
        """Back to tick 0: initial values, every block reset."""
        self.values[:] = self._initial
        self.stamps[:] = [-1] * len(self._initial)
        self.times[:] = [0] * len(self.nodes)
        self.calls[:] = [0] * len(self.nodes)
        for probe in self.probes.values():
            probe.ticks.clear()
            probe.values.clear()
        self.tick = 0
        self.ctx.tick = 0
        self.ctx.stop_reason = None
        self.ctx.metrics.clear()
        self.ctx.shared.clear()
        self.wall_time = 0.0
        for node, blk in zip(self.nodes, self.blocks):
            self._guard(node.path, blk.reset)

    def _guard(self, path: str, fn: Callable[[], Any]) -> Any:
        try:
            return fn()
        except SemmapError as exc:
            exc.node = exc.node or path
            raise
        except Exception as exc:
            node = self.graph.nodes[path]
            raise BlockFailure(path, node.type_name, self.tick, exc) from exc

    def step(self, n: int = 1) -> None:
        """Run ``n`` ticks (for step-by-step debugging and tests)."""
        self.run(n)

    def run(self, steps: int | None = None,
            on_tick: Callable[[int], None] | None = None) -> str:
        """Run ``steps`` ticks, or until a block requests a stop.

        Returns the status: ``done`` (steps reached), ``stopped`` (a block
        asked), or ``interrupted`` (Ctrl-C). Exceptions from blocks become
        BlockFailure (bugs) or SemmapError (user errors), naming the node.
        """
        tick_fn = self._tick
        ctx = self.ctx
        t = self.tick
        end = None if steps is None else t + steps
        self.status = "running"
        start = time.perf_counter()
        try:
            while end is None or t < end:
                ctx.tick = t
                tick_fn(t)
                t += 1
                if ctx.stop_reason is not None:
                    self.status = "stopped"
                    break
                if on_tick is not None:
                    on_tick(t)
            else:
                self.status = "done"
        except KeyboardInterrupt:
            self.status = "interrupted"
        except BaseException as exc:
            self.status = "failed"
            node = self._node_of(exc)
            if isinstance(exc, SemmapError):
                if node and not exc.node:
                    exc.node = node
                exc.message = f"at tick {t}: {exc.message}"
                raise
            raise BlockFailure(node or "?", self.graph.nodes[node].type_name if node else "?",
                               t, exc) from exc
        finally:
            self.tick = t
            self.wall_time += time.perf_counter() - start
        return self.status

    def _node_of(self, exc: BaseException) -> str | None:
        tb = exc.__traceback__
        found = None
        while tb is not None:
            if tb.tb_frame.f_code.co_filename == FILENAME:
                found = self._line_node.get(tb.tb_lineno)
            tb = tb.tb_next
        return found

    def value(self, name: str) -> Any:
        """The current value on an output port, ``node.port``."""
        ep = self._resolve_record(name)
        return self.values[self._plan.output_slot[(ep.node, ep.port)]]

    def finish(self) -> list[str]:
        """Let every block write its outputs; then write probes. Returns errors."""
        errors = []
        for node, blk in zip(self.nodes, self.blocks):
            try:
                blk.finish()
            except Exception as exc:  # one block's failure must not lose the others' files
                errors.append(f"node '{node.path}' failed to finish: {type(exc).__name__}: {exc}")
        if self.out_dir is not None and self.probes:
            self.ctx.outputs.extend(save_probes(list(self.probes.values()), self.out_dir))
        return errors

    # ---- reporting ---------------------------------------------------------------------
    def profile_table(self) -> list[dict[str, Any]]:
        """Per-block timing, slowest first."""
        rows = []
        for i, node in enumerate(self.nodes):
            gated = node.period > 1 or bool(node.triggers)
            calls = self.calls[i] if gated else self.tick
            total = self.times[i] / 1e9
            rows.append({"node": node.path, "type": node.type_name, "calls": calls,
                         "total_s": round(total, 6),
                         "mean_us": round(total / calls * 1e6, 3) if calls else 0.0})
        return sorted(rows, key=lambda r: -r["total_s"])

    def summary(self, extra: dict[str, Any] | None = None) -> dict[str, Any]:
        """Everything run.json records."""
        sim_time = self.tick * self.graph.dt
        return {
            "status": self.status,
            "stop_reason": self.ctx.stop_reason,
            "graph": self.graph.to_dict(),
            "seed": self.seed,
            "ticks": self.tick,
            "dt": self.graph.dt,
            "sim_time_s": sim_time,
            "wall_time_s": round(self.wall_time, 6),
            "x_real_time": round(sim_time / self.wall_time, 3) if self.wall_time > 0 else None,
            "profile": self.profile_table() if self.profile else [],
            "metrics": self.ctx.metrics,
            "records": list(self.probes),
            "outputs": sorted(set(self.ctx.outputs)),
            "versions": {"python": platform.python_version(), "numpy": np.__version__,
                         "semmap": _version()},
            "command": sys.argv,
            **(extra or {}),
        }


def _version() -> str:
    try:
        from importlib.metadata import version
        return version("semmap")
    except Exception:
        return "unknown"
