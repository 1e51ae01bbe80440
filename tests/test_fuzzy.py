"""The compiled fuzzy evaluator against scikit-fuzzy (the oracle), and the controller's intent."""
from __future__ import annotations

import itertools
import textwrap

import numpy as np
import pytest
from skfuzzy import control as ctrl

from blocks.explore.controller import (GROUP_INPUTS, KB_DIR, KnowledgeBases,
                                       PerimeterController)
from blocks.fuzzy import compile_kb, load_kb
from blocks.fuzzy.kb import KnowledgeBaseError, merge_kbs
from blocks.fuzzy.oracle import build_skfuzzy, skfuzzy_evaluate

KBS = ["front", "side", "follow"]


def oracle_inputs(kb, count: int, seed: int) -> np.ndarray:
    """Random inputs plus the edges: bounds, every breakpoint, and values beyond the range."""
    rng = np.random.default_rng(seed)
    columns = []
    for var in kb.inputs.values():
        edges = {var.low, var.high, var.low - 1.0, var.high + 1.0}
        for term in var.terms.values():
            edges |= {term.a, term.b, term.c, term.d}
        edges = np.array(sorted(edges))
        column = rng.uniform(var.low, var.high, count)
        pick = rng.random(count) < 0.2  # a fifth of the values sit exactly on an edge
        column[pick] = rng.choice(edges, pick.sum())
        columns.append(column)
    return np.column_stack(columns)


@pytest.mark.parametrize("name", KBS)
def test_compiled_matches_skfuzzy_on_10000_inputs(name):
    kb = load_kb(KB_DIR / f"{name}.yaml")
    compiled = compile_kb(kb)
    inputs = oracle_inputs(kb, 10_000, seed=KBS.index(name))
    sim = ctrl.ControlSystemSimulation(build_skfuzzy(kb), cache=False)
    for i, var in enumerate(compiled.input_names):
        sim.input[var] = inputs[:, i]
    sim.compute()
    ours = compiled.evaluate(inputs)
    for k, out in enumerate(compiled.output_names):
        var = kb.outputs[out]
        error = np.abs(ours[:, k] - sim.output[out]).max()
        assert error <= 1e-3 * (var.high - var.low), (out, error)
        assert error < 1e-9  # in fact the same numbers, to rounding


def test_single_scalar_skfuzzy_call_agrees_too():
    kb = load_kb(KB_DIR / "follow.yaml")
    compiled = compile_kb(kb)
    reference = skfuzzy_evaluate(build_skfuzzy(kb), {"FrontCP": 0.2, "RightCP": 0.65, "dRt": 0.1})
    ours = compiled(FrontCP=0.2, RightCP=0.65, dRt=0.1)
    assert ours == pytest.approx(reference, abs=1e-9)


@pytest.mark.parametrize("name", KBS)
def test_batch_equals_row_by_row(name):
    compiled = compile_kb(load_kb(KB_DIR / f"{name}.yaml"))
    inputs = oracle_inputs(load_kb(KB_DIR / f"{name}.yaml"), 50, seed=9)
    batch = compiled.evaluate(inputs)
    rows = np.vstack([compiled.evaluate(row[None]) for row in inputs])
    assert np.array_equal(batch, rows)


def _bits(values) -> bytes:
    return np.asarray(values, dtype=np.float64).tobytes()


@pytest.mark.parametrize("name", KBS + ["front+side"])
def test_one_row_evaluation_is_the_batch_evaluation_bit_for_bit(name):
    kb = (merge_kbs(load_kb(KB_DIR / "front.yaml"), load_kb(KB_DIR / "side.yaml"))
          if name == "front+side" else load_kb(KB_DIR / f"{name}.yaml"))
    compiled, fresh = compile_kb(kb), compile_kb(kb)
    fresh.memo_size = 0  # every row computed, none looked up
    inputs = oracle_inputs(kb, 3000, seed=21)
    batch = compiled.evaluate(inputs)
    for row, want in zip(inputs, batch):
        assert _bits(compiled.evaluate_one(row.tolist())) == _bits(want), row
        assert _bits(fresh.evaluate_one(row)) == _bits(want), row
    assert 0 < len(compiled._by_activation) <= compiled.memo_size and not fresh._by_activation
    for row, want in zip(inputs[:300], batch[:300]):  # again, now from the kept activations
        assert _bits(compiled.evaluate_one(row)) == _bits(want), row


def test_one_row_evaluation_takes_nan_inputs_as_the_batch_does():
    compiled = compile_kb(load_kb(KB_DIR / "follow.yaml"))
    for row in ([np.nan, 0.5, 0.0], [0.2, np.nan, 0.1], [0.2, 0.3, np.nan]):
        want = compiled.evaluate(np.array([row]))[0]
        assert _bits(compiled.evaluate_one(row)) == _bits(want)
    with pytest.raises(ValueError, match="takes 3 inputs"):
        compiled.evaluate_one([0.2, 0.3])


def test_rule_tables_are_complete():
    counts = {name: len(load_kb(KB_DIR / f"{name}.yaml").rules) for name in KBS}
    assert counts == {"front": 64, "side": 16, "follow": 48}
    for name in KBS:  # every combination of input terms has exactly one rule
        kb = load_kb(KB_DIR / f"{name}.yaml")
        combos = {tuple(t for _, t in rule.antecedents) for rule in kb.rules}
        assert combos == set(itertools.product(*[v.terms for v in kb.inputs.values()]))


def test_controller_follows_its_stated_intent():
    pc = PerimeterController(KnowledgeBases.load(), max_speed=1.0, max_turn_rate=1.5)

    def decide(**groups):
        row = np.array([[groups.get(n, 4.0) for n in GROUP_INPUTS]])
        row[0, GROUP_INPUTS.index("dRt")] = groups.get("dRt", 0.0)
        return pc.decide(row)[0]

    v, w = decide(Rt=0.45, RtFr=0.6, FrRt=0.9)  # parallel, at the target distance
    assert v > 0.5 and abs(w) < 0.05
    v, w = decide(Fr=0.3, Rt=0.45, RtFr=0.6)  # wall right ahead: stop and turn left
    assert v < 0.1 and w > 0.4
    v, w = decide(Rt=4.0, RtFr=4.0, dRt=1.0)  # the wall ended on the right: wrap around it
    assert 0.0 < v < 0.35 and w < -0.4
    v, w = decide(Rt=0.45, RtFr=0.6, dRt=0.3)  # heading away from the wall: turn right
    assert w < -0.1
    v, w = decide(Rt=0.45, RtFr=0.6, dRt=-0.3)  # heading into the wall: turn left
    assert w > 0.1
    v, w = decide(Rt=0.1, RtFr=0.3)  # far too close to the wall: move away
    assert w > 0.1
    limits = pc.decide(np.random.default_rng(0).uniform(0, 4, (500, 6)))
    assert limits[:, 0].max() <= 0.7 + 1e-9 and np.abs(limits[:, 1]).max() <= 0.4 * 1.5 + 1e-9


def write_kb(tmp_path, text):
    path = tmp_path / "kb.yaml"
    path.write_text(textwrap.dedent(text))
    return path


GOOD = """
    name: tiny
    inputs:
      x:
        universe: [0.0, 1.0, 0.1]
        terms: {LOW: [0.0, 0.0, 0.2, 0.6], HIGH: [0.2, 0.6, 1.0, 1.0]}
    outputs:
      y:
        universe: [0.0, 1.0, 0.1]
        terms: {SMALL: [0.0, 0.0, 0.3], BIG: [0.7, 1.0, 1.0]}
    rules:
      - x is LOW -> y is SMALL
      - x is HIGH -> y is BIG
"""


@pytest.mark.parametrize("old,new,message", [
    ("[0.0, 0.0, 0.2, 0.6]", "[0.0, 0.0, 0.25, 0.6]", "not on the universe grid"),
    ("[0.0, 0.0, 0.2, 0.6]", "[0.5, 0.0, 0.2, 0.6]", "a <= b <= c <= d"),
    ("x is HIGH -> y is BIG", "x is MEDIUM -> y is BIG", "'x' has no term 'MEDIUM'"),
    ("x is HIGH -> y is BIG", "z is HIGH -> y is BIG", "unknown input variable 'z'"),
    ("x is HIGH -> y is BIG", "x is HIGH", "is not 'A is X and B is Y -> C is Z'"),
    ("LOW: [", "no: [", "quote the name"),
    ("universe: [0.0, 1.0, 0.1]\n    terms: {SMALL", "universe: [0.0, 1.0, 0.3]\n    terms: {SMALL",
     "whole number of steps"),
])
def test_knowledge_base_errors(tmp_path, old, new, message):
    text = textwrap.dedent(GOOD)
    assert old in text or old in GOOD
    path = write_kb(tmp_path, GOOD.replace(old, new, 1) if old in GOOD else
                    text.replace(old, new, 1))
    with pytest.raises(KnowledgeBaseError) as info:
        load_kb(path)
    assert message.lower() in str(info.value).lower() and str(path) in str(info.value)


def test_tiny_kb_and_merge(tmp_path):
    kb = load_kb(write_kb(tmp_path, GOOD))
    compiled = compile_kb(kb)
    low, high = compiled.evaluate(np.array([[0.0], [1.0]]))[:, 0]
    assert low < 0.2 and high > 0.8
    with pytest.raises(ValueError, match="appear twice"):
        merge_kbs(kb, kb)
