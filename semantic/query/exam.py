"""Commands with their right answers on a floor: an exam the task planner is scored on.

For each world, :func:`generate_commands` writes English commands whose right
answer follows from the world's ground truth alone (:mod:`semantic.query.truth`:
its places, signs, doors, objects and timetable, and the ontology's words and
classes) under the planner's documented semantics (docs/query.md); the planner
is never asked. :func:`write_commands` and :func:`load_commands` keep them in a
small YAML file next to the world (its ``commands:`` key names it), and
:func:`score_commands` asks the planner each command on a map (a semantic
mapping run's, or the world surveyed) and counts the right answers.

The categories (:data:`CATEGORIES`):

- ``go_named``: "go to office 204", a room by the number on its sign;
- ``go_kind``: "take me to the kitchen", a kind of room the floor has once, or
  several of which one is nearest the start by :data:`NEAREST_MARGIN` or more;
- ``fetch``: "take the printer to Alan Turing", an object standing in one
  room, to a person's workplace, a room named by its sign or its kind, or to
  the one asking;
- ``where_object``: "where is the printer?", answered with its room;
- ``where_person``: "where is Alan Turing at 10:30 on tuesday?", the room of
  the timetable's slot then, else the person's workplace;
- ``refuse_kind``: "go to the pharmacy" on a floor without one;
- ``refuse_number``: "go to office 907" on a floor where no sign carries 907.

A command is asked only if it has one right answer: a place is named only if a
sign on the floor carries its name, and by number only if the number is on
its sign (the planner reads "ward 2", not "ward b"); the robot is sent only
into rooms it can surely get into from its start (:mod:`semantic.query.truth`);
an object is asked about only if it stands in one room and belongs in no other;
a kind of room is asked for only if no room of that kind is unsigned, and
refused only if no place is of that kind and no sign names it (corridors and
halls aside: a run's map types unsigned places as those).

A command that expects a plan is right when the plan's objectives are the
expected (action, place) pairs in order and, on a map of a known world, each
place's stop is at that true room (:func:`stops_at`: inside it, or in front of
it, as a plan to a room the robot only read the sign of stops); a question,
when the answer holds every expected word (whole words, case kept); a refusal,
when the planner raises
:class:`~semantic.query.GroundingError` holding every expected word. Anything
else (a parse error, a plan where a refusal was due) is wrong, and the row says
what came instead. Names compare as the sign scorer compares them
(:func:`~semantic.vocabulary.same_name`: case and spacing say nothing), so a
plate ``POSTROOM`` read ``POST ROOM`` is a place planned to rightly.
"""
from __future__ import annotations

import datetime as dt
import json
import math
import re
from collections.abc import Iterable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import cv2
import numpy as np

from blocks.core.atomic import atomic_write_text
from blocks.core.errors import SemmapError
from blocks.core.yamlsrc import line_of, load_versioned_mapping
from semantic.lexicon import normalise
from semantic.timetable import DAYS, Person, Slot
from semantic.vocabulary import same_name

from .ground import GroundingError
from .mapsource import QueryMap
from .parse import TITLES
from .session import ask, parse_now
from .truth import FloorTruth, _containing, floor_truth

if TYPE_CHECKING:
    from sim2d.world import World

__all__ = ["AT_ROOM", "CATEGORIES", "DEFAULT_NOW", "NEAREST_MARGIN", "REFUSAL_SHARE", "CommandCase",
           "CommandsError", "generate_commands", "load_commands", "score_commands", "stops_at",
           "write_commands"]

#: How far (m) outside the right room's outline a plan's stop may be, in a place the
#: room's door leads to, and still be at that room: in the corridor in front of it,
#: where a plan to a room known only by its sign stops (semantic.semantic_map's
#: DOOR_ANCHOR), the map's drift included.
AT_ROOM = 1.5

#: Command categories and what each asks.
CATEGORIES: dict[str, str] = {
    "go_named": "go to a room by the number on its sign",
    "go_kind": "go to a kind of room: the only one, or the nearest by a clear margin",
    "fetch": "take an object standing in one room to a person, a room or the one asking",
    "where_object": "where an object standing in one room is",
    "where_person": "where a person is at a time: their timetable slot, else their workplace",
    "refuse_kind": "refuse a kind of place the floor does not have",
    "refuse_number": "refuse a room number no sign on the floor carries",
}
#: The moment a commands file is asked at, unless given.
DEFAULT_NOW = "monday 10:00"
#: "the nearest office" is asked only if the next one is this much farther (m).
NEAREST_MARGIN = 3.0
#: Each refusal category gives at most this share of the commands (at least one): on a
#: small floor they would otherwise fill the file, and they are the easy ones.
REFUSAL_SHARE = 0.1
#: Actions an expected objective may have (see semantic.query.Objective).
OBJECTIVE_ACTIONS = ("go to", "pick up", "hand over", "look for")
CASE_KEYS = ("command", "category", "objectives", "answer", "refused", "why")
_EXPECTATIONS = ("objectives", "answer", "refused")
_THINGS = frozenset({"object", "equipment"})


class CommandsError(SemmapError):
    """A commands file is malformed."""


@dataclass(frozen=True)
class CommandCase:
    """An English command and its right answer on one floor.

    Exactly one expectation is set.

    Attributes
    ----------
    command
        As a person would type it ("take the printer to Alan Turing").
    category
        A key of :data:`CATEGORIES` (files may add their own).
    objectives
        The plan's objectives, in order: (action, place label) pairs, the place as
        the planner names it (its sign text, or ``"you"``, the one asking).
    answer
        Words the answer to a question must hold.
    refused
        Words the error refusing the command must hold.
    why
        Why this is the right answer, from the ground truth (for readers).
    """

    command: str
    category: str
    objectives: tuple[tuple[str, str], ...] = ()
    answer: tuple[str, ...] = ()
    refused: tuple[str, ...] = ()
    why: str = ""

    def __post_init__(self) -> None:
        given = [k for k in _EXPECTATIONS if getattr(self, k)]
        if len(given) != 1:
            raise ValueError(f"a command case needs exactly one of {', '.join(_EXPECTATIONS)}, "
                             f"got {', '.join(given) or 'none'}")

    @property
    def expects(self) -> str:
        """``"plan"``, ``"answer"`` or ``"refusal"``."""
        return "plan" if self.objectives else "answer" if self.answer else "refusal"

    def expected_text(self) -> str:
        """The expectation in a line: ``"pick up at ADMIN; hand over at you"``."""
        if self.objectives:
            return "; ".join(f"{action} at {place}" for action, place in self.objectives)
        words = ", ".join(self.answer or self.refused)
        return f"answer with {words}" if self.answer else f"refuse with {words}"


# ---- generating ---------------------------------------------------------------------------------
def generate_commands(world: World, *, seed: int, count: int = 20) -> list[CommandCase]:
    """Commands with their right answers on a floor, from its ground truth.

    Parameters
    ----------
    world
        A loaded world with ground truth (``places``, ``doors``, ``signs``,
        ``objects``, a timetable); what it lacks, no command asks about.
    seed
        The same seed gives the same commands.
    count
        How many at most; the categories take turns, so each the floor allows
        appears once ``count`` reaches the number of categories. Each refusal
        category gives at most :data:`REFUSAL_SHARE` of ``count``, so a small
        floor may give fewer.

    Returns
    -------
    list of CommandCase
        No command twice.

    Examples
    --------
    >>> from sim2d.world import load_world
    >>> from sim2d.worlds import world_path
    >>> cases = generate_commands(load_world(world_path("office")), seed=0, count=7)
    >>> sorted({c.category for c in cases}) == sorted(CATEGORIES)
    True
    """
    truth = floor_truth(world)
    rng = np.random.default_rng(seed)
    pools = {name: list(make(truth, rng)) for name, make in _MAKERS.items()}
    caps = {name: max(1, math.ceil(REFUSAL_SHARE * count)) for name in pools
            if name.startswith("refuse_")}
    return _take_turns(pools, rng, count, caps)


def _take_turns(pools: dict[str, list[CommandCase]], rng: np.random.Generator, count: int,
                caps: dict[str, int]) -> list[CommandCase]:
    """Each category's cases shuffled (the first ``caps[name]`` kept), then one from each
    in turn until ``count``."""
    queues = {name: [pool[i] for i in rng.permutation(len(pool))][:caps.get(name, len(pool))]
              for name, pool in pools.items()}
    out: list[CommandCase] = []
    seen: set[str] = set()
    while len(out) < count and any(queues.values()):
        for queue in queues.values():
            while queue and len(out) < count:
                case = queue.pop(0)
                if case.command not in seen:
                    seen.add(case.command)
                    out.append(case)
                    break
    return out


def _pick(rng: np.random.Generator, options: Sequence[str]) -> str:
    return options[int(rng.integers(len(options)))]


# -- how commands name things ---------------------------------------------------------------------
def _sign_words(truth: FloorTruth, name: str) -> str | None:
    """How a command names a signed room by its number ("office 204"), or None when the
    planner could read the words as another room (or not at all).

    The planner reads "office 204" as the place named OFFICE 204 (the words' label
    and the number), else as the one place whose name ends in 204.
    """
    words = name.split()
    if len(words) < 2 or not words[-1].isdigit() or name not in truth.signed:
        return None
    concept = truth.ontology.lexicon.resolve(" ".join(words[:-1]).lower(), kinds={"place"},
                                             fuzzy=False)
    if concept is None:
        return None
    reading = f"{concept.label.upper()} {words[-1]}"
    same = [n for n in truth.kinds if n.upper() == reading]
    numbered = [n for n in truth.kinds if n.split()[-1] == words[-1]]
    if same == [name] or (not same and numbered == [name]):
        return name.lower()
    return None


def _word(truth: FloorTruth, cls: str, kinds: frozenset[str] = frozenset({"place"})
          ) -> str | None:
    """The ontology's first word for a class ("mail room"), if it reads back as that
    class among concepts of ``kinds``; else None."""
    word = truth.word(cls)
    if word is None:
        return None
    concept = truth.ontology.lexicon.resolve(word, kinds=kinds, fuzzy=False)
    return word if concept is not None and concept.local_name == cls else None


def _signed_kinds(truth: FloorTruth) -> list[str]:
    """The classes of the signed places, in file order."""
    out: dict[str, None] = {}
    for name in truth.kinds:
        if name in truth.signed:
            out.update(dict.fromkeys(sorted(truth.kinds[name])))
    return list(out)


def _named_people(truth: FloorTruth) -> list[Person]:
    """The timetable's people whose full name no one else's name holds (the planner
    matches names by their words, titles aside)."""
    if truth.timetable is None:
        return []
    words = {p.name: frozenset(w for w in normalise(p.name).split() if w not in TITLES)
             for p in truth.timetable.people}
    return [p for p in truth.timetable.people
            if words[p.name] and not any(words[p.name] <= other
                                         for name, other in words.items() if name != p.name)]


# -- places ---------------------------------------------------------------------------------------
_GO = ("go to {x}", "take me to {x}", "head to {x}", "how do I get to {x}?", "please go to {x}")
_GO_THE = ("go to the {x}", "take me to the {x}", "head to the {x}", "how do I get to the {x}?",
           "which way is the {x}?")


def _go_named(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    for name in truth.kinds:
        words = _sign_words(truth, name)
        if words is not None and name in truth.reachable:
            yield CommandCase(_pick(rng, _GO).format(x=words), "go_named",
                              objectives=(("go to", name),), why=f"the sign {name}")


def _one_of_kind(truth: FloorTruth, cls: str) -> tuple[str, str] | None:
    """(the place "the <kind>" means, why), or None when that is not clear-cut."""
    members = truth.places_of(cls)
    word = _word(truth, cls)
    if (word is None or not members or any(m not in truth.signed or m in truth.unsure
                                           for m in members)):
        return None
    reach = [m for m in members if m in truth.reachable]
    if len(reach) == 1:
        only = "only" if len(members) == 1 else "only reachable"
        return reach[0], f"the {only} {word}"
    if not reach:
        return None
    start = truth.world.start[:2]
    far = sorted((math.dist(start, truth.centre(m)), m) for m in reach)
    (d1, first), (d2, second) = far[:2]
    if d2 - d1 < NEAREST_MARGIN:
        return None
    return first, f"the nearest {word}: {d1:.1f} m from the start, {second} {d2:.1f} m"


def _go_kind(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    for cls in _signed_kinds(truth):
        found = _one_of_kind(truth, cls)
        if found is not None:
            yield CommandCase(_pick(rng, _GO_THE).format(x=_word(truth, cls)), "go_kind",
                              objectives=(("go to", found[0]),), why=found[1])


# -- objects --------------------------------------------------------------------------------------
def _things(truth: FloorTruth) -> Iterator[tuple[str, str, str]]:
    """(class, word, room) of each object class standing in one signed room only, with no
    subclass elsewhere and belonging in no other room."""
    for label, rooms in truth.holding.items():
        word = _word(truth, label, _THINGS)
        if word is None or len(rooms) != 1 or rooms[0] not in truth.signed:
            continue
        room = rooms[0]
        elsewhere = {r for other, where in truth.holding.items()
                     if other != label and truth.is_a(other, label) for r in where} - {room}
        if elsewhere or set(truth.belongs_in(label)) - {room}:
            continue
        yield label, word, room


def _destinations(truth: FloorTruth) -> list[tuple[str, str, str]]:
    """(how a command says it, place, why) for every clear-cut place to take things to:
    people's workplaces, rooms by number, rooms by kind."""
    out = []
    for person in _named_people(truth):
        places = truth.workplaces(person)
        if len(places) == 1 and places[0] in truth.signed and places[0] in truth.reachable:
            out.append((person.name, places[0], f"{person.name} works there"))
    for name in truth.kinds:
        words = _sign_words(truth, name)
        if words is not None and name in truth.reachable:
            out.append((words, name, f"the sign {name}"))
    for cls in _signed_kinds(truth):
        members = truth.places_of(cls)
        word = _word(truth, cls)
        if (word is not None and len(members) == 1 and members[0] in truth.signed
                and members[0] in truth.reachable):
            out.append((f"the {word}", members[0], f"the only {word}"))
    return out


_TAKE = ("take the {thing} to {dest}", "bring the {thing} to {dest}",
         "carry the {thing} to {dest}", "deliver the {thing} to {dest}",
         "please take the {thing} to {dest}")
_TO_ME = ("bring me the {thing}", "fetch the {thing}", "get me the {thing}")


def _fetch(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    destinations = _destinations(truth)
    for label, word, room in _things(truth):
        if room not in truth.reachable:
            continue
        seen = f"{_a(word)} stands in {room}"
        others = [d for d in destinations if d[1] != room]
        if others:
            text, place, why = others[int(rng.integers(len(others)))]
            yield CommandCase(_pick(rng, _TAKE).format(thing=word, dest=text), "fetch",
                              objectives=(("pick up", room), ("hand over", place)),
                              why=f"{seen}; {why}")
        yield CommandCase(_pick(rng, _TO_ME).format(thing=word), "fetch",
                          objectives=(("pick up", room), ("hand over", "you")),
                          why=f"{seen}; the one asking stands at the start")


_WHERE_THING = ("where is the {thing}?", "where can I find the {thing}?", "where's the {thing}")


def _where_object(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    for _, word, room in _things(truth):
        yield CommandCase(_pick(rng, _WHERE_THING).format(thing=word), "where_object",
                          answer=(room,), why=f"{_a(word)} stands in {room}")


# -- people ---------------------------------------------------------------------------------------
_WHERE_WHO = ("where is {who} at {time} on {day}?", "where will {who} be at {time} on {day}?",
              "where is {who} on {day} at {time}?")
_WEEKDAYS = DAYS[:5]


def _moment(day: str, minutes: int) -> dt.datetime:
    """That day of the week of 2026-01-05 (a Monday), ``minutes`` after midnight."""
    return dt.datetime(2026, 1, 5 + DAYS.index(day), minutes // 60, minutes % 60)


def _time_words(when: dt.datetime, rng: np.random.Generator) -> str:
    """ "10:30", or on the hour sometimes "2 pm"."""
    if when.minute == 0 and rng.random() < 0.5:
        return f"{when.hour % 12 or 12} {'am' if when.hour < 12 else 'pm'}"
    return f"{when.hour}:{when.minute:02d}"


def _person_question(person: Person, place: str, when: dt.datetime, why: str,
                     rng: np.random.Generator) -> CommandCase:
    text = _pick(rng, _WHERE_WHO).format(who=person.name, time=_time_words(when, rng),
                                         day=when.strftime("%A").lower())
    return CommandCase(text, "where_person", answer=(place, f"{when:%H:%M} on {when:%A}"),
                       why=why)


def _slot_moment(slot: Slot, theirs: list[Slot], rng: np.random.Generator
                 ) -> dt.datetime | None:
    """A moment inside ``slot`` that no other slot of theirs holds, or None."""
    start = slot.start.hour * 60 + slot.start.minute
    steps = max(1, (slot.end.hour * 60 + slot.end.minute - start) // 5)
    for _ in range(20):
        when = _moment(_pick(rng, slot.days), start + 5 * int(rng.integers(steps)))
        if [s for s in theirs if s.holds(when)] == [slot]:
            return when
    return None


def _free_moment(theirs: list[Slot], rng: np.random.Generator) -> dt.datetime | None:
    """A weekday moment between 07:00 and 19:00 that none of their slots holds, or None."""
    for _ in range(20):
        when = _moment(_pick(rng, _WEEKDAYS), 7 * 60 + 5 * int(rng.integers(144)))
        if not any(s.holds(when) for s in theirs):
            return when
    return None


def _where_person(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    if truth.timetable is None:
        return
    for person in _named_people(truth):
        theirs = [s for s in truth.timetable.slots if s.person == person.name]
        for slot in theirs:
            places = truth.named(slot.place)
            when = _slot_moment(slot, theirs, rng)
            if when is not None and len(places) == 1 and places[0] in truth.signed:
                subject = f" ({slot.subject})" if slot.subject else ""
                yield _person_question(person, places[0], when,
                                       f"the timetable's slot{subject}", rng)
        places = truth.workplaces(person)
        when = _free_moment(theirs, rng)
        if when is not None and len(places) == 1 and places[0] in truth.signed:
            yield _person_question(person, places[0], when,
                                   f"no slot then; {person.name} works there", rng)


# -- refusals -------------------------------------------------------------------------------------
def _refuse_kind(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    for entry in truth.ontology.vocabulary.entries:
        cls = entry.place_class
        word = _word(truth, cls)
        if (word is None or truth.places_of(cls) or truth.is_a(cls, "Circulation")
                or any(truth.is_a(k, cls) for k in truth.sign_kinds)):
            continue
        yield CommandCase(_pick(rng, _GO_THE[:3]).format(x=word), "refuse_kind",
                          refused=(f"this map has no {word}",),
                          why=f"no place on this floor is {_a(word)}")


def _a(word: str) -> str:
    return ("an " if word[:1] in "aeiou" else "a ") + word


def _number_words(truth: FloorTruth) -> list[str]:
    """Words rooms are numbered with ("OFFICE"): the floor's signs' first, then the
    vocabulary's (circulation aside), each only if the planner reads it back as itself."""
    words = [" ".join(n.split()[:-1]) for n in truth.kinds
             if n in truth.signed and len(n.split()) > 1 and n.split()[-1].isdigit()]
    words += [p.before for p in truth.ontology.vocabulary.patterns
              if p.slot in ("number", "id") and p.before and not p.after
              and not truth.is_a(p.place_class, "Circulation")]
    out = []
    for word in dict.fromkeys(words):
        concept = truth.ontology.lexicon.resolve(word.lower(), kinds={"place"}, fuzzy=False)
        if concept is not None and concept.label.upper() == word:
            out.append(word)
    return out


def _refuse_number(truth: FloorTruth, rng: np.random.Generator) -> Iterator[CommandCase]:
    used = {n.split()[-1] for n in truth.kinds} | {s.text.split()[-1]
                                                    for s in truth.world.signs if s.text.split()}
    words = _number_words(truth)
    for word in words[:3]:
        number = str(int(rng.integers(100, 1000)))
        while number in used:
            number = str(int(rng.integers(100, 1000)))
        used.add(number)
        name = f"{word} {number}"
        yield CommandCase(_pick(rng, _GO).format(x=name.lower()), "refuse_number",
                          refused=(f"this map has no place named {name}",),
                          why=f"no sign on this floor carries {number}")


_MAKERS = {"go_named": _go_named, "go_kind": _go_kind, "fetch": _fetch,
           "where_object": _where_object, "where_person": _where_person,
           "refuse_kind": _refuse_kind, "refuse_number": _refuse_number}
assert tuple(_MAKERS) == tuple(CATEGORIES)


# ---- scoring ------------------------------------------------------------------------------------
def score_commands(qm: QueryMap, cases: Iterable[CommandCase],
                   now: str | dt.datetime = DEFAULT_NOW, *,
                   world: World | None = None) -> dict[str, Any]:
    """Ask the planner every command on a map and count the right answers.

    Parameters
    ----------
    qm
        The map (:func:`semantic.query.load_map`: a run's folder or a world surveyed).
    cases
        From :func:`generate_commands` or :func:`load_commands`.
    now
        The moment the commands are asked at ("monday 10:00" or a datetime).
    world
        The world the map is of, to check where plans stop (:func:`stops_at`);
        default: the map's own (``qm.world``), when known.

    Returns
    -------
    dict
        ``total``, ``right``, ``right_fraction`` (0 when there are no cases),
        ``categories`` (name -> ``{total, right, right_fraction}``) and ``cases``:
        one row per command, ``{command, category, right, expected, got}``.

    Raises
    ------
    SemmapError
        ``now`` is not a moment.
    """
    when = parse_now(now) if isinstance(now, str) else now
    world = world if world is not None else _world_of(qm)
    rows = [_judge(case, qm, when, world) for case in cases]
    categories: dict[str, dict[str, Any]] = {}
    for row in rows:
        tally = categories.setdefault(row["category"], {"total": 0, "right": 0})
        tally["total"] += 1
        tally["right"] += int(row["right"])
    for tally in [*categories.values()]:
        tally["right_fraction"] = _fraction(tally["right"], tally["total"])
    right = sum(int(r["right"]) for r in rows)
    return {"total": len(rows), "right": right, "right_fraction": _fraction(right, len(rows)),
            "categories": categories, "cases": rows}


def _fraction(part: int, whole: int) -> float:
    return part / whole if whole else 0.0


def _world_of(qm: QueryMap) -> World | None:
    """The world a map is of, loaded, or None when it is unknown or cannot be read (the
    plans are then judged by their places' names alone)."""
    if qm.world is None:
        return None
    from sim2d.world import load_world
    try:
        return load_world(qm.world)
    except SemmapError:
        return None


def stops_at(world: World, name: str, x: float, y: float) -> bool:
    """Whether a stop at (x, y) is at the true place called ``name``: inside its outline,
    or in front of it, within :data:`AT_ROOM` of its outline in a place one of its open
    doors leads to (a corridor), not behind a wall in the room next door.  True when the
    world has no such place: there is nothing to check the stop against."""
    places = [p for p in world.places if same_name(p.name, name)]
    if not places:
        return True
    outlines = [np.asarray(p.polygon, np.float32).reshape(-1, 1, 2) for p in places]
    nearest = max(cv2.pointPolygonTest(o, (float(x), float(y)), True) for o in outlines)
    if nearest >= 0:
        return True
    names = {p.name for p in places}
    fronts = {other for d in world.doors if not d.closed and names & set(d.between)
              for other in d.between if other not in names}
    return -nearest <= AT_ROOM and _containing(world, x, y) in fronts


def _judge(case: CommandCase, qm: QueryMap, when: dt.datetime,
           world: World | None = None) -> dict[str, Any]:
    """One row of the score: whether the planner's answer is the expected one."""
    row = {"command": case.command, "category": case.category, "right": False,
           "expected": case.expected_text(), "got": ""}
    try:
        plan = ask(case.command, qm, now=when)
    except SemmapError as exc:
        row["got"] = f"error: {exc}"
        row["right"] = (case.expects == "refusal" and isinstance(exc, GroundingError)
                        and _holds(str(exc), case.refused))
        return row
    got = tuple((o.action, o.target.label) for o in plan.grounding.objectives)
    if case.expects == "plan":
        row["got"] = "; ".join(f"{a} at {p}" for a, p in got) or "no objectives"
        row["right"] = len(got) == len(case.objectives) and all(
            action == want_action and same_name(place, want_place)
            for (action, place), (want_action, want_place) in zip(got, case.objectives))
        astray = [o.target for o in plan.grounding.objectives if o.target.place_id is not None
                  and world is not None and not stops_at(world, o.target.label, o.target.x,
                                                         o.target.y)]
        if row["right"] and astray:
            row["right"] = False
            row["got"] += "; " + "; ".join(f"stops at ({t.x:.1f}, {t.y:.1f}) m, not at "
                                          f"{t.label}" for t in astray)
    elif case.expects == "answer":
        row["got"] = plan.grounding.answer
        row["right"] = _holds(plan.grounding.answer, case.answer)
    else:
        row["got"] = "not refused: " + ("; ".join(f"{a} at {p}" for a, p in got)
                                        or plan.grounding.answer)
    return row


def _holds(text: str, words: Sequence[str]) -> bool:
    """Whether ``text`` holds every one of ``words`` as whole words (case kept; spacing
    says nothing, as in :func:`~semantic.vocabulary.same_name`)."""
    return all(re.search(r"(?<!\w)" + r"\s*".join(re.escape(ch) for ch in w if not ch.isspace())
                         + r"(?!\w)", text) for w in words)


# ---- the file -----------------------------------------------------------------------------------
_HEADER = """\
# English commands with their right answers on this floor, from its ground truth
# (semantic/query/exam.py). Each command expects the plan's objectives in order
# ([action, place]), words its answer must hold, or words of the error refusing it.
# `now` is the moment they are asked at.
"""


def write_commands(path: str | Path, cases: Iterable[CommandCase],
                   now: str = DEFAULT_NOW) -> Path:
    """Write commands and the moment they are asked at (atomically), one command a line.

    Raises
    ------
    SemmapError
        ``now`` is not a moment ("monday 10:00" or an ISO date and time).
    """
    parse_now(now)
    lines = [_HEADER.rstrip("\n"), "version: 1", f"now: {json.dumps(now)}", "commands:"]
    for case in cases:
        fields = {"command": case.command, "category": case.category}
        for key in _EXPECTATIONS:
            value = getattr(case, key)
            if value:
                fields[key] = [list(v) for v in value] if key == "objectives" else list(value)
        if case.why:
            fields["why"] = case.why
        body = ", ".join(f"{k}: {json.dumps(v, ensure_ascii=False)}" for k, v in fields.items())
        lines.append(f"  - {{{body}}}")
    if lines[-1] == "commands:":
        lines[-1] = "commands: []"
    path = Path(path)
    atomic_write_text(path, "\n".join(lines) + "\n")
    return path


def load_commands(path: str | Path) -> tuple[list[CommandCase], str]:
    """Read a commands file: its commands and the moment they are asked at.

    Raises
    ------
    CommandsError
        The file is missing or not YAML, or a field is missing, unknown or malformed;
        the message names the file, line and field.
    """
    path = Path(path)
    doc = load_versioned_mapping(path, CommandsError, what="a commands file",
                                 fields=("now", "commands"),
                                 missing_hint="Write one with semantic.query.exam."
                                              "write_commands, or give the path of one.")
    now = doc.get("now", DEFAULT_NOW)
    if not isinstance(now, str):
        raise CommandsError(f"'now' must be a moment such as \"monday 10:00\", got {now!r}",
                            file=path, line=line_of(doc, "now"), field="now")
    try:
        parse_now(now)
    except SemmapError as exc:
        raise CommandsError(exc.message, file=path, line=line_of(doc, "now"), field="now",
                            hint=exc.hint) from None
    raw = doc.get("commands", [])
    if not isinstance(raw, list):
        raise CommandsError("'commands' must be a list", file=path,
                            line=line_of(doc, "commands"), field="commands")
    return [_case(item, path, line_of(raw, i), i) for i, item in enumerate(raw)], now


def _case(raw: Any, path: Path, line: int | None, index: int) -> CommandCase:
    """Check and build one entry of ``commands``."""
    what = f"command {index + 1}"
    if not isinstance(raw, dict):
        raise CommandsError(f"{what} must be a mapping with fields {', '.join(CASE_KEYS)}, "
                            f"got {raw!r}", file=path, line=line, field="commands")
    line = line_of(raw) or line

    def fail(message: str, key: str, hint: str | None = None) -> CommandsError:
        return CommandsError(message, file=path, line=line_of(raw, key) if key in raw else line,
                             field=key, hint=hint)

    for key in raw:
        if key not in CASE_KEYS:
            raise fail(f"unknown field {key!r} in {what}", str(key),
                       hint=f"Known fields: {', '.join(CASE_KEYS)}.")
    for key in ("command", "category"):
        if not isinstance(raw.get(key), str) or not raw[key].strip():
            raise fail(f"'{key}' of {what} must be a non-empty text, got {raw.get(key)!r}", key)
    given = [k for k in _EXPECTATIONS if k in raw]
    if len(given) != 1:
        raise fail(f"{what} must have exactly one of {', '.join(_EXPECTATIONS)}, got "
                   f"{', '.join(given) or 'none'}", given[-1] if given else "objectives")
    key = given[0]
    value = raw[key]
    if key == "objectives":
        expectation = _objectives(value, what, fail)
    elif (not isinstance(value, list) or not value
          or not all(isinstance(w, str) and w.strip() for w in value)):
        raise fail(f"'{key}' of {what} must be a non-empty list of texts, got {value!r}", key)
    else:
        expectation = tuple(value)
    why = raw.get("why", "")
    if not isinstance(why, str):
        raise fail(f"'why' of {what} must be a text, got {why!r}", "why")
    return CommandCase(raw["command"], raw["category"], why=why, **{key: expectation})


def _objectives(value: Any, what: str, fail: Any) -> tuple[tuple[str, str], ...]:
    ok = isinstance(value, list) and value and all(
        isinstance(v, list) and len(v) == 2 and all(isinstance(s, str) and s for s in v)
        for v in value)
    if not ok:
        raise fail(f"'objectives' of {what} must be a non-empty list of [action, place] "
                   f"pairs, got {value!r}", "objectives",
                   hint='Write e.g. objectives: [["pick up", "ADMIN"], ["hand over", "you"]].')
    for action, _ in value:
        if action not in OBJECTIVE_ACTIONS:
            raise fail(f"'objectives' of {what} has the action {action!r}", "objectives",
                       hint=f"Actions: {', '.join(OBJECTIVE_ACTIONS)}.")
    return tuple((action, place) for action, place in value)
