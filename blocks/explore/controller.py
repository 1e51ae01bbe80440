"""The two-layer fuzzy perimeter follower as plain functions, for one robot or a batch.

Layer 1 predicts collisions: the front controller maps the Fr, FrLt and FrRt
group distances to FrontCP (64 rules), the side controller maps Rt and RtFr to
RightCP (16 rules). Layer 2 maps FrontCP, RightCP and dRt = Rt1 - Rt2 to the
translation and rotation velocity (48 rules), as fractions of 70 % of the top
speed and 40 % of the top turn rate. The knowledge bases are the YAML files in
``blocks/explore/kb``; the rules' reasoning is in each file's ``doc``.
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..fuzzy import CompiledController, KnowledgeBase, compile_kb, load_kb
from ..fuzzy.kb import merge_kbs

KB_DIR = Path(__file__).parent / "kb"
GROUP_INPUTS = ("Fr", "FrLt", "FrRt", "Rt", "RtFr", "dRt")


@dataclass(frozen=True)
class KnowledgeBases:
    front: KnowledgeBase
    side: KnowledgeBase
    follow: KnowledgeBase

    @classmethod
    def load(cls, front: str | Path | None = None, side: str | Path | None = None,
             follow: str | Path | None = None) -> "KnowledgeBases":
        """The packaged knowledge bases, or the user's files where given."""
        return cls(load_kb(front or KB_DIR / "front.yaml"), load_kb(side or KB_DIR / "side.yaml"),
                   load_kb(follow or KB_DIR / "follow.yaml"))


def sonar_group_index(spec) -> dict[str, list[int]]:
    """Sonar indices of each group in a robot file, plus ``Rt1`` and ``Rt2`` for dRt."""
    index = {name: [spec.sonar_index(s) for s in members]
             for name, members in spec.sonar_groups.items()}
    for name in ("Rt1", "Rt2"):
        index[name] = [spec.sonar_index(name)]
    return index


def sonar_groups(ranges: np.ndarray, index: dict[str, list[int]]) -> dict[str, np.ndarray]:
    """Group distances (the minimum of each group's sonars) and dRt = Rt1 - Rt2.

    ``ranges`` is (16,) or (B, 16); ``index`` maps group names, plus ``Rt1`` and
    ``Rt2``, to sonar indices.
    """
    ranges = np.atleast_2d(ranges)
    groups = {name: ranges[:, idx].min(axis=1) for name, idx in index.items()
              if name not in ("Rt1", "Rt2")}
    groups["dRt"] = ranges[:, index["Rt1"][0]] - ranges[:, index["Rt2"][0]]
    return groups


def sonar_groups_one(ranges: np.ndarray, index: dict[str, list[int]]) -> dict[str, float]:
    """:func:`sonar_groups` of one scan as Python floats: the same numbers, a tenth of the cost.

    One robot's (16,) ranges make a dozen tiny numpy reductions cost more than
    the minimums themselves. A scan with a NaN goes through :func:`sonar_groups`
    (``min`` of Python floats does not propagate NaN as ``np.min`` does).
    """
    values = np.asarray(ranges, dtype=np.float64).ravel().tolist()
    if any(v != v for v in values):
        return {name: float(v[0]) for name, v in sonar_groups(np.asarray(ranges), index).items()}
    groups = {name: min([values[i] for i in idx]) for name, idx in index.items()
              if name not in ("Rt1", "Rt2")}
    groups["dRt"] = values[index["Rt1"][0]] - values[index["Rt2"][0]]
    return groups


class PerimeterController:
    """Group distances in, velocity commands (m/s, rad/s) out; one call for many robots."""

    def __init__(self, kbs: KnowledgeBases, max_speed: float, max_turn_rate: float,
                 v_fraction: float = 0.7, w_fraction: float = 0.4) -> None:
        # The two layer-1 controllers share one call: same rules, half the overhead.
        self.layer1: CompiledController = compile_kb(merge_kbs(kbs.front, kbs.side))
        self.layer2: CompiledController = compile_kb(kbs.follow)
        self.v_scale = v_fraction * max_speed
        self.w_scale = w_fraction * max_turn_rate
        self._l1_order = np.array([GROUP_INPUTS.index(n) for n in self.layer1.input_names])
        # layer 2's input columns, taken from [layer-1 outputs | groups] in one indexing
        cp_names = self.layer1.output_names
        self._l2_take = np.array([cp_names.index(n) if n in cp_names
                                  else len(cp_names) + GROUP_INPUTS.index(n)
                                  for n in self.layer2.input_names])
        self._scale = np.array([self.v_scale if n == "v" else self.w_scale
                                for n in self.layer2.output_names])
        self._vw = [self.layer2.output_names.index("v"), self.layer2.output_names.index("w")]

    def decide(self, groups: np.ndarray) -> np.ndarray:
        """Velocities (B, 2) = [v, w] for group rows (B, 6) ordered as ``GROUP_INPUTS``."""
        groups = np.atleast_2d(groups)
        cp = self.layer1.evaluate(groups[:, self._l1_order])
        layer2_in = np.concatenate((cp, groups), axis=1)[:, self._l2_take]
        out = self.layer2.evaluate(layer2_in) * self._scale
        return out[:, self._vw]


def narrow_corridor_groups(groups: dict[str, np.ndarray], target: float = 0.45,
                           diagonal_share: float = 0.55) -> dict[str, np.ndarray]:
    """The paper's fix for narrow corridors: take the left sonars into account.

    A right-wall follower cannot keep ``target`` (m, from the side sonars) to
    the right wall in a passage narrower than twice that: the left wall comes
    within the front-left sonars' reach, the front controller predicts a
    collision and the robot turns away at the mouth. Here the left clearance
    is the nearer of the left group ``Lt`` and the front-left diagonal ``FrLt``
    times ``diagonal_share`` (its sideways share at 25-40 degrees, so a
    passage is recognised at its mouth, before ``Lt`` is level with it). Where
    ``Rt + left < 2 * target`` the right-side and diagonal distances are
    scaled so that the middle of the passage reads as the target: the
    follower centres itself and drives in instead of turning away.

    Parameters
    ----------
    groups
        Group distances from :func:`sonar_groups`, including ``Lt``.
    target
        Side distance the side controller aims for (m, from the sonars).
    diagonal_share
        How much of the ``FrLt`` reading counts as left clearance.

    Returns
    -------
    dict
        The groups, with ``Rt``, ``RtFr``, ``FrRt`` and ``FrLt`` rescaled in
        narrow passages and unchanged elsewhere.
    """
    left = np.minimum(groups["Lt"], groups["FrLt"] * diagonal_share)
    half_width = (groups["Rt"] + left) / 2
    scale = np.where(half_width < target, target / np.maximum(half_width, 1e-6), 1.0)
    out = dict(groups)
    for name in ("Rt", "RtFr", "FrRt", "FrLt"):
        out[name] = groups[name] * scale
    return out
