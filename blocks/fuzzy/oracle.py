"""The same knowledge base as a scikit-fuzzy ControlSystem: the reference implementation.

Used to check the compiled evaluator (tests) and to measure the speed-up
(benchmarks); too slow (tens of ms per call) for a control loop.
"""
from __future__ import annotations

from functools import reduce
from operator import and_
from typing import Any

from .kb import KnowledgeBase


def build_skfuzzy(kb: KnowledgeBase) -> Any:
    """A ``skfuzzy.control.ControlSystem`` equivalent to ``kb``."""
    import skfuzzy as fuzz
    from skfuzzy import control as ctrl

    antecedents = {}
    for name, var in kb.inputs.items():
        ant = ctrl.Antecedent(var.universe, name)
        for term in var.terms.values():
            ant[term.name] = fuzz.trapmf(var.universe, [term.a, term.b, term.c, term.d])
        antecedents[name] = ant
    consequents = {}
    for name, var in kb.outputs.items():
        con = ctrl.Consequent(var.universe, name, defuzzify_method="centroid")
        for term in var.terms.values():
            con[term.name] = fuzz.trapmf(var.universe, [term.a, term.b, term.c, term.d])
        consequents[name] = con
    rules = []
    for rule in kb.rules:
        condition = reduce(and_, [antecedents[v][t] for v, t in rule.antecedents])
        rules.append(ctrl.Rule(condition, [consequents[v][t] for v, t in rule.consequents]))
    return ctrl.ControlSystem(rules)


def skfuzzy_evaluate(system: Any, inputs: dict[str, float]) -> dict[str, float]:
    """One skfuzzy evaluation (a fresh simulation without cache, so memory stays flat)."""
    from skfuzzy import control as ctrl

    sim = ctrl.ControlSystemSimulation(system, cache=False)
    for name, value in inputs.items():
        sim.input[name] = value
    sim.compute()
    return {name: float(value) for name, value in sim.output.items()}
