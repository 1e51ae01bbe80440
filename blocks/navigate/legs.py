"""A leg of a way and a turn on the spot: what every go-somewhere behaviour drives.

Why a module: room visits and plate views both follow A* ways with pure
pursuit, give a leg up when it takes too long or stops getting anywhere, and
turn on the spot to a heading; one copy of those rules keeps them alike.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .collision_monitor import EchoMemory, HeldClock
from .pursuit import PurePursuit, wrap

__all__ = ["Leg", "TurnWatch", "dedupe", "turn_rate"]

#: How far (rad) a turn on the spot must have turned to count as a leg's progress.
TURN_HEADWAY = 0.05


@dataclass
class Leg:
    """A way being followed by pure pursuit, with the clock that abandons it."""

    follower: PurePursuit
    started: float
    best: float = 0.0
    progress_time: float = math.nan
    last: tuple[float, float] = (0.0, 0.0)  # the command of the last step
    held: HeldClock = field(default_factory=HeldClock)  # by a collision monitor
    backed: float = 0.0  # m backed in a row by creeping round what the monitor would stop
    last_time: float = math.nan
    heading: float = math.nan  # the heading at the last progress: a turn counts once it turns
    creep_sign: float = 0.0  # the direction of the last creep (+1 ahead, -1 back)
    reversals: int = 0  # creeps that went the other way from the one before, since progress
    why: str = ""  # what 'no progress' meant, for a person reading the log

    def __post_init__(self) -> None:
        if math.isnan(self.progress_time):
            self.progress_time = self.started

    def step(self, time: float, pose: np.ndarray, *, timeout: float,
             stall_time: float, scale: float = 1.0,
             held_time: float = math.inf,
             echoes: EchoMemory | None = None,
             creep_back: float = 0.4,
             creep_reversals: int = 3) -> tuple[float, float, str]:
        """``(v, w, outcome)``: outcome is '' while under way, else 'arrived',
        'timeout' (longer than ``timeout`` s), 'no progress' (none for ``stall_time`` s)
        or 'held' (a collision monitor let none of the leg's command through, ``scale``
        0, for ``held_time`` s: driving on into what stopped it would only touch it
        again once the monitor backs the robot off).

        With ``echoes`` (the monitor's, and ``pose`` in their odometry frame), a
        command the monitor would stop (a corner the way swings onto, a jamb
        met askew) is replaced by the nearest slow motion it lets through
        (:meth:`~blocks.navigate.collision_monitor.EchoMemory.nearest_clear`):
        the robot creeps round it and the way is kept; creeping that gets
        nowhere ends as 'no progress', and so does creeping backwards for more
        than ``creep_back`` (m) with no going ahead between (turns on the spot
        do not count): the rear has few sonars, and a wall behind met at a
        slant is silent (a room visit's way back through a door 0.8 m wide
        backed 1.2 m into one).  Creeping that goes ahead, back, ahead again
        more than ``creep_reversals`` times with no progress between ends as
        'no progress' too: the robot is jiggling on the spot, and each back
        may touch that silent wall (a room visit pinned by a wall corner jiggled
        40 s against one).  A turn on the spot is progress only while the
        heading moves: a turn the monitor stops, replaced by creeps, is not.
        """
        if self.held.update(time, scale, self.last != (0.0, 0.0)) >= held_time - 1e-9:
            self.last = (0.0, 0.0)
            return 0.0, 0.0, "held"
        v, w, status = self.follower.step(pose, 0.0)
        if status == "arrived":
            return 0.0, 0.0, "arrived"
        turned = status == "turning" and (math.isnan(self.heading) or abs(
            wrap(float(pose[2]) - self.heading)) >= TURN_HEADWAY)
        if self.follower.progress > self.best + 0.05 or turned:
            self.best, self.progress_time = max(self.best, self.follower.progress), time
            self.heading, self.reversals = float(pose[2]), 0
        if time - self.started > timeout:
            return 0.0, 0.0, "timeout"
        if time - self.progress_time > stall_time:
            self.why = f"no progress for {stall_time:g} s"
            return 0.0, 0.0, "no progress"
        backing = False
        if echoes is not None and echoes.stops(pose, v, w):
            v, w = echoes.nearest_clear(pose, v, w) or (v, w)
            backing = v < 0.0
            if v != 0.0:
                sign = math.copysign(1.0, v)
                self.reversals += int(self.creep_sign == -sign)
                self.creep_sign = sign
        if self.reversals > creep_reversals:
            self.last, self.why = (0.0, 0.0), f"crept ahead and back {self.reversals} times"
            return 0.0, 0.0, "no progress"
        dt = 0.0 if math.isnan(self.last_time) else time - self.last_time
        self.last_time = time
        if backing:
            self.backed += abs(v) * dt
        elif v > 0.0:  # going ahead again (a turn on the spot between backs goes nowhere)
            self.backed = 0.0
        if self.backed > creep_back:
            self.last, self.why = (0.0, 0.0), f"crept back {creep_back:g} m blind"
            return 0.0, 0.0, "no progress"
        self.last = (float(v), float(w))
        return float(v), float(w), ""


@dataclass
class TurnWatch:
    """Whether a turn on the spot still gets anywhere.

    Why: a turn is measured, not timed (it ends at a heading, or after a
    whole turn), so a turn that cannot be made (a collision monitor that
    stops it with furniture at a corner, a body wedged) would be asked for
    for ever while the behaviour holds control.  A turn whose heading has
    not moved by ``headway`` (rad) for ``stall_time`` (s) is given up.  Asked
    every tick of a turn; a gap of more than ``gap`` (s) between two asks, or
    another ``what``, starts a new turn.

    Examples
    --------
    >>> watch = TurnWatch(stall_time=5.0)
    >>> [watch.stalled(k / 2, 1.0, "spin") for k in range(12)][-3:]  # every 0.5 s
    [False, False, True]
    >>> watch.stalled(6.0, 1.0, "spin")  # given up: the next ask starts a new turn
    False
    >>> watch.stalled(20.0, 1.0, "spin")  # a later turn, not the stalled one
    False
    """

    stall_time: float = 10.0
    headway: float = 0.05
    gap: float = 1.0
    given_up: int = field(default=0, init=False)
    _mark: tuple[float, float, str] | None = field(default=None, init=False, repr=False)
    _last: float = field(default=-math.inf, init=False, repr=False)  # the last ask

    def stalled(self, time: float, heading: float, what: str) -> bool:
        """True (once, counted) when the turn called ``what`` has stalled."""
        mark, self._last, last = self._mark, time, self._last
        if mark is None or mark[2] != what or time - last > self.gap \
                or abs(wrap(heading - mark[1])) >= self.headway:
            self._mark = (time, heading, what)
            return False
        if time - mark[0] <= self.stall_time:
            return False
        self._mark, self.given_up = None, self.given_up + 1
        return True


def turn_rate(heading: float, theta: float, rate: float, tolerance: float) -> float | None:
    """Turn rate (rad/s) from ``theta`` toward ``heading``, slowing near it, or None once
    within ``tolerance``."""
    error = wrap(heading - theta)
    if abs(error) <= tolerance:
        return None
    return math.copysign(min(rate, max(0.15, 1.5 * abs(error))), error)


def dedupe(path: np.ndarray) -> np.ndarray:
    """The path without consecutive points closer than 1 cm (the follower needs length)."""
    path = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    keep = [0] + [k for k in range(1, len(path))
                  if np.hypot(*(path[k] - path[k - 1])) > 0.01]
    out = path[keep]
    return out if len(out) >= 2 else np.vstack([out, out[-1] + 1e-3])
