"""Weekly timetables: who is where, when.

The paper's semantic task planner reaches "a specific instructor in locations
according to time": the robot knows from door signs where "LAB" is, and a
timetable says that Dr Lovelace teaches there on Monday mornings. A timetable
file lists the people (name, role, optional workplace) and their weekly slots,
naming places by their *sign text*, so the same file works on any map whose
signs the robot has read:

.. code-block:: yaml

    people:
      - {name: "Dr Ada Lovelace", role: Researcher, workplace: "OFFICE 101"}
    slots:
      - {person: "Dr Ada Lovelace", place: "LAB", days: [mon, wed],
         start: "09:00", end: "11:00", subject: "Robotics"}

Roles are ontology role names (``Manager``, ``Teacher``...); the knowledge
base (:mod:`semantic.kb`) checks them against its ontology. Loading checks
everything else and raises :class:`TimetableError` naming the file, line and
field on the first problem.
"""
from __future__ import annotations

import datetime as dt
import re
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from blocks.core.errors import SemmapError
from blocks.core.yamlsrc import line_of, load_versioned_mapping

__all__ = ["DAYS", "Person", "Slot", "Timetable", "TimetableError", "load_timetable",
           "EXAMPLES"]

#: Day names as written in files, Monday first (index = ``datetime.weekday()``).
DAYS = ("mon", "tue", "wed", "thu", "fri", "sat", "sun")
_TIME_RE = re.compile(r"([01]?[0-9]|2[0-3]):([0-5][0-9])")
#: The example timetables shipped with semmap's worlds (their ``timetable:`` key), by world.
EXAMPLES = {name: Path(__file__).resolve().parent.parent / "sim2d" / "worlds" /
            "timetables" / f"{name}.yaml" for name in ("office", "hospital")}
PERSON_KEYS = ("name", "role", "workplace")
SLOT_KEYS = ("person", "place", "days", "start", "end", "subject")


class TimetableError(SemmapError):
    """A timetable file is malformed."""


@dataclass(frozen=True)
class Person:
    """Someone in a timetable. ``workplace`` is a sign text (their own office), if given."""

    name: str
    role: str | None = None
    workplace: str | None = None
    line: int | None = field(default=None, compare=False)


@dataclass(frozen=True)
class Slot:
    """A weekly slot: ``person`` is at ``place`` (a sign text) on ``days`` from ``start`` to ``end``.

    The end is exclusive: a 09:00-11:00 slot holds at 10:59, not at 11:00, so
    back-to-back slots never overlap.
    """

    person: str
    place: str
    days: tuple[str, ...]
    start: dt.time
    end: dt.time
    subject: str | None = None
    line: int | None = field(default=None, compare=False)

    def holds(self, when: dt.datetime) -> bool:
        """Whether the slot covers the moment ``when`` (its weekday and time of day)."""
        return DAYS[when.weekday()] in self.days and self.start <= when.time() < self.end


@dataclass
class Timetable:
    """People and their weekly slots (see the module docstring for the file format)."""

    people: list[Person]
    slots: list[Slot]
    source: str | None = None

    def person(self, name: str) -> Person | None:
        """The person called ``name`` (case and spacing ignored), or None."""
        key = _key(name)
        return next((p for p in self.people if _key(p.name) == key), None)

    def slot_at(self, person: str, when: dt.datetime) -> Slot | None:
        """The first slot of ``person`` holding at ``when``, or None."""
        found = self.person(person)
        if found is None:
            return None
        return next((s for s in self.slots if s.person == found.name and s.holds(when)), None)

    def where(self, person: str, when: dt.datetime) -> str | None:
        """The place name (sign text) where ``person`` is at ``when`` by the timetable, or None.

        None outside every slot of theirs (and for unknown people): the
        timetable does not know, and the caller may fall back on the person's
        workplace (:meth:`semantic.kb.KnowledgeBase.where_is_person_at` does).
        """
        slot = self.slot_at(person, when)
        return slot.place if slot is not None else None


def _key(name: str) -> str:
    return " ".join(str(name).lower().split())


# ---- loading --------------------------------------------------------------------------------
def load_timetable(path: str | Path) -> Timetable:
    """Load a timetable YAML file.

    Raises
    ------
    TimetableError
        When the file is missing or not YAML, or a field is missing, unknown or
        malformed (bad day or time, end not after start, a slot for someone not
        in ``people``); the message names the file, line and field.
    """
    path = Path(path)
    doc = load_versioned_mapping(
        path, TimetableError, what="a timetable", fields=("people", "slots"),
        missing_hint="Give the path of a timetable YAML (see "
                     "sim2d/worlds/timetables/office.yaml for an example).")
    people_raw = doc.get("people", [])
    slots_raw = doc.get("slots", [])
    for key, value in (("people", people_raw), ("slots", slots_raw)):
        if not isinstance(value, list):
            raise TimetableError(f"'{key}' must be a list", file=path, line=line_of(doc, key),
                                 field=key)
    people: list[Person] = []
    for i, raw in enumerate(people_raw):
        person = _person(raw, path, line_of(people_raw, i), i)
        if any(_key(p.name) == _key(person.name) for p in people):
            raise TimetableError(f"person {person.name!r} is listed twice", file=path,
                                 line=person.line, field="name",
                                 hint="Give each person once; add more slots instead.")
        people.append(person)
    by_name = {_key(p.name): p for p in people}
    slots = [_slot(raw, path, line_of(slots_raw, i), i, by_name)
             for i, raw in enumerate(slots_raw)]
    return Timetable(people=people, slots=slots, source=str(path))


def _check_keys(raw: Any, keys: tuple[str, ...], what: str, path: Path, line: int | None) -> None:
    if not isinstance(raw, Mapping):
        raise TimetableError(f"{what} must be a mapping with fields {', '.join(keys)}, "
                             f"got {raw!r}", file=path, line=line)
    for key in raw:
        if key not in keys:
            import difflib
            close = difflib.get_close_matches(str(key), keys, n=1)
            raise TimetableError(f"unknown field {key!r} in {what}", file=path,
                                 line=line_of(raw, key), field=str(key),
                                 hint=f"Did you mean {close[0]!r}?" if close else
                                 f"Known fields: {', '.join(keys)}.")


def _text(raw: Mapping, key: str, what: str, path: Path, required: bool) -> str | None:
    value = raw.get(key)
    if value is None and not required:
        return None
    if not isinstance(value, str) or not value.strip():
        raise TimetableError(f"'{key}' of {what} must be a non-empty text, got {value!r}",
                             file=path, line=line_of(raw, key) if key in raw else line_of(raw),
                             field=key, hint="Quote texts YAML would read otherwise "
                                             "(numbers, times, YES/NO).")
    return " ".join(value.split())


def _person(raw: Any, path: Path, line: int | None, index: int) -> Person:
    what = f"person {index + 1}"
    _check_keys(raw, PERSON_KEYS, what, path, line)
    name = _text(raw, "name", what, path, required=True)
    role = _text(raw, "role", f"person {name!r}", path, required=False)
    if role is not None and not re.fullmatch(r"[A-Z][A-Za-z0-9]*", role):
        raise TimetableError(f"'role' of person {name!r} must be an ontology role name in "
                             f"UpperCamelCase (e.g. Teacher, Manager), got {role!r}", file=path,
                             line=line_of(raw, "role"), field="role")
    workplace = _text(raw, "workplace", f"person {name!r}", path, required=False)
    return Person(name=str(name), role=role, workplace=workplace, line=line_of(raw) or line)


def _time(raw: Mapping, key: str, what: str, path: Path) -> dt.time:
    value = raw.get(key)
    if isinstance(value, int) and key in raw:  # YAML 1.1 reads an unquoted 09:00 as 540
        value = f"{value // 60:02d}:{value % 60:02d}"
    m = _TIME_RE.fullmatch(str(value).strip()) if isinstance(value, str) else None
    if m is None:
        raise TimetableError(f"'{key}' of {what} must be a time \"HH:MM\" (24 h), got {value!r}",
                             file=path, line=line_of(raw, key) if key in raw else line_of(raw),
                             field=key, hint='Write it quoted, e.g. start: "09:00".')
    return dt.time(int(m.group(1)), int(m.group(2)))


def _slot(raw: Any, path: Path, line: int | None, index: int,
          people: dict[str, Person]) -> Slot:
    what = f"slot {index + 1}"
    _check_keys(raw, SLOT_KEYS, what, path, line)
    name = _text(raw, "person", what, path, required=True)
    person = people.get(_key(str(name)))
    if person is None:
        raise TimetableError(f"{what} is for {name!r}, who is not in 'people'", file=path,
                             line=line_of(raw, "person"), field="person",
                             hint="Add them to 'people' (name and role) or fix the spelling.")
    place = _text(raw, "place", what, path, required=True)
    days = raw.get("days")
    if isinstance(days, str):
        days = [days]
    if (not isinstance(days, list) or not days
            or not all(isinstance(d, str) and d.strip().lower()[:3] in DAYS for d in days)):
        raise TimetableError(f"'days' of {what} must be a list of days ({', '.join(DAYS)}), "
                             f"got {days!r}", file=path,
                             line=line_of(raw, "days") if "days" in raw else line_of(raw),
                             field="days")
    start = _time(raw, "start", what, path)
    end = _time(raw, "end", what, path)
    if end <= start:
        raise TimetableError(f"{what} ends ({end:%H:%M}) before it starts ({start:%H:%M})",
                             file=path, line=line_of(raw, "end"), field="end",
                             hint="Slots run within one day; split one that crosses midnight.")
    subject = _text(raw, "subject", what, path, required=False)
    return Slot(person=person.name, place=str(place),
                days=tuple(dict.fromkeys(d.strip().lower()[:3] for d in days)), start=start,
                end=end, subject=subject, line=line_of(raw) or line)
