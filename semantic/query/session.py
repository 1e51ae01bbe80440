"""One call from a sentence to a plan: parse, ground, plan (what ``semmap ask``, the
planner block and the benchmark all run)."""
from __future__ import annotations

import datetime as dt
import re

from blocks.core.errors import SemmapError

from .ground import ground
from .mapsource import QueryMap
from .parse import parse_command
from .tasks import TaskPlan, plan_task

__all__ = ["ask", "parse_now"]

_DAY = {"mon": 0, "tue": 1, "wed": 2, "thu": 3, "fri": 4, "sat": 5, "sun": 6}


def ask(command: str, qm: QueryMap, *, now: dt.datetime | None = None) -> TaskPlan:
    """The plan for an English command or question on a map.

    Raises
    ------
    semantic.query.ParseError
        The sentence is not understood (names the words).
    semantic.query.GroundingError
        Something it needs is not on this map (says what is known).
    """
    request = parse_command(command, qm.kb.lexicon, people=qm.people)
    return plan_task(ground(request, qm, now=now), qm)


def parse_now(text: str) -> dt.datetime:
    """A moment as an ISO date-time (``2026-11-23T10:30``) or a weekday and time
    (``"monday 10:30"``: that day of the week of 2026-01-05, a Monday).

    Raises
    ------
    SemmapError
        Neither form (names the text and both forms).
    """
    text = text.strip()
    try:
        return dt.datetime.fromisoformat(text)
    except ValueError:
        pass
    m = re.fullmatch(r"([a-z]{3})[a-z]*\s+(\d{1,2}):(\d\d)", text.lower())
    if m and m.group(1) in _DAY and int(m.group(2)) < 24 and int(m.group(3)) < 60:
        return dt.datetime(2026, 1, 5 + _DAY[m.group(1)], int(m.group(2)), int(m.group(3)))
    raise SemmapError(f"{text!r} is not a moment", field="now",
                      hint='Write an ISO date and time ("2026-11-23T10:30") or a weekday and '
                           'a 24-hour time ("monday 10:30").')
