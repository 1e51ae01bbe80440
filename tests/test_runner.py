"""Run-time semantics: feedback, delays, multi-rate hold, triggers, stop, failures."""
from __future__ import annotations

import json

import numpy as np
import pytest

from blocks import Block, Param, Port, Runner, block, load_graph
from blocks.core import BlockFailure, SemmapError


@block("test.source_list")
class SourceList(Block):
    """Emits the given values one per run, then holds the last."""

    outputs = {"y": Port.scalar(None)}
    params = {"values": Param(list, [0])}

    def reset(self):
        self._i = 0

    def step(self):
        value = self.p.values[min(self._i, len(self.p.values) - 1)]
        self._i += 1
        return {"y": value}


@block("test.collect")
class Collect(Block):
    """Keeps every input (for assertions)."""

    inputs = {"x": Port()}
    seen: list

    def reset(self):
        self.seen = []

    def step(self, x):
        self.seen.append(x)


@block("test.flag_every")
class FlagEvery(Block):
    """An event that is true every n-th run."""

    outputs = {"fired": Port.event()}
    params = {"n": Param(int, 2, min=1)}

    def reset(self):
        self._k = 0

    def step(self):
        self._k += 1
        return {"fired": self._k % self.p.n == 0}


@block("test.boom")
class Boom(Block):
    """Raises at a chosen tick."""

    inputs = {"x": Port(required=False)}
    outputs = {"y": Port.scalar()}
    params = {"at": Param(int, 3), "what": Param(str, "error", choices=("error", "interrupt"))}

    def step(self, x=None):
        if self.ctx.tick == self.p.at:
            if self.p.what == "interrupt":
                raise KeyboardInterrupt
            raise ZeroDivisionError("bad maths")
        return {"y": 1.0}


@block("test.liar")
class Liar(Block):
    """Declares a float array but outputs a string (strict mode must catch it)."""

    outputs = {"y": Port.array("float64", (3,))}

    def step(self):
        return {"y": "not an array"}


@block("test.accumulator")
class Accumulator(Block):
    """Running sum without direct feedthrough: output is the sum of past inputs."""

    direct_feedthrough = False
    inputs = {"x": Port.scalar(None)}
    outputs = {"total": Port.scalar(None)}

    def reset(self):
        self._total = 0

    def output(self):
        return {"total": self._total}

    def update(self, x):
        self._total += x


def collected(runner: Runner, node: str) -> list:
    return runner.blocks[runner.index[node]].seen


def test_feedback_edge_delays_by_n(write):
    path = write("g.yaml", """
        nodes:
          - {id: one, type: constant, params: {value: 1}}
          - {id: add, type: arith}
          - {id: out, type: test.collect}
        edges:
          - one.value -> add.a
          - {from: add.y, to: add.b, delay: 2, initial: 10}
          - add.y -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(6)
    # y[t] = 1 + y[t-2], with y[-1] = y[-2] = 10
    assert collected(runner, "out") == [11, 11, 12, 12, 13, 13]


def test_delay_block_breaks_a_cycle(write):
    path = write("g.yaml", """
        nodes:
          - {id: one, type: constant, params: {value: 2}}
          - {id: add, type: arith}
          - {id: z, type: delay, params: {n: 1, initial: 0}}
          - {id: out, type: test.collect}
        edges:
          - one.value -> add.a
          - add.y -> z.x
          - z.y -> add.b
          - add.y -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(4)
    assert collected(runner, "out") == [2, 4, 6, 8]


def test_user_block_without_feedthrough_in_a_cycle(write):
    path = write("g.yaml", """
        nodes:
          - {id: acc, type: test.accumulator}
          - {id: inc, type: scale, params: {gain: 1.0, offset: 1.0}}
          - {id: out, type: test.collect}
        edges:
          - acc.total -> inc.x
          - inc.y -> acc.x
          - acc.total -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(4)
    assert collected(runner, "out") == [0, 1.0, 3.0, 7.0]


def test_multirate_holds_outputs_between_runs(write):
    path = write("g.yaml", """
        nodes:
          - {id: slow, type: counter, period: 3, offset: 1}
          - {id: out, type: test.collect}
        edges:
          - slow.count -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(8)
    # Runs at ticks 1, 4, 7; None before the first run; held in between.
    assert collected(runner, "out") == [None, 0, 0, 0, 1, 1, 1, 2]
    assert runner.profile_table()[[r["node"] for r in runner.profile_table()].index("slow")][
        "calls"] == 3


def test_trigger_runs_node_only_on_fresh_true(write):
    path = write("g.yaml", """
        nodes:
          - {id: flag, type: test.flag_every, params: {n: 2}, period: 2}
          - {id: count, type: counter}
          - {id: out, type: test.collect, trigger: flag.fired}
        edges:
          - count.count -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(12)
    # flag runs at ticks 0,2,4,...; it is true on its 2nd, 4th, ... run: ticks 2, 6, 10.
    # Its held True value on ticks 3, 7, 11 must not fire again.
    assert collected(runner, "out") == [2, 6, 10]


def test_trigger_any_of_list(write):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: test.flag_every, params: {n: 3}}
          - {id: b, type: test.flag_every, params: {n: 5}}
          - {id: count, type: counter}
          - {id: out, type: test.collect, trigger: [a.fired, b.fired]}
        edges:
          - count.count -> out.x
    """)
    runner = Runner(load_graph(path))
    runner.run(10)
    assert collected(runner, "out") == [2, 4, 5, 8, 9]


def test_subgraph_period_and_trigger_apply_inside(write):
    write("sub.yaml", """
        inputs: {x: s.x}
        outputs: {y: s.y}
        nodes:
          - {id: s, type: scale, params: {gain: 10.0}, period: 2}
    """)
    path = write("g.yaml", """
        nodes:
          - {id: count, type: counter}
          - {id: f, include: sub.yaml, period: 3}
          - {id: out, type: test.collect}
        edges:
          - count.count -> f.x
          - f.y -> out.x
    """)
    graph = load_graph(path)
    assert (graph.nodes["f.s"].period, graph.nodes["f.s"].offset) == (6, 0)
    runner = Runner(graph)
    runner.run(8)
    assert collected(runner, "out") == [0.0] * 6 + [60.0, 60.0]


def test_stop_request_ends_run(write):
    path = write("g.yaml", """
        nodes:
          - {id: c, type: counter}
          - {id: t, type: threshold, params: {level: 4.5}}
          - {id: s, type: stop_when, params: {reason: enough}}
        edges:
          - c.count -> t.x
          - t.fired -> s.x
    """)
    runner = Runner(load_graph(path))
    assert runner.run() == "stopped"
    assert runner.tick == 6 and runner.ctx.stop_reason == "s: enough"


def test_step_by_step_and_value(write):
    path = write("g.yaml", """
        nodes:
          - {id: c, type: counter, params: {start: 5}}
    """)
    runner = Runner(load_graph(path))
    runner.step()
    assert runner.value("c.count") == 5
    runner.step(3)
    assert runner.value("c.count") == 8 and runner.tick == 4
    runner.reset()
    runner.step()
    assert runner.value("c.count") == 5


def test_block_failure_names_node_and_tick(write):
    path = write("g.yaml", """
        nodes:
          - {id: ok, type: counter}
          - {id: bad, type: test.boom, params: {at: 3}}
    """)
    runner = Runner(load_graph(path))
    with pytest.raises(BlockFailure) as info:
        runner.run(10)
    assert info.value.node == "bad" and info.value.tick == 3
    assert "ZeroDivisionError" in info.value.traceback


def test_cli_block_failure_keeps_outputs(write, cli, tmp_path):
    path = write("g.yaml", """
        nodes:
          - {id: c, type: counter}
          - {id: rec, type: recorder}
          - {id: bad, type: test.boom, params: {at: 5}}
        edges:
          - c.count -> rec.x
    """)
    out = tmp_path / "run"
    result = cli("run", path, "--out", out, "--quiet", "--steps", 20)
    assert result.code == 1
    assert "Traceback" not in result.err
    assert "node 'bad' (test.boom) failed at tick 5" in result.err and "error.log" in result.err
    assert "ZeroDivisionError" in (out / "error.log").read_text()
    summary = json.loads((out / "run.json").read_text())
    assert summary["status"] == "failed" and summary["error"]["node"] == "bad"
    # The recorder runs before "bad" within tick 5, so it holds ticks 0..5.
    assert np.load(out / "rec.npz")["values"].tolist() == [0, 1, 2, 3, 4, 5]


def test_cli_interrupt_writes_run_json_and_outputs(write, cli, tmp_path):
    path = write("g.yaml", """
        nodes:
          - {id: c, type: counter}
          - {id: rec, type: recorder}
          - {id: ctrl_c, type: test.boom, params: {at: 7, what: interrupt}}
        edges:
          - c.count -> rec.x
    """)
    out = tmp_path / "run"
    result = cli("run", path, "--out", out, "--steps", 100, "--record", "c.count")
    assert result.code == 130
    assert "Traceback" not in result.err and "interrupted at tick 7" in result.err
    summary = json.loads((out / "run.json").read_text())
    assert summary["status"] == "interrupted" and summary["ticks"] == 7
    assert np.load(out / "rec.npz")["values"].tolist() == list(range(8))
    assert np.load(out / "probes.npz")["c.count"].tolist() == list(range(8))


def test_strict_mode_catches_a_lying_block(write, cli, tmp_path):
    path = write("g.yaml", """
        nodes:
          - {id: liar, type: test.liar}
    """)
    runner = Runner(load_graph(path), strict=False)
    runner.run(2)  # not checked without strict
    with pytest.raises(SemmapError) as info:
        Runner(load_graph(path), strict=True).run(2)
    assert "expected a numpy array" in str(info.value) and info.value.node == "liar"
    result = cli("run", path, "--strict", "--steps", 2, "--out", tmp_path / "r", "-q")
    assert result.code == 1 and "Traceback" not in result.err


def test_optional_input_gets_default(write):
    path = write("g.yaml", """
        nodes:
          - {id: b, type: test.boom, params: {at: -1}}
    """)
    runner = Runner(load_graph(path))
    runner.run(2)
    assert runner.value("b.y") == 1.0


def test_each_block_gets_its_own_seeded_rng(write):
    path = write("g.yaml", """
        nodes:
          - {id: a, type: noise}
          - {id: b, type: noise}
    """)
    first = Runner(load_graph(path), seed=7)
    first.run(1)
    again = Runner(load_graph(path), seed=7)
    again.run(1)
    other = Runner(load_graph(path), seed=8)
    other.run(1)
    assert first.value("a.value") == again.value("a.value")
    assert first.value("a.value") != first.value("b.value")
    assert first.value("a.value") != other.value("a.value")


def test_rng_stream_independent_of_other_nodes(write):
    one = write("one.yaml", """
        nodes:
          - {id: a, type: noise}
    """)
    two = write("two.yaml", """
        nodes:
          - {id: z, type: noise}
          - {id: a, type: noise}
    """)
    r1, r2 = Runner(load_graph(one), seed=3), Runner(load_graph(two), seed=3)
    r1.run(5)
    r2.run(5)
    assert r1.value("a.value") == r2.value("a.value")


def test_generated_schedule_is_readable(write):
    path = write("g.yaml", """
        nodes:
          - {id: c, type: counter, period: 2}
    """)
    source = Runner(load_graph(path)).tick_source
    assert "# c (counter, step)" in source and "t % 2 == 0" in source


def test_select_and_switch(write):
    path = write("g.yaml", """
        nodes:
          - {id: arr, type: constant, params: {value: [3.0, 1.0, 2.0, 5.0]}}
          - {id: pick, type: select, params: {indices: [0, 2]}}
          - {id: nearest, type: select, params: {indices: [0, 1, 2], reduce: min}}
          - {id: close, type: threshold, params: {level: 1.5, direction: below}}
          - {id: near_value, type: constant, params: {value: 10.0}}
          - {id: far_value, type: constant, params: {value: 20.0}}
          - {id: choose, type: switch}
        edges:
          - arr.value -> pick.x
          - arr.value -> nearest.x
          - nearest.y -> close.x
          - close.on -> choose.when
          - near_value.value -> choose.a
          - far_value.value -> choose.b
    """)
    runner = Runner(load_graph(path), strict=True)
    runner.run(1)
    assert runner.value("pick.y").tolist() == [3.0, 2.0]
    assert runner.value("nearest.y") == 1.0 and isinstance(runner.value("nearest.y"), float)
    assert runner.value("choose.y") == 10.0


def test_select_index_out_of_range_is_a_user_error(write):
    path = write("g.yaml", """
        nodes:
          - {id: arr, type: constant, params: {value: [1.0, 2.0]}}
          - {id: pick, type: select, params: {indices: [5]}}
        edges:
          - arr.value -> pick.x
    """)
    with pytest.raises(SemmapError) as info:
        Runner(load_graph(path)).run(1)
    assert "index out of range" in str(info.value) and info.value.node == "pick"
