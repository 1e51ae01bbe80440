"""Domain rules of the indoor knowledge base: what OWL 2 RL cannot (or should not) derive.

The OWL reasoner (``reasonable``) gives the ontology's consequences: a place
typed MailRoom is a ServiceRoom, a Room and a Place and has the function
MailHandling (an ``owl:hasValue`` restriction); a door's places get
``indoor:hasDoor``; ``adjacentTo`` is symmetric. The rules here add the
domain knowledge the paper asks of the reasoning engine (section 2.4): signs
name rooms, rooms hold their functions' default equipment unless the robot saw
otherwise, people work in the rooms of their role's kind, objects belong in
places of a kind, and every place reachable through doors is connected.

Each rule is a small documented Python function over an indexed set of facts
(:class:`Facts`); where a rule is a plain graph pattern its SPARQL CONSTRUCT
form is given too (``Rule.sparql``), as its specification: the tests check
that the KB's materialised graph holds everything the CONSTRUCT gives.
Python rather than SPARQL runs them because rdflib's SPARQL engine costs
milliseconds per query, and the whole pass must stay in tens of ms to re-run
on every new sign.

Two stages, run by :meth:`semantic.kb.KnowledgeBase.reason`:

``pre``
    on the asserted facts, before the OWL pass; their outputs are given to the
    reasoner, so their consequences (a sign's place class implies functions,
    superclasses, ...) are materialised by it. Pre rules look up class
    hierarchy facts in the ontology (:class:`TBox`), not in the OWL closure.
``post``
    on the OWL closure; their outputs use properties without OWL axioms of
    their own (``hasDefaultEquipment``, ``belongsIn``, ``connectedTo``), so they
    need no second OWL pass. A post rule marked ``feeds_owl`` would trigger one
    (the KB iterates OWL + rules to a fixpoint); none does by default.

Within a stage rules run in order and each sees the previous ones' outputs;
no rule's output feeds an earlier rule, so one pass in this order is a
fixpoint (stratified evaluation). Some rules are not monotonic (a default is
dropped once an object of its class is observed), which is why the KB
recomputes every rule from the asserted facts on each reasoning pass.
"""
from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from typing import Any

import networkx as nx
import numpy as np
import rdflib
from rdflib import RDF, RDFS, Literal, URIRef

from semantic.vocabulary import compact

__all__ = ["INDOOR", "MAP", "PAIRWISE_MAX", "POST_RULES", "PRE_RULES", "Facts", "Rule",
           "RuleContext", "TBox", "Triple", "run_rules"]



class _Namespace(rdflib.Namespace):
    """An rdflib Namespace that builds each attribute term once: ``INDOOR.worksIn`` is a
    dict look-up, not a new URIRef validated on every use in the rules' inner loops."""

    def __getattr__(self, name: str) -> URIRef:
        if name.startswith("__"):
            raise AttributeError(name)
        term = self.term(name)
        self.__dict__[name] = term
        return term


INDOOR = _Namespace("https://w3id.org/semmap/indoor#")
MAP = _Namespace("https://w3id.org/semmap/map#")
Triple = tuple[Any, Any, Any]
#: Components of the place graph up to this many places get every connectedTo pair
#: materialised (at most 64 * 63 = 4032 triples); larger ones only adjacency (see
#: :func:`connectivity`).
PAIRWISE_MAX = 64
OBSERVED = Literal("observed")
DEFAULT = Literal("default")


class Facts:
    """A set of triples indexed by (subject, predicate) and (predicate, object).

    Rules read it with :meth:`objects` / :meth:`subjects` (dict look-ups, far
    cheaper than rdflib graph matching) and add to it as they derive.
    """

    def __init__(self, triples: Iterable[Triple] = ()) -> None:
        self.triples: set[Triple] = set(triples)
        self._sp: dict[tuple, set] = defaultdict(set)
        self._po: dict[tuple, set] = defaultdict(set)
        self._p: dict[Any, set] = defaultdict(set)
        sp, po, pp = self._sp, self._po, self._p
        for s, p, o in self.triples:  # no per-triple membership test: rdflib's __eq__ is slow
            sp[(s, p)].add(o)
            po[(p, o)].add(s)
            pp[p].add(s)

    def __len__(self) -> int:
        return len(self.triples)

    def __contains__(self, t: Triple) -> bool:
        return t in self.triples

    def __iter__(self) -> Iterator[Triple]:
        return iter(self.triples)

    def add(self, t: Triple) -> bool:
        """Add a triple; True when it is new."""
        if t in self.triples:
            return False
        s, p, o = t
        self.triples.add(t)
        self._sp[(s, p)].add(o)
        self._po[(p, o)].add(s)
        self._p[p].add(s)
        return True

    def objects(self, s: Any, p: Any) -> set:
        return self._sp.get((s, p), set())

    def subjects(self, p: Any, o: Any) -> set:
        return self._po.get((p, o), set())

    def subjects_with(self, p: Any) -> set:
        """Every subject that has some value for ``p``."""
        return self._p.get(p, set())

    def one(self, s: Any, p: Any) -> Any:
        """One value of (s, p) (the smallest, for determinism), or None."""
        values = self._sp.get((s, p))
        return min(values, key=str) if values else None


class TBox:
    """The ontology's class hierarchy and class-level facts, computed once per ontology.

    Attributes
    ----------
    facts : Facts
        Every ontology triple.
    supers : dict
        Class -> the set of its named superclasses, itself included (rdfs:subClassOf*).
    """

    def __init__(self, graph: rdflib.Graph) -> None:
        self.facts = Facts(graph)
        parents: dict[Any, set] = defaultdict(set)
        for s, _, o in graph.triples((None, RDFS.subClassOf, None)):
            if isinstance(s, URIRef) and isinstance(o, URIRef):
                parents[s].add(o)
        self.supers: dict[Any, set] = {}
        for cls in set(parents) | {o for v in parents.values() for o in v}:
            seen, todo = {cls}, [cls]
            while todo:
                for up in parents.get(todo.pop(), ()):
                    if up not in seen:
                        seen.add(up)
                        todo.append(up)
            self.supers[cls] = seen
        self.subs: dict[Any, set] = defaultdict(set)
        for cls, ups in self.supers.items():
            for up in ups:
                self.subs[up].add(cls)
        self.place_classes = set(self.subs.get(INDOOR.Place, {INDOOR.Place})) | {INDOOR.Place}

    def is_sub(self, cls: Any, top: Any) -> bool:
        return cls == top or top in self.supers.get(cls, ())

    def depth(self, cls: Any) -> int:
        return len(self.supers.get(cls, ()))


@dataclass
class RuleContext:
    """What rules need besides the facts: the ontology, place outlines, the lexicon.

    ``place_graph`` is filled by :func:`connectivity` (the KB keeps it for
    ``connected`` and ``place_graph``).
    """

    tbox: TBox
    polygons: dict[Any, np.ndarray] = field(default_factory=dict)
    lexicon: Any = None
    place_graph: nx.Graph = field(default_factory=nx.Graph)
    rule_ms: dict[str, float] = field(default_factory=dict)

    def typed(self, facts: Facts, individual: Any, cls: Any) -> bool:
        """Whether an asserted type of ``individual`` is ``cls`` or a subclass of it."""
        return any(self.tbox.is_sub(t, cls) for t in facts.objects(individual, RDF.type))

    def instances(self, facts: Facts, cls: Any) -> set:
        """Individuals with an asserted type that is ``cls`` or a subclass of it."""
        out: set = set()
        for sub in self.tbox.subs.get(cls, {cls}) | {cls}:
            out |= {s for s in facts.subjects(RDF.type, sub) if isinstance(s, URIRef)
                    and str(s).startswith(str(MAP))}
        return out

    def places(self, facts: Facts) -> set:
        return self.instances(facts, INDOOR.Place)

    def places_named(self, facts: Facts) -> dict[str, set]:
        """compact(name) -> places with that indoor:name (sign text), e.g. "MAILROOM"."""
        out: dict[str, set] = defaultdict(set)
        for p in self.places(facts):
            for name in facts.objects(p, INDOOR.name):
                out[compact(str(name))].add(p)
        return out


@dataclass(frozen=True)
class Rule:
    """A domain rule: ``apply(facts, ctx)`` yields the triples it derives."""

    name: str
    stage: str  # "pre" or "post"
    apply: Callable[[Facts, RuleContext], Iterable[Triple]]
    sparql: str | None = None
    feeds_owl: bool = False

    @property
    def doc(self) -> str:
        return (self.apply.__doc__ or "").strip()


def run_rules(rules: Iterable[Rule], facts: Facts, ctx: RuleContext) -> dict[str, set]:
    """Apply rules in order, adding each one's output to ``facts`` before the next runs.

    Returns the new triples of each rule, by rule name; each rule's milliseconds go to
    ``ctx.rule_ms``.
    """
    derived: dict[str, set] = {}
    for rule in rules:
        t0 = time.perf_counter()
        new = set()
        for t in rule.apply(facts, ctx):
            if facts.add(t):
                new.add(t)
        derived[rule.name] = new
        ctx.rule_ms[rule.name] = (time.perf_counter() - t0) * 1e3
    return derived


# ---- pre rules (before the OWL pass) --------------------------------------------------------------
def sign_names_place(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """A sign makes the place behind it a place of the class its text names.

    A door plate reading MANAGER (class ManagerOffice in semantic/vocabulary.yaml)
    makes the room it labels a ManagerOffice, and its text the room's name when
    the room has none yet (so timetables can name it: "LAB", "OFFICE 101").
    """
    for sign in sorted(ctx.instances(facts, INDOOR.Sign) | facts.subjects(RDF.type, INDOOR.Sign),
                       key=str):
        for place in facts.objects(sign, INDOOR.labels):
            for cls in facts.objects(sign, INDOOR.signClass):
                yield (place, RDF.type, cls)
            if not facts.objects(place, INDOOR.name):
                text = facts.one(sign, INDOOR.text)
                if text is not None:
                    yield (place, INDOOR.name, Literal(str(text)))


def door_adjacency(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """Two places a door connects are adjacent (both ways).

    OWL could say this only with a property chain (hasDoor o connects), which
    would also make every place adjacent to itself.
    """
    for door in facts.subjects(RDF.type, INDOOR.Door):
        places = sorted(facts.objects(door, INDOOR.connects), key=str)
        for a in places:
            for b in places:
                if a != b:
                    yield (a, INDOOR.adjacentTo, b)


def locate_by_outline(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """An object given without a place is in the place whose outline holds its (x, y).

    Objects are often added before the place segmentation knows the rooms; this
    places them once it does. The smallest containing outline wins (a room
    drawn inside a hall).
    """
    if not ctx.polygons:
        return
    outlines = sorted((_outline(poly) + (p, poly) for p, poly in ctx.polygons.items()),
                      key=lambda t: (t[0], str(t[5])))
    for obj in sorted(ctx.instances(facts, INDOOR.PhysicalObject), key=str):
        if facts.objects(obj, INDOOR.locatedIn):
            continue
        x, y = facts.one(obj, INDOOR.x), facts.one(obj, INDOOR.y)
        if x is None or y is None:
            continue
        x, y = float(x), float(y)
        for _, x0, y0, x1, y1, place, poly in outlines:
            if x0 <= x <= x1 and y0 <= y <= y1 and _inside(poly, x, y):
                yield (obj, INDOOR.locatedIn, place)
                break


_OUTLINES: dict[int, tuple] = {}


def _outline(poly: np.ndarray) -> tuple[float, float, float, float, float]:
    """(area, x0, y0, x1, y1) of an outline, cached by array identity (the KB keeps its
    arrays for the place's lifetime and never changes them in place)."""
    key = id(poly)
    hit = _OUTLINES.get(key)
    if hit is None or hit[0] is not poly:
        hit = (poly, (_area(poly), float(poly[:, 0].min()), float(poly[:, 1].min()),
                      float(poly[:, 0].max()), float(poly[:, 1].max())))
        if len(_OUTLINES) > 4096:
            _OUTLINES.clear()
        _OUTLINES[key] = hit
    return hit[1]


def _inside(poly: np.ndarray, x: float, y: float) -> bool:
    """Even-odd ray casting: whether (x, y) is inside the polygon (N, 2)."""
    xs, ys = poly[:, 0], poly[:, 1]
    xn, yn = np.roll(xs, -1), np.roll(ys, -1)
    crosses = (ys > y) != (yn > y)
    with np.errstate(divide="ignore", invalid="ignore"):
        at = xs + (y - ys) * (xn - xs) / (yn - ys)
    return bool(np.count_nonzero(crosses & (x < at)) % 2)


def _area(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(np.dot(x, np.roll(y, 1)) - np.dot(y, np.roll(x, 1))))


def named_workplace(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """A person whose timetable entry names a workplace ("OFFICE 101") works in the
    map place carrying that name, when the map has it."""
    named = ctx.places_named(facts)
    for person in facts.subjects_with(INDOOR.workplaceName):
        for name in facts.objects(person, INDOOR.workplaceName):
            for place in named.get(compact(str(name)), ()):
                yield (person, INDOOR.worksIn, place)


def role_workplace(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """People of a role work in the places of their role's workplace kind on this map.

    The ontology says a Manager works in a ManagerOffice (``indoor:workplaceKind``);
    once a sign has made a room a ManagerOffice, the managers on record (from a
    timetable) work there - or, when nobody of that role is known, a person
    standing for the role ("Manager", ``indoor:source "default"``) is created,
    so "fetch the manager's mail" has an answer. People with a workplace of
    their own (:func:`named_workplace`) keep it.
    """
    tb = ctx.tbox.facts
    for role in sorted(tb.subjects(RDF.type, INDOOR.Role), key=str):
        kind = tb.one(role, INDOOR.workplaceKind)
        if kind is None:
            continue
        places = sorted(ctx.instances(facts, kind), key=str)
        if not places:
            continue
        people = sorted(facts.subjects(INDOOR.hasRole, role), key=str)
        if not people:
            person = MAP[f"role_{_local(role)}"]
            people = [person]
            yield (person, RDF.type, INDOOR.Person)
            yield (person, INDOOR.hasRole, role)
            yield (person, INDOOR.name, Literal(_local(role)))
            yield (person, INDOOR.source, DEFAULT)
        for person in people:
            if facts.objects(person, INDOOR.workplaceName) and facts.objects(person,
                                                                             INDOOR.worksIn):
                continue
            for place in places:
                yield (person, INDOOR.worksIn, place)


def slot_place(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """A timetable slot's place name ("LAB") is the map place carrying that name."""
    named = ctx.places_named(facts)
    for slot in facts.subjects(RDF.type, INDOOR.Slot):
        for name in facts.objects(slot, INDOOR.placeName):
            for place in named.get(compact(str(name)), ()):
                yield (slot, INDOOR.place, place)


# ---- post rules (on the OWL closure) --------------------------------------------------------------
def connectivity(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """Places joined by a chain of doors (and the corridors between) are connected.

    ``indoor:connectedTo`` is transitive in the ontology, but an OWL reasoner
    derives a transitive closure pair by pair through rule joins, which grows
    as the cube of a component's size; networkx finds the connected components
    of the place graph (places, adjacency) in linear time. Every pair of a
    component of at most :data:`PAIRWISE_MAX` places is materialised (a floor's
    rooms: SPARQL can ask ``?a indoor:connectedTo ?b`` directly); for a larger
    component only the adjacency pairs are (ask ``indoor:adjacentTo+`` or use
    :meth:`semantic.kb.KnowledgeBase.connected`, which reads the graph).
    """
    g = nx.Graph()
    for place in ctx.places(facts):
        g.add_node(place)
    for a in list(g.nodes):
        for b in facts.objects(a, INDOOR.adjacentTo):
            if b in g:
                g.add_edge(a, b)
    ctx.place_graph = g
    for comp in nx.connected_components(g):
        members = sorted(comp, key=str)
        if len(members) <= PAIRWISE_MAX:
            for a in members:
                for b in members:
                    if a != b:
                        yield (a, INDOOR.connectedTo, b)
        else:
            for a, b in g.subgraph(members).edges:
                yield (a, INDOOR.connectedTo, b)
                yield (b, INDOOR.connectedTo, a)


def observed_classes(facts: Facts) -> set:
    """Every class (with superclasses, from the OWL closure) of an observed object."""
    out: set = set()
    for obj in facts.subjects(INDOOR.source, OBSERVED):
        out |= facts.objects(obj, RDF.type)
    return out


def default_equipment(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """A place holds its functions' default equipment, unless the robot saw otherwise.

    A mail room (function MailHandling) has a shredder by default. But once a
    shredder has been *observed* anywhere on the map (``indoor:source
    "observed"``), observation takes precedence: the default is not derived, and
    ``where_is("Shredder")`` gives the observed place. Defaults are classes
    (``?place indoor:hasDefaultEquipment indoor:Shredder``), not invented
    individuals, so a default never passes for an object the robot could fetch.
    """
    tb = ctx.tbox.facts
    seen = observed_classes(facts)
    for place in ctx.places(facts):
        for function in facts.objects(place, INDOOR.hasFunction):
            for equipment in tb.objects(function, INDOOR.defaultEquipment):
                if equipment not in seen:
                    yield (place, INDOOR.hasDefaultEquipment, equipment)


def object_belongs(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """Objects whose kind belongs in a kind of place belong in the places of that kind here.

    Mail belongs in a MailRoom (``indoor:belongsInKind``), so the kind Mail and
    every Mail individual belong in this map's mail room(s): "fetch the mail"
    knows where to look even before any mail is seen.
    """
    tb = ctx.tbox.facts
    for cls in sorted(tb.subjects_with(INDOOR.belongsInKind), key=str):
        places = set()
        for kind in tb.objects(cls, INDOOR.belongsInKind):
            places |= facts.subjects(RDF.type, kind) & ctx.places(facts)
        for place in places:
            yield (cls, INDOOR.belongsIn, place)
            for obj in facts.subjects(RDF.type, cls):
                yield (obj, INDOOR.belongsIn, place)


def owner_belongs(facts: Facts, ctx: RuleContext) -> Iterator[Triple]:
    """An owned object (laptop, document, key) belongs at its owner's workplace.

    The owner is named by ``indoor:ownedBy`` (a person) or ``indoor:ownerName``:
    a person's name, a role ("manager" -> the managers' workplaces) or a place
    name ("ADMIN" -> the admin office: "the admin laptop").
    """
    named = ctx.places_named(facts)
    people_by_name: dict[str, set] = defaultdict(set)
    for person in facts.subjects(RDF.type, INDOOR.Person):
        for name in facts.objects(person, INDOOR.name):
            people_by_name[compact(str(name))].add(person)
    for obj in sorted(facts.subjects_with(INDOOR.ownerName)
                      | facts.subjects_with(INDOOR.ownedBy), key=str):
        owners = set(facts.objects(obj, INDOOR.ownedBy))
        places: set = set()
        for name in facts.objects(obj, INDOOR.ownerName):
            key = compact(str(name))
            owners |= people_by_name.get(key, set())
            places |= named.get(key, set())
            if ctx.lexicon is not None and not owners and not places:
                concept = ctx.lexicon.resolve(str(name), kinds={"role", "place"})
                if concept is not None and concept.kind == "role":
                    owners |= facts.subjects(INDOOR.hasRole, URIRef(concept.iri))
                elif concept is not None:
                    places |= facts.subjects(RDF.type, URIRef(concept.iri)) & ctx.places(facts)
        for person in owners:
            places |= facts.objects(person, INDOOR.worksIn)
        for place in sorted(places, key=str):
            yield (obj, INDOOR.belongsIn, place)


def _local(iri: Any) -> str:
    text = str(iri)
    return text.rsplit("#", 1)[-1].rsplit("/", 1)[-1]


_P = "PREFIX indoor: <https://w3id.org/semmap/indoor#>\n"
PRE_RULES: tuple[Rule, ...] = (
    Rule("sign_names_place", "pre", sign_names_place, _P + """
CONSTRUCT { ?place a ?cls } WHERE {
  ?sign a indoor:Sign ; indoor:labels ?place ; indoor:signClass ?cls }"""),
    Rule("door_adjacency", "pre", door_adjacency, _P + """
CONSTRUCT { ?a indoor:adjacentTo ?b } WHERE {
  ?door a indoor:Door ; indoor:connects ?a, ?b . FILTER (?a != ?b) }"""),
    Rule("locate_by_outline", "pre", locate_by_outline),
    Rule("named_workplace", "pre", named_workplace, _P + """
CONSTRUCT { ?person indoor:worksIn ?place } WHERE {
  ?person indoor:workplaceName ?n . ?place a indoor:Place ; indoor:name ?m .
  FILTER (UCASE(REPLACE(?n, "[^A-Za-z0-9]", "")) = UCASE(REPLACE(?m, "[^A-Za-z0-9]", ""))) }"""),
    Rule("role_workplace", "pre", role_workplace, _P + """
CONSTRUCT { ?person indoor:worksIn ?place } WHERE {
  ?person indoor:hasRole ?role . ?role indoor:workplaceKind ?kind . ?place a ?kind .
  FILTER NOT EXISTS { ?person indoor:workplaceName ?n } }"""),
    Rule("slot_place", "pre", slot_place, _P + """
CONSTRUCT { ?slot indoor:place ?place } WHERE {
  ?slot a indoor:Slot ; indoor:placeName ?n . ?place a indoor:Place ; indoor:name ?m .
  FILTER (UCASE(REPLACE(?n, "[^A-Za-z0-9]", "")) = UCASE(REPLACE(?m, "[^A-Za-z0-9]", ""))) }"""),
)
POST_RULES: tuple[Rule, ...] = (
    Rule("connectivity", "post", connectivity),
    Rule("default_equipment", "post", default_equipment, _P + """
CONSTRUCT { ?place indoor:hasDefaultEquipment ?eq } WHERE {
  ?place a indoor:Place ; indoor:hasFunction ?f . ?f indoor:defaultEquipment ?eq .
  FILTER NOT EXISTS { ?seen a ?eq ; indoor:source "observed" } }"""),
    Rule("object_belongs", "post", object_belongs, _P + """
CONSTRUCT { ?cls indoor:belongsIn ?place } WHERE {
  ?cls indoor:belongsInKind ?kind . ?place a ?kind , indoor:Place }"""),
    Rule("owner_belongs", "post", owner_belongs),
)
