"""A compiled Mamdani evaluator: the same answers as scikit-fuzzy, vectorised over a batch.

scikit-fuzzy's ``ControlSystemSimulation.compute()`` walks Python objects and
takes ~95 ms for a 64-rule controller. Here everything is arrays, prepared
once: the input terms' trapezoids, each rule's antecedent term indices, and
the output terms. One call evaluates a batch of B input vectors with a few
dozen numpy operations. For one robot, where every numpy call is mostly
overhead, ``evaluate_one`` gives the same numbers bit for bit with half the
work (see its docstring).

To match scikit-fuzzy's centroid exactly, the output is sampled where
scikit-fuzzy samples it: on the universe grid plus, for each output term, the
two points where its trapezoid crosses the term's activation level (0.5 does
the same upsampling), and the centroid of that piecewise-linear function is
computed exactly (trapezoid rule for area and moment).
"""
from __future__ import annotations

import math

import numpy as np

from .kb import KnowledgeBase

_EPS = np.finfo(float).eps
_EPS_PY = float(_EPS)


def trapezoids(x: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray,
               d: np.ndarray) -> np.ndarray:
    """Membership of ``x`` (broadcast) in trapezoids (a, b, c, d); flat shoulders allowed."""
    rise_slope, rise_shift, fall_slope, fall_shift = _slopes(a, b, c, d)
    return _trapezoids(x, a, d, rise_slope, rise_shift, fall_slope, fall_shift)


def _slopes(a, b, c, d):
    """Edge slopes; a vertical edge (a == b or c == d) becomes a step via a huge slope + 1."""
    a, b, c, d = (np.asarray(v, dtype=np.float64) for v in (a, b, c, d))
    rise_flat, fall_flat = b <= a, d <= c
    rise_slope = np.where(rise_flat, 1e12, 1.0 / np.where(rise_flat, 1.0, b - a))
    fall_slope = np.where(fall_flat, 1e12, 1.0 / np.where(fall_flat, 1.0, d - c))
    return rise_slope, rise_flat.astype(float), fall_slope, fall_flat.astype(float)


def _trapezoids(x, a, d, rise_slope, rise_shift, fall_slope, fall_shift):
    # Plain ufuncs: np.clip and friends cost microseconds of Python wrapping per call,
    # which is most of the time for a single robot.
    rise = np.subtract(x, a)
    rise *= rise_slope
    rise += rise_shift
    fall = np.subtract(d, x)
    fall *= fall_slope
    fall += fall_shift
    np.minimum(rise, fall, out=rise)
    np.minimum(rise, 1.0, out=rise)
    return np.maximum(rise, 0.0, out=rise)


class CompiledController:
    """Evaluate a knowledge base fast; call with keyword inputs or ``evaluate`` a batch.

    All output variables are evaluated in one pass: their grids are padded to a
    common length by repeating the last point (zero-width segments add nothing)
    and their term lists by terms that never fire.
    """

    memo_size = 256  # activation patterns whose outputs evaluate_one keeps (first come)

    def __init__(self, kb: KnowledgeBase) -> None:
        self.name = kb.name
        self.input_names = list(kb.inputs)
        self.output_names = list(kb.outputs)
        self.low = np.array([v.low for v in kb.inputs.values()])
        self.high = np.array([v.high for v in kb.inputs.values()])
        term_input, bounds, offsets = [], [], {}
        for i, (name, var) in enumerate(kb.inputs.items()):
            for term_name, term in var.terms.items():
                offsets[(name, term_name)] = len(term_input)
                term_input.append(i)
                bounds.append((term.a, term.b, term.c, term.d))
        self._term_input = np.array(term_input)
        a, b, c, d = (np.array(col) for col in zip(*bounds))
        self._in_a, self._in_d = a, d
        self._in_slopes = _slopes(a, b, c, d)
        ones = len(term_input)  # index of a constant-1 column: "this input does not matter"
        self._antecedents = np.full((len(kb.rules), len(kb.inputs)), ones)
        for r, rule in enumerate(kb.rules):
            for var, term in rule.antecedents:
                self._antecedents[r, self.input_names.index(var)] = offsets[(var, term)]
        self._prepare_outputs(kb)
        self._prepare_single()

    def _prepare_outputs(self, kb: KnowledgeBase) -> None:
        variables = list(kb.outputs.values())
        n_terms = max(len(v.terms) for v in variables)
        n_grid = max(len(v.universe) for v in variables)
        zero = len(kb.rules)  # index of a constant-0 strength column: no rule fired
        grid = np.empty((len(variables), n_grid))
        shape = np.empty((4, len(variables), n_terms))
        columns, starts = [], []
        for o, var in enumerate(variables):
            grid[o, :len(var.universe)] = var.universe
            grid[o, len(var.universe):] = var.universe[-1]
            terms = list(var.terms.values())
            for t in range(n_terms):
                starts.append(len(columns))
                if t < len(terms):
                    term = terms[t]
                    shape[:, o, t] = (term.a, term.b, term.c, term.d)
                    columns += [r for r, rule in enumerate(kb.rules)
                                if (var.name, term.name) in rule.consequents]
                else:  # padding: a spike at the grid's start that never fires
                    shape[:, o, t] = var.universe[0]
                columns.append(zero)
        self._grid = grid
        self._columns, self._starts = np.array(columns), np.array(starts)
        self._n_terms = n_terms
        self._oa, self._ob, self._oc, self._od = shape
        self._rise, self._fall = self._ob - self._oa, self._od - self._oc
        rs, rsh, fs, fsh = _slopes(*shape)
        # Broadcast to (B, O, T, M) for the membership of the sample points.
        self._out_slopes = tuple(v[None, :, :, None] for v in (self._oa, self._od, rs, rsh, fs, fsh))

    def _prepare_single(self) -> None:
        """Tables for :meth:`evaluate_one`: the same numbers as Python floats and flat indices."""
        rs, rsh, fs, fsh = self._in_slopes
        self._terms_py = [(int(i), float(a), float(d), float(r), float(rh), float(f), float(fh))
                          for i, a, d, r, rh, f, fh in zip(self._term_input, self._in_a,
                                                             self._in_d, rs, rsh, fs, fsh)]
        self._low_py, self._high_py = self.low.tolist(), self.high.tolist()
        n_mu = len(self._term_input)
        # mu gets a 1 (input not used) and a 0 at its end; rule R is the 0 rule that the
        # padding terms point at, so the strengths need no extra column
        zero_rule = np.full((1, self._antecedents.shape[1]), n_mu + 1)
        self._antecedents_one = np.vstack([self._antecedents, zero_rule])
        # each output term twice: once for its rising crossing point, once for the falling one
        outputs, terms = len(self._grid), self._n_terms
        groups = [self._columns[self._starts[k]:(self._starts[k + 1] if k + 1 < len(self._starts)
                                                 else len(self._columns))]
                  for k in range(outputs * terms)]
        twice = [groups[o * terms + t] for o in range(outputs) for _ in range(2)
                 for t in range(terms)]
        self._columns_twice = np.concatenate(twice)
        self._starts_twice = np.cumsum([0] + [len(g) for g in twice[:-1]])
        self._cross_slope = np.concatenate([self._rise, -self._fall], axis=1)
        self._cross_base = np.concatenate([self._oa, self._od], axis=1)
        # the output terms' trapezoids shaped (O, T, 1) against (O, 1, M) sample points
        self._member_shape = tuple(v[0] for v in self._out_slopes)
        # outputs by term activations: the crisp outputs are a function of the activations
        # alone, and a controller spends much of its time with one term fully active
        # (a third to a half of the office run's calls repeat one of a few dozen)
        self._by_activation: dict[bytes, tuple[float, ...]] = {}

    def evaluate_one(self, values) -> list[float]:
        """Crisp outputs for one input vector (a sequence of floats in ``input_names`` order).

        The same numbers as ``evaluate(np.array([values]))[0]``, bit for bit, in a
        third fewer numpy calls: one robot's controller is all call overhead. The
        input memberships are the same float operations done on Python floats,
        the padding column of the rule strengths is a rule of its own, both
        crossing points of every output term come from one multiply-add, and the
        centroid's last division is done on Python floats. The outputs of the
        first ``memo_size`` activation patterns are kept and looked up: they
        depend on nothing else. Inputs that are NaN go through :meth:`evaluate`
        (Python's min and max do not propagate NaN).
        """
        if len(values) != len(self._low_py):
            raise ValueError(f"{self.name} takes {len(self._low_py)} inputs "
                             f"{self.input_names}, got {len(values)}")
        xs = [max(min(float(v), hi), lo) for v, lo, hi in zip(values, self._low_py,
                                                                self._high_py)]
        if any(x != x for x in xs):
            return self.evaluate(np.array([values], dtype=np.float64))[0].tolist()
        mu = []
        for i, a, d, rise_slope, rise_shift, fall_slope, fall_shift in self._terms_py:
            x = xs[i]
            rise = (x - a) * rise_slope + rise_shift
            fall = (d - x) * fall_slope + fall_shift
            m = fall if fall < rise else rise
            m = 1.0 if m > 1.0 else m
            mu.append(0.0 if m < 0.0 else m)
        mu.append(1.0)
        mu.append(0.0)
        strengths = np.minimum.reduce(np.array(mu)[self._antecedents_one], axis=1)
        twice = np.maximum.reduceat(strengths[self._columns_twice], self._starts_twice)
        key = twice.tobytes()
        known = self._by_activation.get(key)
        if known is not None:
            return list(known)
        outputs, terms = self._grid.shape[0], self._n_terms
        twice = twice.reshape(outputs, 2 * terms)
        grid = self._grid.shape[1]
        points = np.empty((outputs, grid + 2 * terms))
        points[:, :grid] = self._grid
        cross = points[:, grid:]
        np.multiply(twice, self._cross_slope, out=cross)
        cross += self._cross_base
        points.sort(axis=1)
        member = _trapezoids(points[:, None, :], *self._member_shape)
        np.minimum(member, twice[:, :terms, None], out=member)
        y = np.maximum.reduce(member, axis=1)
        out = _centroid_lists(points, y)
        if len(self._by_activation) < self.memo_size:
            self._by_activation[key] = tuple(out)
        return out

    def rule_strengths(self, inputs: np.ndarray) -> np.ndarray:
        """Firing strength of every rule, (B, R + 1) with a final 0 column, for (B, n_inputs)."""
        x = np.maximum(np.minimum(inputs, self.high), self.low)
        mu = np.empty((len(x), len(self._term_input) + 1))
        mu[:, -1] = 1.0
        mu[:, :-1] = _trapezoids(x[:, self._term_input], self._in_a, self._in_d, *self._in_slopes)
        strengths = np.empty((len(x), len(self._antecedents) + 1))
        strengths[:, -1] = 0.0
        np.min(mu[:, self._antecedents], axis=2, out=strengths[:, :-1])
        return strengths

    def evaluate(self, inputs: np.ndarray) -> np.ndarray:
        """Crisp outputs (B, n_outputs) for a batch of inputs (B, n_inputs), in declared order.

        Inputs outside a universe are clipped to it, as scikit-fuzzy does. A row
        on which no rule fires has no defined output and gives nan.
        """
        if not (isinstance(inputs, np.ndarray) and inputs.ndim == 2
                and inputs.dtype == np.float64):
            inputs = np.atleast_2d(np.asarray(inputs, dtype=np.float64))
        strengths = self.rule_strengths(inputs)
        batch, outputs, terms = len(inputs), len(self._grid), self._n_terms
        activation = np.maximum.reduceat(strengths[:, self._columns], self._starts, axis=1)
        activation = activation.reshape(batch, outputs, terms)
        grid = self._grid.shape[1]
        points = np.empty((batch, outputs, grid + 2 * terms))
        points[:, :, :grid] = self._grid
        # where each term crosses its activation level (scikit-fuzzy samples there too)
        np.multiply(activation, self._rise, out=points[:, :, grid:grid + terms])
        points[:, :, grid:grid + terms] += self._oa
        np.multiply(activation, -self._fall, out=points[:, :, grid + terms:])
        points[:, :, grid + terms:] += self._od
        points.sort(axis=2)
        member = _trapezoids(points[:, :, None, :], *self._out_slopes)
        np.minimum(member, activation[..., None], out=member)
        return _centroid(points, member.max(axis=2))

    def __call__(self, **inputs: float) -> dict[str, float]:
        """One evaluation with named inputs: ``front(Fr=1.2, FrLt=3.0, FrRt=0.8)``."""
        missing = set(self.input_names) - set(inputs)
        if missing:
            raise KeyError(f"missing inputs {sorted(missing)} for {self.name}")
        out = self.evaluate_one([float(inputs[n]) for n in self.input_names])
        return dict(zip(self.output_names, out))


def _centroid(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Exact centroid of piecewise-linear functions sampled at (x, y) along the last axis.

    Rows with zero area (no rule fired) give nan.
    """
    dx = np.diff(x, axis=-1)
    y1, y2 = y[..., :-1], y[..., 1:]
    ysum = y1 + y2
    area = dx * ysum  # twice the area; the factor cancels
    moment = (y2 + ysum) * (1 / 3)
    moment *= dx
    moment += x[..., :-1] * ysum
    moment *= dx
    total = area.sum(axis=-1)
    centroid = moment.sum(axis=-1) / np.fmax(total, _EPS)
    return np.where(total > 0, centroid, np.nan)


def _centroid_lists(x: np.ndarray, y: np.ndarray) -> list[float]:
    """:func:`_centroid` of (O, M) rows as a list of floats, the same numbers bit for bit.

    The same array operations up to the two sums; the division, the guard
    against zero area and the nan are done on the O Python floats.
    """
    dx = np.subtract(x[:, 1:], x[:, :-1])
    y1, y2 = y[:, :-1], y[:, 1:]
    ysum = y1 + y2
    area = dx * ysum
    moment = (y2 + ysum) * (1 / 3)
    moment *= dx
    moment += x[:, :-1] * ysum
    moment *= dx
    totals = np.add.reduce(area, axis=1).tolist()
    moments = np.add.reduce(moment, axis=1).tolist()
    return [m / (t if t > _EPS_PY else _EPS_PY) if t > 0 else math.nan
            for m, t in zip(moments, totals)]


def compile_kb(kb: KnowledgeBase) -> CompiledController:
    """Prepare a knowledge base for fast evaluation."""
    return CompiledController(kb)
