"""A world's ground truth in the task planner's terms: the answers commands should get.

The command generator (:mod:`semantic.query.exam`) needs to know, from the world
file alone, what a right answer is: which places a command can name (a place is
addressable only if a sign on the floor carries its name), what kind each place
is (its true kind, and the class its sign's text names), where each object
stands, where each person works, and which rooms the robot can get into from
its start. :class:`FloorTruth` holds that, read from the world's ``places``,
``doors``, ``signs``, ``objects`` and timetable and from the ontology's class
hierarchy and words; nothing here asks the planner or the reasoner about the
floor.

Reachability is decided by the doors: a room is **reachable** when a chain of
open doors at least :data:`SURE_DOOR` wide joins it to the start's place, and
**unsure** when the chain needs a door between :data:`TIGHT_DOOR` and
:data:`SURE_DOOR` (the robot's width plus up to two planning cells: the
planner's inflated grid may or may not let it through; on generated floors 3 of
69 such rooms were out of its reach). Commands never send the robot to an unsure
room.
"""
from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import networkx as nx
import numpy as np
from rdflib import URIRef

from blocks.navigate.grid import DEFAULT_RADIUS
from semantic.query.mapsource import PLAN_RESOLUTION
from semantic.kb import INDOOR, KnowledgeBase
from semantic.rules import _area, _inside
from semantic.timetable import Person, Timetable, load_timetable
from semantic.vocabulary import compact

if TYPE_CHECKING:
    from sim2d.world import World

__all__ = ["SURE_DOOR", "TIGHT_DOOR", "FloorTruth", "floor_truth"]

#: Open doors at least this wide (m) let the robot through for sure: its width, plus a
#: planning cell each side that coarsening the map may take off the opening.
SURE_DOOR = 2 * DEFAULT_RADIUS + 2 * PLAN_RESOLUTION
#: Doors narrower than this (m) never let it through.
TIGHT_DOOR = 2 * DEFAULT_RADIUS


@dataclass(frozen=True)
class FloorTruth:
    """What a world's ground truth says about its places, objects and people.

    Attributes
    ----------
    world
        The world.
    ontology
        A knowledge base holding only the ontology: its words (``lexicon``), class
        hierarchy (``tbox``) and the classes sign texts name.
    timetable
        The world's timetable, or None.
    kinds
        Place name -> the classes it is (its true kind and its sign's class).
    signed
        The names of the places a sign on the floor carries.
    sign_kinds
        The place classes the floor's sign texts name (a sign may name no place).
    reachable
        Places the robot surely gets into from its start.
    unsure
        Places it may or may not get into (see the module docstring).
    holding
        Object label -> the names of the places holding one, in file order.
    """

    world: World
    ontology: KnowledgeBase
    timetable: Timetable | None
    kinds: dict[str, frozenset[str]]
    signed: frozenset[str]
    sign_kinds: frozenset[str]
    reachable: frozenset[str]
    unsure: frozenset[str]
    holding: dict[str, tuple[str, ...]]

    # ---- classes --------------------------------------------------------------------------------
    def is_a(self, cls: str, top: str) -> bool:
        """Whether class ``cls`` is ``top`` or a subclass of it (local names)."""
        return self.ontology.tbox.is_sub(URIRef(INDOOR[cls]), URIRef(INDOOR[top]))

    def places_of(self, cls: str) -> list[str]:
        """The places of a class or any subclass of it, signed or not, in file order."""
        return [name for name, kinds in self.kinds.items()
                if any(self.is_a(k, cls) for k in kinds)]

    def word(self, cls: str) -> str | None:
        """The ontology's first English label of a class ("mail room"), or None."""
        labels = self.ontology.lexicon.labels_of(cls)
        return labels[0] if labels else None

    def annotation(self, cls: str, prop: str) -> list[str]:
        """The local names an ontology annotation gives a class (``workplaceKind``...)."""
        return sorted(_local(o) for o in
                      self.ontology.tbox.facts.objects(URIRef(INDOOR[cls]), INDOOR[prop]))

    def belongs_in(self, cls: str) -> list[str]:
        """The places where things of a class belong (``indoor:belongsInKind``: mail in a
        mail room), through its super- and subclasses too."""
        tb = self.ontology.tbox.facts
        kinds = {_local(k) for c in tb.subjects_with(INDOOR.belongsInKind)
                 if self.is_a(cls, _local(c)) or self.is_a(_local(c), cls)
                 for k in tb.objects(c, INDOOR.belongsInKind)}
        return [p for kind in sorted(kinds) for p in self.places_of(kind)]

    # ---- places ---------------------------------------------------------------------------------
    def named(self, text: str) -> list[str]:
        """The places whose name is ``text``, spaces, case and punctuation aside (as
        timetables and workplaces name them)."""
        key = compact(text)
        return [name for name in self.kinds if compact(name) == key]

    def centre(self, name: str) -> tuple[float, float]:
        """The mean of a place's corners (the point the knowledge base gives it), m."""
        place = self.world.place(name)
        assert place is not None, name
        poly = np.asarray(place.polygon, dtype=np.float64)
        return float(poly[:, 0].mean()), float(poly[:, 1].mean())

    # ---- people ---------------------------------------------------------------------------------
    def person(self, name: str) -> Person | None:
        """The timetable's person of that name, or None."""
        return self.timetable.person(name) if self.timetable is not None else None

    def workplaces(self, person: Person) -> list[str]:
        """Where a person works: the place named by their workplace, else the places of
        their role's workplace kind."""
        if person.workplace:
            named = self.named(person.workplace)
            if named:
                return named
        if person.role is None:
            return []
        return [p for kind in self.annotation(person.role, "workplaceKind")
                for p in self.places_of(kind)]


def _local(iri: object) -> str:
    return str(iri).rsplit("#", 1)[-1]


def floor_truth(world: World, *, ontology: KnowledgeBase | None = None) -> FloorTruth:
    """Read a world's ground truth (see :class:`FloorTruth`).

    Parameters
    ----------
    world
        A loaded world with ``places`` (and usually ``doors``, ``signs``,
        ``objects`` and a timetable).
    ontology
        The ontology to classify with (default: the packaged one).
    """
    kb = ontology if ontology is not None else KnowledgeBase()
    timetable = load_timetable(world.timetable) if world.timetable is not None else None
    texts = {" ".join(s.text.split()) for s in world.signs}
    signed = frozenset(p.name for p in world.places if p.name in texts)
    kinds = {p.name: frozenset(_classes(kb, p.kind, p.name if p.name in signed else None))
             for p in world.places}
    sure, maybe = _reach(world)
    sign_kinds = frozenset(k for text in texts for k in _classes(kb, None, text))
    return FloorTruth(world=world, ontology=kb, timetable=timetable, kinds=kinds, signed=signed,
                      sign_kinds=sign_kinds, reachable=frozenset(sure),
                      unsure=frozenset(maybe - sure), holding=_holding(world))


def _classes(kb: KnowledgeBase, kind: str | None, sign: str | None) -> Iterable[str]:
    """A place's true kind and the place class its sign's text names."""
    if kind is not None:
        yield kind
    concept = kb.resolve_sign(sign) if sign else None
    if concept is not None and concept.kind == "place":
        yield concept.local_name


def _containing(world: World, x: float, y: float) -> str | None:
    """The place whose outline holds (x, y); the smallest when outlines nest (as the
    knowledge base places objects)."""
    holding = [(_area(np.asarray(p.polygon, float)), p.name) for p in world.places
               if _inside(np.asarray(p.polygon, float), x, y)]
    return min(holding)[1] if holding else None


def _holding(world: World) -> dict[str, tuple[str, ...]]:
    out: dict[str, list[str]] = {}
    for obj in world.objects:
        place = _containing(world, obj.x, obj.y)
        if place is not None and place not in out.setdefault(obj.label, []):
            out[obj.label].append(place)
    return {label: tuple(places) for label, places in out.items()}


def _reach(world: World) -> tuple[set[str], set[str]]:
    """(places surely reachable from the start, places perhaps reachable)."""
    start = _containing(world, *world.start[:2])
    if start is None:
        return set(), {p.name for p in world.places}
    found = []
    for least in (SURE_DOOR, TIGHT_DOOR):
        g = nx.Graph()
        g.add_nodes_from(p.name for p in world.places)
        g.add_edges_from(d.between for d in world.doors
                         if not d.closed and d.width >= least and all(n in g for n in d.between))
        found.append(set(nx.node_connected_component(g, start)))
    return found[0], found[1]
