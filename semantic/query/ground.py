"""Objectives to places: grounding a parsed request in the semantic map, through the reasoner.

:func:`ground` turns a :class:`~semantic.query.parse.Request` into
:class:`Objective` s, each at a place of this map, with the reason the
knowledge base gives for it:

- things: where one was **observed**, else where the map's rooms hold one **by
  default** (a kitchen has a coffee machine), else where the kind **belongs**
  (mail belongs in a mail room); owned things that stay with their owner
  (a laptop, a key) are at the **owner's** workplace;
- roles and people: where they **work** (the office behind the MANAGER sign),
  or, given a time, where the timetable puts them;
- places: by kind ("the kitchen") or by the name on their sign ("office 101").

Where several places fit, the nearest to where the robot will be is taken and
the others are named in the answer. Nothing is guessed: a request that cannot be
grounded raises :class:`GroundingError`, saying what is missing and what is
known ("this map has no library; known places: ...").
"""
from __future__ import annotations

import datetime as dt
import math
import re
from dataclasses import dataclass, field
from typing import Any

from rdflib import URIRef

from blocks.core.errors import SemmapError
from semantic.rules import INDOOR
from semantic.timetable import DAYS

from .mapsource import QueryMap, _words
from .parse import Mention, Request

__all__ = ["Grounding", "GroundingError", "Objective", "Target", "ground", "moment"]

#: The day names answers use.
DAY_NAMES = dict(zip(DAYS, ("Monday", "Tuesday", "Wednesday", "Thursday", "Friday",
                            "Saturday", "Sunday")))
#: What each action does with its object.
CARRY = ("fetch", "bring", "take", "send", "deliver")
#: Why a thing is looked for where it is (kb.where_is's ``how``).
HOW = {"observed": "seen there by the robot", "default": "{kinds} usually have one",
       "belongs": "{thing} belongs in {a_kind}"}


class GroundingError(SemmapError):
    """A request whose things, people or places this map cannot place; the message says
    what is missing and what the map knows."""

    exit_code = 3


@dataclass(frozen=True)
class Target:
    """A place to go to, and why.

    ``place_id`` is None for the person asking, who stands where the robot starts.
    """

    place_id: str | None
    label: str
    x: float
    y: float
    why: str

    def to_dict(self) -> dict[str, Any]:
        return {"place": self.label, "place_id": self.place_id, "x": round(self.x, 3),
                "y": round(self.y, 3), "why": self.why}


@dataclass(frozen=True)
class Objective:
    """One thing to do at one place: ``go to``, ``pick up``, ``hand over`` or ``look for``."""

    action: str
    target: Target
    thing: str | None = None

    def to_dict(self) -> dict[str, Any]:
        return {"action": self.action, "object": self.thing, **self.target.to_dict()}


@dataclass
class Grounding:
    """A request grounded in a map: objectives (in order) and, for questions, the answer."""

    request: Request
    objectives: list[Objective] = field(default_factory=list)
    answer: str = ""
    when: dt.datetime | None = None


def moment(request: Request, now: dt.datetime) -> dt.datetime | None:
    """The date and time a request speaks of: its day (this week of ``now``) and time
    (``now``'s when not given); None when it gives neither."""
    if request.time is None and request.day is None:
        return None
    when = now
    if request.day is not None:
        when = when + dt.timedelta(days=DAYS.index(request.day) - when.weekday())
    if request.time is not None:
        hh, mm = (int(v) for v in request.time.split(":"))
        when = when.replace(hour=hh, minute=mm, second=0, microsecond=0)
    return when


def _when_text(when: dt.datetime) -> str:
    return f"at {when:%H:%M} on {DAY_NAMES[DAYS[when.weekday()]]}"


def _a(word: str) -> str:
    return ("an " if word[:1].lower() in "aeiou" else "a ") + word


class _Grounder:
    """Grounds one request (see :func:`ground`)."""

    def __init__(self, qm: QueryMap, request: Request, when: dt.datetime | None) -> None:
        self.qm, self.kb, self.request, self.when = qm, qm.kb, request, when
        self.notes: list[str] = []

    # ---- errors -------------------------------------------------------------------------
    def fail(self, what: str, hint: str | None = None) -> GroundingError:
        return GroundingError(f'cannot do "{self.request.text.strip()}": {what}',
                              hint=hint or f"Known places: {self.qm.known_places()}.")

    # ---- words to concepts ----------------------------------------------------------------
    def _concept_label(self, m: Mention) -> str:
        labels = self.kb.lexicon.labels_of(m.concept)
        return labels[0] if labels else _words(m.concept).lower()

    def _kind_words(self, concept: str) -> str:
        labels = self.kb.lexicon.labels_of(concept)
        return labels[0] if labels else _words(concept).lower()

    # ---- places ---------------------------------------------------------------------------
    def target(self, place_id: str, why: str) -> Target:
        point = self.qm.place_point(place_id)
        label = self.qm.label(place_id)
        if point is None:
            raise self.fail(f"{label} is on this map, but no way into it is known (the robot "
                            "has not been inside, and its doorway is mapped too narrow)",
                            hint="Map the building again with room visits on, or ask for "
                                 f"another place. Known places: {self.qm.known_places()}.")
        info = self.qm.places.get(place_id)
        if info is not None and info.polygon is None and info.name:
            note = (f"the robot read {label}'s sign but has not been inside: the plan stops "
                    "at its door")
            if note not in self.notes:
                self.notes.append(note)
        return Target(place_id, label, point[0], point[1], why)

    def home(self, why: str = "where you are") -> Target:
        x, y, _ = self.qm.home
        return Target(None, "you", x, y, why)

    def nearest(self, candidates: list[tuple[str, str]], what: str,
                near: tuple[float, float]) -> Target:
        """The candidate place nearest ``near`` that the robot can reach."""
        reachable = [(pid, why) for pid, why in candidates if self.qm.place_point(pid)]
        if not reachable:
            pid, why = candidates[0]
            return self.target(pid, why)  # raises: names the unreachable place
        pts = {pid: self.qm.place_point(pid) for pid, _ in reachable}
        pid, why = min(reachable, key=lambda c: (math.dist(pts[c[0]], near), c[0]))
        if len({p for p, _ in reachable}) > 1:
            others = ", ".join(self.qm.label(p) for p, _ in reachable if p != pid)
            self.notes.append(f"the nearest {what} is {self.qm.label(pid)} (others: {others})")
        return self.target(pid, why)

    def places_of(self, m: Mention, *, owner: Mention | None = None) -> list[tuple[str, str]]:
        """(place id, why) pairs for a place, person, role or numbered name."""
        if m.kind == "name":
            found = [pid for pid, info in self.qm.places.items()
                     if info.name and info.name.upper() == m.concept.upper()]
            if not found:  # "room 103": the place whose sign carries that number
                *words, number = m.concept.upper().split()
                found = [pid for pid, info in self.qm.places.items()
                         if info.name and info.name.split()[-1] == number
                         and self._same_kind_of_room(words, info.name.split()[:-1])]
                found = found if len(found) == 1 else []
            if not found:
                raise self.fail(f"this map has no place named {m.concept}")
            return [(pid, f"the sign {self.qm.places[pid].name}") for pid in found]
        if m.kind in ("person", "role"):
            return self.people_places(m)
        if m.kind == "place":
            found = [pid for pid, how in self.kb.where_is(m.concept) if pid in self.qm.places]
            if owner is not None:
                theirs = {pid for pid, _ in self.places_of(owner)}
                mine = [pid for pid in found if pid in theirs]
                if not mine:
                    where = ", ".join(self.qm.label(p) for p in sorted(theirs))
                    raise self.fail(f"{owner.text} is in {where}, which is not "
                                    f"{_a(self._concept_label(m))}")
                return [(pid, f"{owner.text}'s {self._concept_label(m)}") for pid in mine]
            if not found:
                raise self.fail(f"this map has no {self._concept_label(m)}")
            return [(pid, f"{_a(self._concept_label(m))}") for pid in found]
        raise self.fail(f'"{m.text}" is {_a(m.kind)}, not a place or a person')

    def _same_kind_of_room(self, asked: list[str], signed: list[str]) -> bool:
        """Whether a room asked for by number with the words ``asked`` ("ROOM", "LAB") may
        be the one whose sign has ``signed`` before that number ("OFFICE").

        Why: "room 103" means whatever room carries 103, but "lab 2" is no reason to go
        to STORE 2; a synonym ("laboratory 2" for LAB 2) is the same kind of room.
        """
        if not asked or asked == ["ROOM"] or asked == signed:
            return True
        if not signed:
            return False
        lexicon = self.kb.lexicon
        mine = lexicon.resolve(" ".join(asked), kinds={"place"}, fuzzy=False)
        theirs = lexicon.resolve(" ".join(signed), kinds={"place"}, fuzzy=False)
        return mine is not None and theirs is not None and mine.iri == theirs.iri

    def people_places(self, m: Mention) -> list[tuple[str, str]]:
        """Where a person or the people of a role are (now, or at the request's time)."""
        who = m.concept if m.kind == "person" else self._concept_label(m)
        names = self.kb.people_named(who)
        if not names:
            raise self.fail(f"no one on this map is {_a(who)}",
                            hint=f"People known: {', '.join(self.qm.people) or 'none'}. "
                                 f"Known places: {self.qm.known_places()}.")
        found: dict[str, list[tuple[str, str]]] = {}  # place -> [(name, why)]
        for name in names:
            if self.when is not None:
                place = self.kb.where_is_person_at(name, self.when)
                why = f"{name} is there {_when_text(self.when)}"
                if place is not None and place not in self.qm.places:
                    raise self.fail(f"the timetable puts {name} in the {place} "
                                    f"{_when_text(self.when)}, and this map has no {place}")
                places = [place] if place else []
            else:
                places = self.kb.works_in(name)
                why = f"{name} works there"
            for pid in places:
                found.setdefault(pid, []).append((name, why))
        if not found:
            raise self.fail(f"nothing on this map says where {who} is")
        if len(found) > 1 and m.kind == "role":
            options = " or ".join(f"{' and '.join(n for n, _ in found[p])} ({self.qm.label(p)})"
                                  for p in sorted(found))
            first = found[sorted(found)[0]][0][0]
            example = re.sub(rf"\b(the |a |an )?{re.escape(m.text)}", first, self.request.text,
                             count=1, flags=re.IGNORECASE)
            raise self.fail(f'"{m.text}" could mean {options}',
                            hint=f'Name the person, e.g. "{example}".')
        return [(pid, found[pid][0][1]) for pid in sorted(found)]

    # ---- things ---------------------------------------------------------------------------
    def belongs_with_owner(self, m: Mention) -> bool:
        iri = URIRef(str(INDOOR) + m.concept)
        return any(str(o).lower() == "true"
                   for o in self.kb.tbox.facts.objects(iri, INDOOR.belongsWithOwner))

    def thing_places(self, m: Mention, owner: Mention | None) -> list[tuple[str, str]]:
        """Where to find a thing: the owner's (if it stays with them), else observed,
        default and belonging places."""
        thing = self._concept_label(m)
        if owner is not None and self.belongs_with_owner(m):
            return [(pid, f"{_a(thing)} is kept by its owner: {why}")
                    for pid, why in self.places_of(owner)]
        found = [(pid, how) for pid, how in self.kb.where_is(m.concept) if pid in self.qm.places]
        if found:
            return [(pid, self._how(how, m, pid)) for pid, how in found]
        if self.belongs_with_owner(m):
            raise self.fail(f"whose {thing}? {_a(thing).capitalize()} is kept by its owner, "
                            "and none has been seen",
                            hint=f"Say whose, e.g. \"fetch the manager's {thing}\".")
        kinds = [self._kind_words(_local(k)) for k in
                 self.kb.tbox.facts.objects(URIRef(str(INDOOR) + m.concept),
                                            INDOOR.belongsInKind)]
        if kinds:
            raise self.fail(f"{thing} belongs in {_a(kinds[0])}, and this map has no "
                            f"{kinds[0]}")
        raise self.fail(f"nothing on this map says where to find {_a(thing)}: none was seen, "
                        "and no room here holds one by default")

    def _how(self, how: str, m: Mention, pid: str) -> str:
        thing = self._concept_label(m)
        kind = self.qm.places[pid].kind or "Place"
        words = self._kind_words(kind)
        return HOW.get(how, how).format(kinds=words + "s", thing=thing, a_kind=_a(words))


def _local(iri: Any) -> str:
    text = str(iri)
    return text.rsplit("#", 1)[-1].rsplit("/", 1)[-1]


def ground(request: Request, qm: QueryMap, *, now: dt.datetime | None = None) -> Grounding:
    """Ground a parsed request in a map (see the module docstring).

    Parameters
    ----------
    request
        From :func:`semantic.query.parse_command`.
    qm
        The building (:func:`semantic.query.mapsource.load_map`).
    now
        The moment the request is made: the day and time a request that names
        only one of them is completed with (default: the clock).

    Returns
    -------
    Grounding
        Commands: objectives in order. Questions: the answer (and, for "how do I
        get to", the place to go to as the one objective).

    Raises
    ------
    GroundingError
        Something the request needs is not on this map.
    """
    when = moment(request, now or dt.datetime.now())
    g = _Grounder(qm, request, when)
    out = Grounding(request, when=when)
    action = request.action
    if action in CARRY:
        out.objectives = _carry(g, request)
    elif action == "go":
        out.objectives = [Objective("go to", _destination(g, request.destination, request.owner))]
    elif action == "find":
        out.objectives = _find(g, request)
    elif action == "where":
        out.answer = _where(g, request)
    elif action == "who":
        out.answer = _who(g, request)
    elif action == "route":
        target = _destination(g, request.destination, request.owner)
        out.objectives = [Objective("go to", target)]
        out.answer = f"To get to {target.label}, follow the route below."
    else:  # pragma: no cover - the parser only makes the actions above
        raise g.fail(f"the action {action!r} is not known")
    if g.notes:
        out.answer = " ".join(filter(None, [out.answer] + [n[0].upper() + n[1:] + "." for n in g.notes]))
    return out


def _destination(g: _Grounder, m: Mention | None, owner: Mention | None,
                 near: tuple[float, float] | None = None) -> Target:
    if m is None:
        if owner is None:
            raise g.fail("no destination given", hint="Say where to, e.g. \"go to the kitchen\".")
        m, owner = owner, None
    near = near or g.qm.home[:2]
    return g.nearest(g.places_of(m, owner=owner), _words(m.text), near)


def _carry(g: _Grounder, r: Request) -> list[Objective]:
    thing = r.object
    assert thing is not None
    name = g._concept_label(thing)
    if r.source is not None:
        source = g.nearest(g.places_of(r.source), name, g.qm.home[:2])
    else:
        source = g.nearest(g.thing_places(thing, r.owner), name, g.qm.home[:2])
    here = (source.x, source.y)
    if r.destination is not None:
        dest = _destination(g, r.destination, None, near=here)
    elif r.owner is not None and not g.belongs_with_owner(thing):
        dest = _destination(g, r.owner, None, near=here)
        dest = Target(dest.place_id, dest.label, dest.x, dest.y, f"to its owner: {dest.why}")
    elif r.action in ("fetch", "bring"):
        dest = g.home("to you")
    else:
        raise g.fail(f"where should the {name} go?",
                     hint=f"Say where to, e.g. \"{r.action} the {name} to the kitchen\".")
    owned = f"{r.owner.text}'s {name}" if r.owner is not None else name
    return [Objective("pick up", source, owned), Objective("hand over", dest, owned)]


def _find(g: _Grounder, r: Request) -> list[Objective]:
    m = r.object
    assert m is not None
    if m.kind in ("object", "equipment"):
        target = g.nearest(g.thing_places(m, r.owner), g._concept_label(m), g.qm.home[:2])
        return [Objective("look for", target, g._concept_label(m))]
    target = _destination(g, m, r.owner)
    return [Objective("look for", target, m.text)]


def _where(g: _Grounder, r: Request) -> str:
    m = r.object
    assert m is not None
    if m.kind in ("object", "equipment"):
        thing = g._concept_label(m)
        places = g.thing_places(m, r.owner)
        parts = [f"{g.qm.label(pid)} ({why})" for pid, why in places]
        return f"The {thing} is in " + "; or ".join(parts) + "."
    if m.kind in ("person", "role"):
        places = g.people_places(m)
        who = m.concept if m.kind == "person" else f"the {g._concept_label(m)}"
        parts = " or ".join(g.qm.label(pid) for pid, _ in places)
        if g.when is not None:
            return f"{who[0].upper() + who[1:]} is in {parts} {_when_text(g.when)}."
        return f"{who[0].upper() + who[1:]} works in {parts}."
    places = g.places_of(m, owner=r.owner)
    parts = []
    for pid, _ in places:
        info = g.qm.places[pid]
        centre = f" around ({info.centre[0]:.1f}, {info.centre[1]:.1f}) m" if info.centre else ""
        parts.append(f"{info.label} is{centre}")
    return "; ".join(parts) + "."


def _who(g: _Grounder, r: Request) -> str:
    m = r.object
    assert m is not None
    if m.kind == "role":
        names = g.kb.people_named(g._concept_label(m))
        if not names:
            raise g.fail(f"no one on this map is {_a(g._concept_label(m))}",
                         hint=f"People known: {', '.join(g.qm.people) or 'none'}.")
        return f"{' and '.join(names)}: {g._concept_label(m)}."
    if m.kind == "person":
        places = g.kb.works_in(m.concept)
        where = " or ".join(g.qm.label(p) for p in places) or "no known place"
        return f"{m.concept} works in {where}."
    places = g.places_of(m, owner=r.owner)
    lines = []
    for pid, _ in places:
        if g.when is not None:
            people = [p for p in g.qm.people if g.kb.where_is_person_at(p, g.when) == pid]
            when = f" {_when_text(g.when)}"
        else:
            people = [p if p in g.qm.people else f"{_a(_words(p).lower())} (name not known)"
                      for p in g.kb.who_works_in(pid)]
            when = ""
        label = g.qm.label(pid)
        lines.append(f"{' and '.join(people)} {'is' if len(people) == 1 else 'are'} in "
                     f"{label}{when}" if people else f"No one is known to be in {label}{when}")
    text = "; ".join(lines) + "."
    return text[0].upper() + text[1:]
