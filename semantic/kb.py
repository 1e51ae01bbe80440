"""The semantic map's knowledge base: the indoor ontology plus what the robot found.

The paper's "indoor ontology models and reasoning engine" (section 2.4):
places, doors and signs found on the map, objects seen, people from a
timetable, all stated in the ontology's terms (``semantic/ontology/indoor.ttl``)
and reasoned over, so questions a task planner asks ("where is the shredder",
"where is Dr Lovelace at 10:00 on Monday", "is the lab reachable from the
lobby") have answers.

Reasoning (:meth:`KnowledgeBase.reason`) has three steps, recomputed from the
asserted facts every time so retractions and overrides stay right:

1. *pre rules* (:data:`semantic.rules.PRE_RULES`) on the asserted facts: signs
   type their rooms, doors make places adjacent, people get workplaces;
2. the OWL 2 RL pass by ``reasonable`` over the ontology's axioms and the
   facts (:class:`OwlPass`: the previous closure again when the axioms and facts
   are those of the previous pass, incremental when facts were only added);
3. *post rules* (:data:`semantic.rules.POST_RULES`) on the closure:
   connectivity, default equipment (observed objects take precedence), where
   objects belong. OWL + rules iterate if a rule feeds the reasoner.

The query methods read the result through an index (microseconds); the full
rdflib graph for SPARQL (:meth:`query`) and :meth:`serialize` is built on
demand. A query on a KB changed since the last pass reasons first.

Ids given by the caller ("P3", "door_2", "sign_0") become ``map:`` IRIs
(``https://w3id.org/semmap/map#P3``); answers give them back as plain strings.
"""
from __future__ import annotations

import functools

import datetime as dt
import re
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import networkx as nx
import numpy as np
import rdflib
from rdflib import OWL, RDF, RDFS, XSD, Literal, URIRef
from rdflib.compare import to_canonical_graph
from rdflib.namespace import SKOS

from blocks.core.atomic import atomic_write_text
from blocks.core.errors import SemmapError
from semantic import rules as R
from semantic.lexicon import Concept, build_lexicon
from semantic.rules import INDOOR, MAP, Facts, RuleContext, TBox
from semantic.timetable import DAYS, Slot, Timetable
from semantic.vocabulary import Vocabulary, compact, load_vocabulary

__all__ = ["DEFAULT_ONTOLOGY", "INDOOR", "MAP", "KnowledgeBase", "KnowledgeBaseError",
           "OntologyError", "OwlClosure", "OwlPass", "ReasoningStats", "load_ontology"]

DEFAULT_ONTOLOGY = Path(__file__).with_name("ontology") / "indoor.ttl"
#: Names the rules and queries rely on; a swapped-in ontology must define them.
REQUIRED = ("Place", "Room", "Door", "Sign", "Function", "Role", "Person", "Equipment",
            "PortableObject", "PhysicalObject", "Slot")
#: Ontology triples the OWL pass does not need: annotations read by the rules from the
#: ontology itself, labels, and connectedTo's transitivity (computed by networkx instead,
#: see semantic.rules.connectivity).
_NOT_FOR_OWL = {RDFS.label, SKOS.altLabel, RDFS.comment, OWL.versionInfo, INDOOR.defaultEquipment,
                INDOOR.workplaceKind, INDOOR.belongsInKind, INDOOR.belongsWithOwner}
_MAX_OWL_ROUNDS = 4
_MAP_STR = str(MAP)


class OntologyError(SemmapError):
    """The ontology file is missing, unreadable or lacks the names the KB needs."""


class KnowledgeBaseError(SemmapError):
    """A fact given to the knowledge base names something the ontology does not know."""


@dataclass(frozen=True)
class ReasoningStats:
    """Timing and size of one reasoning pass (milliseconds, triple counts)."""

    ms_owl: float
    ms_rules: float
    triples_before: int
    triples_after: int
    owl_rounds: int = 1
    incremental: bool = False

    @property
    def ms_total(self) -> float:
        return self.ms_owl + self.ms_rules


def _mtime(path: Path) -> float:
    """The file's modification time (0 when missing: load_ontology then reports it)."""
    try:
        return path.stat().st_mtime
    except OSError:
        return 0.0


@functools.lru_cache(maxsize=8)
def _ontology_parts(path: str, mtime: float) -> tuple:
    """What a knowledge base derives from its ontology, parsed and indexed once per file
    version: parsing and indexing take ~140 ms, and the live knowledge block builds a
    fresh base for every new sign. The parts are only ever read."""
    del mtime  # part of the cache key: an edited file is read again
    ontology = load_ontology(path)
    owl_tbox = [t for t in ontology
                if t[1] not in _NOT_FOR_OWL and not isinstance(t[2], Literal)
                and t != (INDOOR.connectedTo, RDF.type, OWL.TransitiveProperty)]
    return ontology, TBox(ontology), build_lexicon(ontology), owl_tbox, frozenset(ontology)


def load_ontology(path: str | Path | None = None) -> rdflib.Graph:
    """Parse an ontology file (Turtle, or any format rdflib guesses from the suffix).

    Raises
    ------
    OntologyError
        Missing file, syntax error (with the line rdflib reports), or a
        required ``indoor:`` class missing.
    """
    path = Path(path) if path is not None else DEFAULT_ONTOLOGY
    fix = ("Give the path of a Turtle ontology using the indoor: names of "
           "semantic/ontology/indoor.ttl, or none for that packaged file.")
    if not path.is_file():
        raise OntologyError("ontology file not found", file=path, hint=fix)
    fmt = rdflib.util.guess_format(str(path)) or "turtle"
    graph = rdflib.Graph()
    try:
        graph.parse(str(path), format=fmt)
    except SyntaxError as exc:  # rdflib's BadSyntax
        why = getattr(exc, "_why", None) or str(exc).split("\n", 1)[0]
        raise OntologyError(f"{fmt} syntax error: {why}", file=path, line=_bad_syntax_line(exc),
                            hint="Fix the statement on that line (each ends with ' .', "
                                 "lists with ' ,' and ' ;'; prefixes must be declared).") from None
    except Exception as exc:  # noqa: BLE001 - any parser failure is the file's fault
        m = re.search(r"line (\d+)", str(exc))
        raise OntologyError(f"cannot parse the ontology as {fmt}: "
                            f"{str(exc).splitlines()[0] if str(exc) else type(exc).__name__}",
                            file=path, line=int(m.group(1)) if m else None, hint=fix) from None
    missing = [n for n in REQUIRED if (INDOOR[n], None, None) not in graph]
    if missing:
        raise OntologyError(f"the ontology does not define indoor:{', indoor:'.join(missing)} "
                            f"(namespace {INDOOR})", file=path, hint=fix)
    return graph


def _bad_syntax_line(exc: BaseException) -> int | None:
    """The 1-based line of an rdflib BadSyntax: counted from its text and offset, which is
    more reliable than its ``lines`` attribute (off at the end of the file)."""
    text, at = getattr(exc, "_str", None), getattr(exc, "_i", None)
    if isinstance(text, (bytes, str)) and isinstance(at, int):
        newline = b"\n" if isinstance(text, bytes) else "\n"
        return text[:at].count(newline) + 1
    lines = getattr(exc, "lines", None)
    return lines + 1 if isinstance(lines, int) else None


def _local(term: Any) -> str:
    text = str(term)
    return text.rsplit("#", 1)[-1].rsplit("/", 1)[-1]


def _slug(text: str) -> str:
    return re.sub(r"[^A-Za-z0-9]+", "_", text).strip("_") or "x"


def _parse_wkt(text: str) -> np.ndarray | None:
    """The outline of a ``POLYGON ((x y, ...))`` written by :func:`_wkt` (None if not one)."""
    m = re.fullmatch(r"\s*POLYGON\s*\(\((.*)\)\)\s*", text)
    if m is None:
        return None
    try:
        pts = np.array([[float(v) for v in pair.split()] for pair in m.group(1).split(",")])
    except ValueError:
        return None
    if pts.ndim != 2 or pts.shape[1] != 2 or len(pts) < 4:
        return None
    return pts[:-1] if np.allclose(pts[0], pts[-1]) else pts


def _slot_order(iri: Any) -> tuple[int, str]:
    """``map:slot_10`` after ``map:slot_9``: slots are consulted in timetable order."""
    m = re.search(r"(\d+)$", str(iri))
    return (int(m.group(1)) if m else 0, str(iri))


def _wkt(polygon: np.ndarray) -> str:
    pts = [(float(x), float(y)) for x, y in np.asarray(polygon, float)]
    if pts and pts[0] != pts[-1]:
        pts.append(pts[0])
    return "POLYGON ((" + ", ".join(f"{x:.6g} {y:.6g}" for x, y in pts) + "))"


@dataclass(frozen=True)
class OwlClosure:
    """What an OWL pass derived, split the way the knowledge base reads it.

    Attributes
    ----------
    on_map : tuple
        The triples about map individuals (subjects in the ``map:`` namespace):
        the rules index these.
    off_map : tuple
        The rest, the ontology's own closure: it goes to the graph untouched.
    """

    on_map: tuple
    off_map: tuple
    _with: dict = field(default_factory=dict, repr=False, compare=False)

    def with_ontology(self, ontology: frozenset) -> frozenset:
        """The ontology's triples and :attr:`off_map` as one set (kept per ontology: the
        closure's terms are new objects, so the union compares them one by one)."""
        key = id(ontology)
        if key not in self._with:
            self._with[key] = (ontology, ontology.union(self.off_map))
        return self._with[key][1]


class OwlPass:
    """The OWL 2 RL pass by ``reasonable``, kept between reasonings.

    Its closure is a function of the set of triples it is given alone (the
    least fixpoint of the OWL 2 RL rules), so a pass given

    - the same triples as last time gives the last closure again, without reasoning;
    - a superset of them loads only the new triples into the reasoner, which
      carries on from its closure (incremental materialisation: the same set);
    - anything else (a fact was retracted) starts a new reasoner from scratch.

    One knowledge base keeps one (facts added after :meth:`KnowledgeBase.reason`
    reason incrementally); the live knowledge block, which builds a fresh base for
    every new sign or object, hands the previous base's pass on, so an update that
    only moves an object (literals, which the OWL pass is not given) costs no OWL
    reasoning at all.

    Attributes
    ----------
    input : frozenset
        The triples the last pass was given (empty before the first).
    """

    def __init__(self) -> None:
        self._reasoner: Any = None
        self._closure: OwlClosure | None = None
        self.input: frozenset = frozenset()

    def close(self, axioms: Iterable[tuple], facts: Iterable[tuple]) -> tuple[OwlClosure, bool]:
        """The OWL closure of ``axioms`` and ``facts`` (no literals: OWL RL ignores them here).

        Returns
        -------
        closure : OwlClosure
        incremental : bool
            False when the reasoner started from scratch.
        """
        import reasonable
        want = frozenset(axioms).union(facts)
        if self._closure is not None and want == self.input:
            return self._closure, True
        if self._reasoner is not None and want >= self.input:
            self._reasoner.from_graph(list(want - self.input))
            incremental = True
        else:
            self._reasoner = reasonable.PyReasoner()
            self._reasoner.from_graph(list(want))
            incremental = False
        try:
            closure = self._reasoner.reason()
        except BaseException:  # the next pass starts afresh, not from a half-loaded reasoner
            self._reasoner, self.input, self._closure = None, frozenset(), None
            raise
        self.input = want
        self._closure = OwlClosure(
            on_map=tuple(t for t in closure if t[0].startswith(_MAP_STR)),
            off_map=tuple(t for t in closure if not t[0].startswith(_MAP_STR)))
        return self._closure, incremental


class KnowledgeBase:
    """The indoor ontology, the map's facts, and the reasoning over both.

    Parameters
    ----------
    ontology : str or Path, optional
        A Turtle ontology using the ``indoor:`` names (default: the packaged
        ``semantic/ontology/indoor.ttl``).
    vocabulary : Vocabulary, optional
        The sign vocabulary, to classify sign texts (default: the packaged one).
    owl : OwlPass, optional
        The OWL pass to reason with (default: a new one). A caller that builds a
        fresh knowledge base for every update passes the previous base's
        :attr:`owl` on: the OWL closure then follows the facts incrementally,
        with the same result as from scratch (see :class:`OwlPass`).
    """

    def __init__(self, ontology: str | Path | None = None,
                 vocabulary: Vocabulary | None = None, owl: OwlPass | None = None) -> None:
        self.ontology_path = Path(ontology) if ontology is not None else DEFAULT_ONTOLOGY
        parts = _ontology_parts(str(self.ontology_path.resolve()), _mtime(self.ontology_path))
        self.ontology, self.tbox, self.lexicon, self._owl_tbox, self._ontology_set = parts
        self.vocabulary = vocabulary if vocabulary is not None else load_vocabulary()
        self._abox: set[tuple] = set()  # asserted map facts
        self._about: dict[Any, set[tuple]] = {}  # the same, by subject (replacing an id)
        self._polygons: dict[URIRef, np.ndarray] = {}
        self._slots: list[tuple[URIRef, URIRef, Any]] = []  # (slot, person, timetable Slot)
        self.owl = owl if owl is not None else OwlPass()
        self._facts: Facts | None = None
        self._graph: rdflib.Graph | None = None
        self._ctx: RuleContext | None = None
        self._tbox_closure: tuple = ()
        self.stats: ReasoningStats | None = None

    @property
    def _reasoner_input(self) -> frozenset:
        """What the last OWL pass was given: the ontology's axioms and the facts."""
        return self.owl.input

    # ---- asserting facts -------------------------------------------------------------------------
    def _iri(self, ident: str) -> URIRef:
        if not isinstance(ident, str) or not ident.strip():
            raise KnowledgeBaseError(f"an id must be a non-empty string, got {ident!r}")
        return MAP[_slug(ident)] if not re.fullmatch(r"[A-Za-z0-9_\-]+", ident) else MAP[ident]

    def _changed(self) -> None:
        self._facts = None
        self._graph = None

    def _forget(self, subject: URIRef) -> None:
        """Drop every asserted fact about ``subject`` (re-adding an id replaces it)."""
        self._abox -= self._about.pop(subject, set())
        self._polygons.pop(subject, None)

    def _assert(self, *triples: tuple) -> None:
        self._abox.update(triples)
        for t in triples:
            self._about.setdefault(t[0], set()).add(t)
        self._changed()

    def _class(self, name: str, kinds: set[str], what: str) -> URIRef:
        """The ontology class a kind/label names: a local name, or a label the lexicon knows."""
        iri = INDOOR[name] if re.fullmatch(r"[A-Za-z][A-Za-z0-9]*", str(name)) else None
        if iri is not None and (iri, RDF.type, OWL.Class) in self.ontology:
            ok = ("place" in kinds and self.tbox.is_sub(iri, INDOOR.Place)) or (
                kinds & {"equipment", "object"} and self.tbox.is_sub(iri, INDOOR.PhysicalObject))
            if ok:
                return iri
        near = self.lexicon.resolve(str(name), kinds=kinds)
        if near is not None and near.score >= 0.95:  # a label or word form, not a near miss
            return URIRef(near.iri)
        hint = (f"Did you mean {near.local_name!r}?" if near is not None else
                f"Use a class of {self.ontology_path.name} (e.g. "
                f"{'MailRoom, Corridor' if 'place' in kinds else 'Shredder, Laptop'}).")
        raise KnowledgeBaseError(f"{what} {name!r} is not a {'/'.join(sorted(kinds))} class of "
                                 "the ontology", file=self.ontology_path, hint=hint)

    def _ensure_place(self, place: URIRef) -> None:
        if not any(t[1] == RDF.type for t in self._about.get(place, ())):
            self._assert((place, RDF.type, INDOOR.Place))

    def add_place(self, place_id: str, kind: str | None = None, *, name: str | None = None,
                  centroid: tuple[float, float] | None = None, polygon: Any = None,
                  area: float | None = None) -> str:
        """Add (or replace) a place.

        Parameters
        ----------
        place_id : str
        kind : str, optional
            An ontology place class (``"MailRoom"``, ``"Corridor"``) or its
            English label (``"mail room"``); None for a place of unknown kind
            (``indoor:Place``; a sign may make it more specific).
        name : str, optional
            Its name, usually the sign text ("OFFICE 101").
        centroid : (x, y), optional
            Map frame, metres; computed from ``polygon`` when omitted.
        polygon : (N, 2) array, optional
            The outline, map frame.
        area : float, optional
            Square metres; computed from ``polygon`` when omitted.

        Returns
        -------
        str
            The place's IRI.
        """
        p = self._iri(place_id)
        cls = INDOOR.Place if kind is None else self._class(kind, {"place"}, "place kind")
        self._forget(p)
        facts = [(p, RDF.type, cls)]
        if name:
            facts.append((p, INDOOR.name, Literal(" ".join(str(name).split()))))
        if polygon is not None:
            poly = np.asarray(polygon, float).reshape(-1, 2)
            if len(poly) >= 3:
                self._polygons[p] = poly
                facts.append((p, INDOOR.polygon, Literal(_wkt(poly))))
                if centroid is None:
                    centroid = (float(poly[:, 0].mean()), float(poly[:, 1].mean()))
                if area is None:
                    area = R._area(poly)
        if centroid is not None:
            facts += [(p, INDOOR.x, Literal(float(centroid[0]), datatype=XSD.double)),
                      (p, INDOOR.y, Literal(float(centroid[1]), datatype=XSD.double))]
        if area is not None:
            facts.append((p, INDOOR.area, Literal(float(area), datatype=XSD.double)))
        self._assert(*facts)
        return str(p)

    def add_door(self, door_id: str, a: str, b: str, *, x: float, y: float,
                 width: float) -> str:
        """Add (or replace) a door or opening joining places ``a`` and ``b`` (ids).

        Places not added yet are created as places of unknown kind.
        """
        d, pa, pb = self._iri(door_id), self._iri(a), self._iri(b)
        self._forget(d)
        self._ensure_place(pa)
        self._ensure_place(pb)
        self._assert((d, RDF.type, INDOOR.Door), (d, INDOOR.connects, pa),
                     (d, INDOOR.connects, pb),
                     (d, INDOOR.x, Literal(float(x), datatype=XSD.double)),
                     (d, INDOOR.y, Literal(float(y), datatype=XSD.double)),
                     (d, INDOOR.width, Literal(float(width), datatype=XSD.double)))
        return str(d)

    def add_sign(self, sign_id: str, text: str, *, x: float, y: float, facing_deg: float = 0.0,
                 place_id: str | None = None, place_class: str | None = None) -> str:
        """Add (or replace) a sign read at (x, y), labelling ``place_id`` if known.

        ``place_class`` defaults to the class the vocabulary gives the text
        ("MANAGER" -> ManagerOffice), else the lexicon's best place label; a
        text naming no place class still records the sign.
        """
        s = self._iri(sign_id)
        text = " ".join(str(text).split())
        if place_class is None:
            concept = self.lexicon.resolve_sign(text, self.vocabulary)
            cls = URIRef(concept.iri) if concept is not None else None
            if cls is not None and cls not in self.tbox.place_classes:
                cls = None
        else:
            cls = self._class(place_class, {"place"}, "sign place class")
        self._forget(s)
        facts = [(s, RDF.type, INDOOR.Sign), (s, INDOOR.text, Literal(text)),
                 (s, INDOOR.x, Literal(float(x), datatype=XSD.double)),
                 (s, INDOOR.y, Literal(float(y), datatype=XSD.double)),
                 (s, INDOOR.facingDeg, Literal(float(facing_deg), datatype=XSD.double))]
        if cls is not None:
            facts.append((s, INDOOR.signClass, cls))
        if place_id is not None:
            p = self._iri(place_id)
            self._ensure_place(p)
            facts.append((s, INDOOR.labels, p))
        self._assert(*facts)
        return str(s)

    def add_object(self, obj_id: str, label: str, *, x: float, y: float,
                   place_id: str | None = None, observed: bool = True,
                   owner: str | None = None) -> str:
        """Add (or replace) an object: equipment or a portable object.

        Parameters
        ----------
        label : str
            Its class (``"Shredder"``) or an English name ("paper shredder").
        place_id : str, optional
            The place it is in; when None, the place whose outline holds (x, y).
        observed : bool
            Seen by the robot (``indoor:source "observed"``: overrides defaults)
            or only assumed (``"default"``).
        owner : str, optional
            A person's name, a role or a place name ("manager", "ADMIN"): the
            object belongs at the owner's workplace.
        """
        o = self._iri(obj_id)
        cls = self._class(label, {"equipment", "object"}, "object label")
        self._forget(o)
        facts = [(o, RDF.type, cls), (o, INDOOR.source, R.OBSERVED if observed else R.DEFAULT),
                 (o, INDOOR.x, Literal(float(x), datatype=XSD.double)),
                 (o, INDOOR.y, Literal(float(y), datatype=XSD.double))]
        if place_id is not None:
            p = self._iri(place_id)
            self._ensure_place(p)
            facts.append((o, INDOOR.locatedIn, p))
        if owner:
            facts.append((o, INDOOR.ownerName, Literal(" ".join(str(owner).split()))))
        self._assert(*facts)
        return str(o)

    def add_timetable(self, tt: Timetable) -> None:
        """Add a timetable's people (with roles and workplaces) and weekly slots.

        Raises
        ------
        KnowledgeBaseError
            A person's role is not a role of the ontology (names the file and line).
        """
        roles = {_local(r): r for r in self.tbox.facts.subjects(RDF.type, INDOOR.Role)}
        people: dict[str, URIRef] = {}
        facts: list[tuple] = []
        for person in tt.people:
            iri = MAP[f"person_{_slug(person.name)}"]
            people[person.name] = iri
            facts += [(iri, RDF.type, INDOOR.Person), (iri, INDOOR.name, Literal(person.name))]
            if person.role is not None:
                role = roles.get(person.role)
                if role is None:
                    concept = self.lexicon.resolve(person.role, kinds={"role"})
                    raise KnowledgeBaseError(
                        f"person {person.name!r} has role {person.role!r}, which is not a role "
                        f"of the ontology {self.ontology_path.name}", file=tt.source,
                        line=person.line, field="role",
                        hint=(f"Did you mean {concept.local_name!r}?" if concept else
                              f"Known roles: {', '.join(sorted(roles))}."))
                facts.append((iri, INDOOR.hasRole, role))
            if person.workplace:
                facts.append((iri, INDOOR.workplaceName, Literal(person.workplace)))
        start = len(self._slots)
        for k, slot in enumerate(tt.slots):
            s = MAP[f"slot_{start + k}"]
            person = people[slot.person]
            self._slots.append((s, person, slot))
            facts += [(s, RDF.type, INDOOR.Slot), (s, INDOOR.person, person),
                      (s, INDOOR.placeName, Literal(slot.place)),
                      (s, INDOOR.startTime, Literal(slot.start.strftime("%H:%M:%S"),
                                                    datatype=XSD.time)),
                      (s, INDOOR.endTime, Literal(slot.end.strftime("%H:%M:%S"),
                                                  datatype=XSD.time))]
            facts += [(s, INDOOR.dayOfWeek, Literal(day)) for day in slot.days]
            if slot.subject:
                facts.append((s, INDOOR.subject, Literal(slot.subject)))
        self._assert(*facts)

    @classmethod
    def from_world(cls, world: Any, *, timetable: Timetable | None = None,
                   ontology: str | Path | None = None) -> KnowledgeBase:
        """A KB of a sim2d world's ground truth: places (ids P0, P1, ... named by their
        sign texts), doors, signs (on the place of the same name), objects, timetable."""
        from semantic.timetable import load_timetable
        kb = cls(ontology)
        ids: dict[str, str] = {}
        for i, place in enumerate(getattr(world, "places", [])):
            ids[place.name] = f"P{i}"
            kb.add_place(f"P{i}", place.kind, name=place.name, polygon=place.polygon)
        for i, door in enumerate(getattr(world, "doors", [])):
            a, b = (ids.get(n, _slug(n)) for n in door.between)
            kb.add_door(f"door_{i}", a, b, x=door.x, y=door.y, width=door.width)
        for i, sign in enumerate(world.signs):
            kb.add_sign(f"sign_{i}", sign.text, x=sign.x, y=sign.y,
                        facing_deg=float(np.degrees(sign.facing)), place_id=ids.get(sign.text))
        for i, obj in enumerate(getattr(world, "objects", [])):
            kb.add_object(f"obj_{i}", obj.label, x=obj.x, y=obj.y)
        if timetable is None and getattr(world, "timetable", None) is not None:
            timetable = load_timetable(world.timetable)
        if timetable is not None:
            kb.add_timetable(timetable)
        return kb

    @classmethod
    def load(cls, path: str | Path, *, ontology: str | Path | None = None,
             vocabulary: Vocabulary | None = None) -> KnowledgeBase:
        """The KB a semantic mapping run wrote (:meth:`serialize`), ready to query.

        The file's map facts (every subject in the ``map:`` namespace, asserted or
        inferred) become this KB's facts, with the outlines and timetable slots
        the queries need, and are reasoned over again with ``ontology`` (default:
        the packaged one). Reasoning is monotone over a closure, so the answers
        are those of the run that wrote the file.

        Raises
        ------
        KnowledgeBaseError
            The file is missing or is not Turtle (names the file and line).
        """
        path = Path(path)
        g = rdflib.Graph()
        try:
            g.parse(path, format="turtle")
        except FileNotFoundError:
            raise KnowledgeBaseError("the semantic map file does not exist", file=path,
                                     hint="Give the output folder of a semantic mapping run "
                                          "(it holds semantic_map.ttl).") from None
        except Exception as exc:  # noqa: BLE001 - rdflib raises many kinds on bad input
            raise KnowledgeBaseError(f"the semantic map is not valid Turtle: "
                                     f"{str(exc).splitlines()[0]}", file=path,
                                     line=_bad_syntax_line(exc),
                                     hint="Re-run the semantic mapping to write it again.") from None
        kb = cls(ontology, vocabulary=vocabulary)
        facts = {t for t in g if str(t[0]).startswith(_MAP_STR)}
        kb._assert(*facts)
        for s, wkt in ((t[0], t[2]) for t in facts if t[1] == INDOOR.polygon):
            poly = _parse_wkt(str(wkt))
            if poly is not None:
                kb._polygons[s] = poly
        names = {s: str(o) for s, p, o in facts if p == INDOOR.name}
        for slot in sorted((t[0] for t in facts if t[1] == RDF.type and t[2] == INDOOR.Slot),
                           key=_slot_order):
            one = {p: o for s2, p, o in facts if s2 == slot and p != INDOOR.dayOfWeek}
            person = one.get(INDOOR.person)
            try:
                start = dt.time.fromisoformat(str(one[INDOOR.startTime]))
                end = dt.time.fromisoformat(str(one[INDOOR.endTime]))
            except (KeyError, ValueError):
                continue  # not a slot this KB wrote
            days = tuple(sorted((str(o) for s2, p, o in facts
                                 if s2 == slot and p == INDOOR.dayOfWeek), key=DAYS.index))
            subject = one.get(INDOOR.subject)
            kb._slots.append((slot, person, Slot(names.get(person, str(person)),
                                                 str(one.get(INDOOR.placeName, "")), days,
                                                 start, end, str(subject) if subject else None)))
        kb._changed()
        return kb

    # ---- reasoning -------------------------------------------------------------------------------
    def reason(self) -> ReasoningStats:
        """Materialise the ontology's and the rules' consequences (see the module docstring).

        Returns
        -------
        ReasoningStats
            ``ms_owl`` (the reasonable passes, with loading their input),
            ``ms_rules`` (pre and post rules, indexing), triple counts.
        """
        t0 = time.perf_counter()
        ctx = RuleContext(tbox=self.tbox, polygons=dict(self._polygons), lexicon=self.lexicon)
        asserted = Facts(self._abox)
        R.run_rules(R.PRE_RULES, asserted, ctx)
        ms_rules = (time.perf_counter() - t0) * 1e3
        ms_owl = 0.0
        literals = [t for t in asserted.triples if isinstance(t[2], Literal)]
        feed = {t for t in asserted.triples if not isinstance(t[2], Literal)}
        rounds, incremental = 0, False
        while True:
            rounds += 1
            t1 = time.perf_counter()
            closure, incremental = self.owl.close(self._owl_tbox, feed)
            t2 = time.perf_counter()
            ms_owl += (t2 - t1) * 1e3
            # The rules read the ontology from self.tbox; index only the facts about map
            # individuals (the closure's ontology part goes to the graph untouched).
            facts = Facts([*closure.on_map, *literals])
            derived = R.run_rules(R.POST_RULES, facts, ctx)
            ms_rules += (time.perf_counter() - t2) * 1e3
            fed = {t for rule in R.POST_RULES if rule.feeds_owl for t in derived[rule.name]
                   if not isinstance(t[2], Literal)}
            if not fed - feed or rounds >= _MAX_OWL_ROUNDS:
                break
            feed |= fed
        self._facts, self._ctx, self._graph = facts, ctx, None
        self._tbox_closure = closure.off_map
        before = len(self.ontology) + len(self._abox)
        base = closure.with_ontology(self._ontology_set)
        after = len(base) + sum(1 for t in facts.triples if t not in base)
        self.stats = ReasoningStats(ms_owl=ms_owl, ms_rules=ms_rules, triples_before=before,
                                    triples_after=after, owl_rounds=rounds,
                                    incremental=incremental)
        return self.stats


    @property
    def facts(self) -> Facts:
        """The materialised facts (reasoning first if anything changed)."""
        if self._facts is None:
            self.reason()
        assert self._facts is not None
        return self._facts

    @property
    def graph(self) -> rdflib.Graph:
        """The whole materialised KB as an rdflib graph: ontology, map facts, inferences."""
        facts = self.facts
        if self._graph is None:
            g = rdflib.Graph()
            for prefix, ns in (("indoor", INDOOR), ("map", MAP), ("skos", SKOS), ("owl", OWL),
                               ("xsd", XSD)):
                g.bind(prefix, ns)
            g.addN((s, p, o, g) for s, p, o in self.ontology)
            g.addN((s, p, o, g) for s, p, o in self._tbox_closure)
            g.addN((s, p, o, g) for s, p, o in facts.triples)
            self._graph = g
        return self._graph

    # ---- queries ---------------------------------------------------------------------------------
    def query(self, sparql: str) -> list[dict[str, str]]:
        """Run a SPARQL SELECT (prefixes indoor, map, rdf, rdfs, owl, skos, xsd predeclared).

        Returns rows as dicts of variable name -> value as a string (unbound
        variables left out). ASK gives ``[{"ask": "true"|"false"}]``.
        """
        ns = {"indoor": INDOOR, "map": MAP, "rdf": RDF, "rdfs": RDFS, "owl": OWL, "skos": SKOS,
              "xsd": XSD}
        try:
            result = self.graph.query(sparql, initNs=ns)
        except Exception as exc:  # noqa: BLE001 - a bad query is the caller's mistake
            raise KnowledgeBaseError(f"SPARQL query failed: {str(exc).splitlines()[0]}",
                                     hint="Check the query's syntax and prefixes.") from None
        if result.type == "ASK":
            return [{"ask": "true" if result.askAnswer else "false"}]
        rows = []
        for row in result:
            rows.append({str(v): str(row[v]) for v in result.vars if row[v] is not None})
        return rows

    def _id(self, term: Any) -> str:
        text = str(term)
        return text[len(str(MAP)):] if text.startswith(str(MAP)) else _local(text)

    def place_kind(self, place_id: str) -> str | None:
        """The most specific place class of a place (local name), or None if unknown."""
        p = self._iri(place_id)
        kinds = [t for t in self.facts.objects(p, RDF.type) if t in self.tbox.place_classes]
        if not kinds:
            return None
        return _local(max(kinds, key=lambda c: (self.tbox.depth(c), str(c))))

    def place_functions(self, place_id: str) -> list[str]:
        """The functions of a place (local names, sorted)."""
        return sorted(_local(f) for f in self.facts.objects(self._iri(place_id),
                                                            INDOOR.hasFunction))

    def _most_specific(self, individual: Any, top: Any) -> Any:
        types = [t for t in self.facts.objects(individual, RDF.type)
                 if isinstance(t, URIRef) and self.tbox.is_sub(t, top) and t != top]
        return max(types, key=lambda c: (self.tbox.depth(c), str(c))) if types else None

    def equipment_in(self, place_id: str) -> list[tuple[str, str]]:
        """What a place holds: ``(class, "observed")`` for objects seen there (and
        ``"default"`` for objects added as not observed), then its default equipment
        ``(class, "default")`` that is not overridden by an observation."""
        facts = self.facts
        p = self._iri(place_id)
        out: list[tuple[str, str]] = []
        for obj in sorted(facts.subjects(INDOOR.locatedIn, p), key=str):
            cls = self._most_specific(obj, INDOOR.PhysicalObject)
            if cls is None:
                continue
            src = "observed" if R.OBSERVED in facts.objects(obj, INDOOR.source) else "default"
            out.append((_local(cls), src))
        for eq in sorted(facts.objects(p, INDOOR.hasDefaultEquipment), key=str):
            if (_local(eq), "observed") not in out and (_local(eq), "default") not in out:
                out.append((_local(eq), "default"))
        return out

    def _people(self, text: str) -> tuple[list[URIRef], Concept | None]:
        """People a text names: a person's name, or a role (everyone with it)."""
        facts = self.facts
        key = compact(text)
        named = sorted((p for p in facts.subjects(RDF.type, INDOOR.Person)
                        if any(compact(str(n)) == key for n in facts.objects(p, INDOOR.name))
                        and R.DEFAULT not in facts.objects(p, INDOOR.source)), key=str)
        if named:
            return named, None
        concept = self.lexicon.resolve(text)  # any kind: "research" is a function, not a role
        if concept is None or concept.kind != "role":
            return [], None
        return sorted(facts.subjects(INDOOR.hasRole, URIRef(concept.iri)), key=str), concept

    def _concept(self, text: str) -> Concept | None:
        concept = self.lexicon.resolve(text)
        return concept

    def where_is(self, concept: str) -> list[tuple[str, str]]:
        """Where to find something: ``(place_id, how)`` pairs, best first.

        For an object or equipment class (or English name): places where one
        was ``"observed"``; only when none was, its ``"default"`` places (from
        room functions, and objects added as not observed); then the places it
        ``"belongs"`` in. For a person's name or a role: where they ``"works"``.
        For a place class: the places of that ``"kind"``; for a function, the
        places with that ``"function"``. Unknown: an empty list.
        """
        facts = self.facts
        out: dict[str, str] = {}

        def put(places: Iterable[Any], how: str) -> None:
            for p in sorted(places, key=str):
                out.setdefault(self._id(p), how)

        people, _ = self._people(concept)
        if people:
            for person in people:
                put(facts.objects(person, INDOOR.worksIn), "works")
            return list(out.items())
        c = self._concept(concept)
        if c is None:
            return []
        iri = URIRef(c.iri)
        if c.kind in ("equipment", "object"):
            observed, assumed = [], []
            for obj in facts.subjects(RDF.type, iri):
                where = facts.objects(obj, INDOOR.locatedIn)
                (observed if R.OBSERVED in facts.objects(obj, INDOOR.source)
                 else assumed).extend(where)
            put(observed, "observed")
            if not observed:
                put(assumed, "default")
                put(facts.subjects(INDOOR.hasDefaultEquipment, iri), "default")
            put(facts.objects(iri, INDOOR.belongsIn), "belongs")
            for obj in sorted(facts.subjects(RDF.type, iri), key=str):
                put(facts.objects(obj, INDOOR.belongsIn), "belongs")
        elif c.kind == "role":
            return []  # a role nobody on the map has (no place of its kind)
        elif c.kind == "place":
            put(facts.subjects(RDF.type, iri) & self._ctx_places(), "kind")
        elif c.kind == "function":
            put(facts.subjects(INDOOR.hasFunction, iri), "function")
        return list(out.items())

    def _ctx_places(self) -> set:
        assert self._ctx is not None
        return self._ctx.places(self.facts)

    def who_works_in(self, place_id: str) -> list[str]:
        """The names of the people working in a place (a created role stand-in is named
        by its role, e.g. "Manager")."""
        facts = self.facts
        people = facts.subjects(INDOOR.worksIn, self._iri(place_id))
        return sorted(str(facts.one(p, INDOOR.name) or self._id(p)) for p in people)

    def works_in(self, role_or_person: str) -> list[str]:
        """The place ids where a person (by name) or the people of a role work."""
        people, _ = self._people(role_or_person)
        return sorted({self._id(p) for person in people
                       for p in self.facts.objects(person, INDOOR.worksIn)})

    def where_is_person_at(self, person_or_role: str, when: dt.datetime) -> str | None:
        """Where a person (or the first person of a role) is at ``when``.

        From the timetable: the map place id of the slot's place when the map
        has it, else the slot's place name as written ("LAB"); outside every
        slot, the person's workplace (place id); None when neither is known.
        """
        people, _ = self._people(person_or_role)
        facts = self.facts
        day = DAYS[when.weekday()]
        for person in people:
            for slot_iri, who, slot in self._slots:
                if who == person and day in slot.days and slot.holds(when):
                    places = sorted(facts.objects(slot_iri, INDOOR.place), key=str)
                    return self._id(places[0]) if places else slot.place
        for person in people:
            places = sorted(facts.objects(person, INDOOR.worksIn), key=str)
            if places:
                return self._id(places[0])
        return None

    def connected(self, a: str, b: str) -> bool:
        """Whether one can walk from place ``a`` to place ``b`` through doors."""
        self.facts  # noqa: B018 - reason if needed
        g = self._ctx.place_graph if self._ctx is not None else nx.Graph()
        pa, pb = self._iri(a), self._iri(b)
        return pa in g and pb in g and nx.has_path(g, pa, pb)

    def place_graph(self) -> nx.Graph:
        """The place graph: nodes are place ids (attributes ``kind``, ``name``, ``x``,
        ``y``), edges join places sharing a door (attribute ``doors``: door ids)."""
        facts = self.facts
        assert self._ctx is not None
        g = nx.Graph()
        for p in self._ctx.place_graph.nodes:
            pid = self._id(p)
            x, y = facts.one(p, INDOOR.x), facts.one(p, INDOOR.y)
            name = facts.one(p, INDOOR.name)
            g.add_node(pid, kind=self.place_kind(pid), name=str(name) if name else None,
                       x=float(x) if x is not None else None,
                       y=float(y) if y is not None else None)
        for a, b in self._ctx.place_graph.edges:
            doors = sorted(self._id(d) for d in facts.objects(a, INDOOR.hasDoor)
                           & facts.objects(b, INDOOR.hasDoor))
            g.add_edge(self._id(a), self._id(b), doors=doors)
        return g

    def polygon(self, place_id: str) -> np.ndarray | None:
        """A place's outline (N, 2), map frame, or None if it has none."""
        poly = self._polygons.get(self._iri(place_id))
        return None if poly is None else poly.copy()

    def people_names(self) -> list[str]:
        """The names of the people from the timetable (not the stand-ins made for roles)."""
        facts = self.facts
        return sorted(str(facts.one(p, INDOOR.name)) for p in facts.subjects(RDF.type, INDOOR.Person)
                      if R.DEFAULT not in facts.objects(p, INDOOR.source)
                      and facts.one(p, INDOOR.name) is not None)

    def people_named(self, text: str) -> list[str]:
        """The names of the people a text names: a person's name, or everyone with a role
        (a stand-in for a role nobody on the timetable has is named by the role)."""
        people, _ = self._people(text)
        return sorted(str(self.facts.one(p, INDOOR.name) or self._id(p)) for p in people)

    def door_position(self, door_id: str) -> tuple[float, float] | None:
        """A door's (x, y), map frame, or None."""
        d = self._iri(door_id)
        x, y = self.facts.one(d, INDOOR.x), self.facts.one(d, INDOOR.y)
        return (float(x), float(y)) if x is not None and y is not None else None

    def resolve(self, text: str) -> Concept | None:
        """The ontology concept an English word or phrase names (see semantic.lexicon)."""
        return self.lexicon.resolve(text)

    def resolve_sign(self, text: str) -> Concept | None:
        """The place class a sign text names, consistently with the sign vocabulary."""
        return self.lexicon.resolve_sign(text, self.vocabulary)

    # ---- output ----------------------------------------------------------------------------------
    def serialize(self, path: str | Path, format: str = "turtle",
                  inferred: bool = True) -> Path:
        """Write the KB (atomically): the ontology, the map facts with their map-frame
        geometry (indoor:x/y, indoor:polygon WKT, indoor:width, indoor:area) and, unless
        ``inferred`` is False, everything reasoning derived."""
        if inferred:
            g = self.graph
        else:
            g = rdflib.Graph()
            for prefix, ns in (("indoor", INDOOR), ("map", MAP), ("skos", SKOS)):
                g.bind(prefix, ns)
            g.addN((s, p, o, g) for s, p, o in self.ontology)
            g.addN((s, p, o, g) for s, p, o in self._abox)
        # blank nodes (the ontology's restrictions) get labels from their content, not
        # from a random id, so a seeded run writes the same file every time
        canonical = rdflib.Graph()
        for prefix, ns in g.namespaces():
            canonical.bind(prefix, ns, override=True, replace=True)
        canonical += to_canonical_graph(g)
        path = Path(path)
        atomic_write_text(path, canonical.serialize(format=format))
        return path
