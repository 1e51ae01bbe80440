"""Fuzzy knowledge bases as data: variables, trapezoidal terms and AND rules in YAML.

Format::

    name: front_collision
    doc: Why the rules are what they are.
    inputs:
      Fr:
        universe: [0.0, 4.0, 0.02]     # start, stop, step (stop included)
        unit: m
        terms:
          VERYCLOSE: [0.0, 0.0, 0.35, 0.6]   # trapezoid a, b, c, d (a triangle: b == c)
          ...
    outputs:
      FrontCP: {universe: [0.0, 1.0, 0.01], terms: {...}}
    rules:
      - Fr is VERYCLOSE and FrLt is FAR -> FrontCP is DANGER
      - ...

Rules are Mamdani: AND is the minimum, implication clips, several rules for
one output term accumulate by the maximum, and outputs are defuzzified by
centroid, as scikit-fuzzy does. Term breakpoints must lie on the universe grid,
so the sampled membership functions are exactly the trapezoids.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.errors import SemmapError
from ..core.yamlsrc import line_of, load_yaml_file


class KnowledgeBaseError(SemmapError):
    """A knowledge base file is malformed."""


@dataclass(frozen=True)
class Term:
    """A linguistic term with a trapezoidal membership function (a <= b <= c <= d)."""

    name: str
    a: float
    b: float
    c: float
    d: float

    def membership(self, x: np.ndarray) -> np.ndarray:
        """Membership of each value in ``x`` (exact trapezoid; shoulders are flat)."""
        x = np.asarray(x, dtype=np.float64)
        with np.errstate(divide="ignore", invalid="ignore"):
            rise = np.where(self.b > self.a, (x - self.a) / (self.b - self.a),
                            np.where(x >= self.a, 1.0, 0.0))
            fall = np.where(self.d > self.c, (self.d - x) / (self.d - self.c),
                            np.where(x <= self.d, 1.0, 0.0))
        return np.clip(np.minimum(rise, fall), 0.0, 1.0)


@dataclass
class Variable:
    """An input or output variable: a sampled universe and its terms."""

    name: str
    universe: np.ndarray
    terms: dict[str, Term]
    unit: str = ""

    @property
    def low(self) -> float:
        return float(self.universe[0])

    @property
    def high(self) -> float:
        return float(self.universe[-1])


@dataclass(frozen=True)
class Rule:
    """IF every (input is term) THEN every (output is term)."""

    antecedents: tuple[tuple[str, str], ...]
    consequents: tuple[tuple[str, str], ...]
    text: str = ""


@dataclass
class KnowledgeBase:
    name: str
    inputs: dict[str, Variable]
    outputs: dict[str, Variable]
    rules: list[Rule]
    doc: str = ""
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)


RULE_RE = re.compile(r"^\s*(?:if\s+)?(?P<lhs>.+?)\s*(?:->|\bthen\b)\s*(?P<rhs>.+?)\s*$",
                     re.IGNORECASE)
CLAUSE_RE = re.compile(r"^\s*(?P<var>[A-Za-z_][A-Za-z0-9_]*)\s+is\s+(?P<term>[A-Za-z_][A-Za-z0-9_]*)"
                       r"\s*$", re.IGNORECASE)


def _universe(spec: Any, path: Path, line: int | None, where: str) -> np.ndarray:
    ok = isinstance(spec, list) and len(spec) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in spec)
    if not ok or not spec[1] > spec[0] or not spec[2] > 0:
        raise KnowledgeBaseError(f"{where}: universe must be [start, stop, step] with "
                                 f"stop > start and step > 0, got {spec!r}",
                                 file=path, line=line, field=f"{where}.universe")
    count = round((spec[1] - spec[0]) / spec[2])
    if abs(spec[0] + count * spec[2] - spec[1]) > 1e-9 * max(1.0, abs(spec[1])) or count > 100_000:
        raise KnowledgeBaseError(f"{where}: the step {spec[2]} does not divide the universe "
                                 f"[{spec[0]}, {spec[1]}] into a whole number of steps",
                                 file=path, line=line, field=f"{where}.universe")
    return np.linspace(spec[0], spec[1], count + 1)


def _variable(name: str, spec: Any, path: Path, line: int | None, kind: str) -> Variable:
    where = f"{kind}.{name}"
    if not isinstance(spec, dict) or "universe" not in spec or "terms" not in spec:
        raise KnowledgeBaseError(f"{where} needs 'universe' and 'terms'", file=path, line=line,
                                 field=where)
    universe = _universe(spec["universe"], path, line_of(spec, "universe"), where)
    raw_terms = spec["terms"]
    if not isinstance(raw_terms, dict) or not raw_terms:
        raise KnowledgeBaseError(f"{where}.terms must map term names to [a, b, c, d]",
                                 file=path, line=line_of(spec, "terms"), field=f"{where}.terms")
    terms = {}
    step = universe[1] - universe[0]
    for term_name, points in raw_terms.items():
        tline = line_of(raw_terms, term_name)
        if isinstance(term_name, bool):
            raise KnowledgeBaseError(
                f"term name {term_name!r} in {where}: YAML read an unquoted yes/no/on/off as "
                "a boolean", file=path, line=tline, field=f"{where}.terms",
                hint="Quote the name, e.g. 'NO': [0.0, 0.0, 0.1, 0.3].")
        if isinstance(points, list) and len(points) == 3:
            points = [points[0], points[1], points[1], points[2]]  # triangle
        ok = isinstance(points, list) and len(points) == 4 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) for v in points)
        if not ok or not points[0] <= points[1] <= points[2] <= points[3]:
            raise KnowledgeBaseError(
                f"term {where}.{term_name} must be [a, b, c, d] with a <= b <= c <= d "
                f"(or a triangle [a, b, c]), got {points!r}", file=path, line=tline,
                field=f"{where}.terms.{term_name}")
        for p in points:
            k = (p - universe[0]) / step
            if abs(k - round(k)) > 1e-6 or not universe[0] - 1e-9 <= p <= universe[-1] + 1e-9:
                raise KnowledgeBaseError(
                    f"term {where}.{term_name}: breakpoint {p} is not on the universe grid "
                    f"(start {universe[0]}, step {step:g})", file=path, line=tline,
                    field=f"{where}.terms.{term_name}",
                    hint="Move it onto the grid or use a finer step.")
        terms[str(term_name)] = Term(str(term_name), *map(float, points))
    return Variable(name=name, universe=universe, terms=terms, unit=str(spec.get("unit", "")))


def _clauses(text: str, variables: dict[str, Variable], path: Path, line: int | None,
             side: str) -> tuple[tuple[str, str], ...]:
    clauses = []
    for part in re.split(r"\s+and\s+", text, flags=re.IGNORECASE):
        match = CLAUSE_RE.match(part)
        if not match:
            raise KnowledgeBaseError(f"cannot read '{part.strip()}' in a rule; write "
                                     f"'VARIABLE is TERM'", file=path, line=line, field="rules")
        var, term = match.group("var"), match.group("term")
        if var not in variables:
            raise KnowledgeBaseError(f"rule uses unknown {side} variable '{var}'", file=path,
                                     line=line, field="rules",
                                     hint=f"The {side}s are: {', '.join(variables)}.")
        if term not in variables[var].terms:
            raise KnowledgeBaseError(f"'{var}' has no term '{term}'", file=path, line=line,
                                     field="rules",
                                     hint=f"Its terms are: {', '.join(variables[var].terms)}.")
        clauses.append((var, term))
    return tuple(clauses)


def load_kb(path: str | Path) -> KnowledgeBase:
    """Read and check a knowledge base file."""
    path = Path(path)
    doc = load_yaml_file(path)
    if not isinstance(doc, dict):
        raise KnowledgeBaseError("a knowledge base must be a YAML mapping", file=path)
    for key in ("inputs", "outputs", "rules"):
        if not isinstance(doc.get(key), (dict if key != "rules" else list)) or not doc.get(key):
            raise KnowledgeBaseError(f"the knowledge base needs a non-empty '{key}'", file=path,
                                     line=line_of(doc, key), field=key)
    unknown = set(doc) - {"name", "doc", "inputs", "outputs", "rules", "defuzzify"}
    if unknown:
        raise KnowledgeBaseError(f"unknown field(s) {sorted(map(str, unknown))}", file=path,
                                 field=str(sorted(map(str, unknown))[0]))
    if doc.get("defuzzify", "centroid") != "centroid":
        raise KnowledgeBaseError("only 'defuzzify: centroid' is supported", file=path,
                                 line=line_of(doc, "defuzzify"), field="defuzzify")
    inputs = {str(n): _variable(str(n), s, path, line_of(doc["inputs"], n), "inputs")
              for n, s in doc["inputs"].items()}
    outputs = {str(n): _variable(str(n), s, path, line_of(doc["outputs"], n), "outputs")
               for n, s in doc["outputs"].items()}
    rules = []
    for i, text in enumerate(doc["rules"]):
        line = line_of(doc["rules"], i)
        match = RULE_RE.match(text) if isinstance(text, str) else None
        if not match:
            raise KnowledgeBaseError(f"rule {i + 1} is not 'A is X and B is Y -> C is Z'",
                                     file=path, line=line, field="rules")
        rules.append(Rule(_clauses(match.group("lhs"), inputs, path, line, "input"),
                          _clauses(match.group("rhs"), outputs, path, line, "output"),
                          text.strip()))
    return KnowledgeBase(name=str(doc.get("name") or path.stem), inputs=inputs, outputs=outputs,
                         rules=rules, doc=str(doc.get("doc") or ""), source=str(path))


def merge_kbs(*kbs: KnowledgeBase, name: str = "") -> KnowledgeBase:
    """One knowledge base holding several independent ones (disjoint variable names).

    Evaluating the merge gives each part's outputs unchanged, in one call.
    """
    inputs: dict[str, Variable] = {}
    outputs: dict[str, Variable] = {}
    rules: list[Rule] = []
    for kb in kbs:
        clash = (set(kb.inputs) & set(inputs)) | (set(kb.outputs) & set(outputs))
        if clash:
            raise ValueError(f"cannot merge {kb.name}: variables {sorted(clash)} appear twice")
        inputs.update(kb.inputs)
        outputs.update(kb.outputs)
        rules.extend(kb.rules)
    return KnowledgeBase(name=name or "+".join(kb.name for kb in kbs), inputs=inputs,
                         outputs=outputs, rules=rules)
