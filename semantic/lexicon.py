"""Words to concepts: English labels and synonyms of the ontology, and sign texts.

A user says "fetch the boss's laptop" and a sign reads "MAIL ROOM"; the
planner needs ``indoor:Manager``, ``indoor:Laptop`` and ``indoor:MailRoom``.
This module indexes the ontology's ``rdfs:label`` and ``skos:altLabel``
(lower case English, one concept per label) and resolves text in three steps:

1. exact: the normalised text is a label ("mail room", "boss");
2. word forms: possessives and plurals stripped ("manager's" -> "manager",
   "books" -> "book", "libraries" -> "library", "mail rooms" -> "mail room");
3. near miss: rapidfuzz ratio >= :data:`FUZZY_CUTOFF` against labels of at
   least :data:`FUZZY_MIN_LEN` letters. Short words are never matched fuzzily:
   one wrong letter in "lab" could be "lap", "tab" or "cab", so short words
   must be exact.

Sign texts go through :func:`resolve_sign`, which asks the place vocabulary
(:mod:`semantic.vocabulary`) first, so a sign and the sign reader always agree
on the place class ("MANAGER" on a door is the manager's office, while the
English word "manager" is the role).
"""
from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass

import rdflib
from rapidfuzz import fuzz, process
from rdflib.namespace import RDF, RDFS, SKOS

__all__ = ["Concept", "Lexicon", "INDOOR", "FUZZY_CUTOFF", "FUZZY_MIN_LEN", "KINDS",
           "build_lexicon", "concept_kinds", "normalise", "word_forms"]

INDOOR = rdflib.Namespace("https://w3id.org/semmap/indoor#")
#: Lowest rapidfuzz ratio (0-100) accepted for a near miss: one typo in a 7-letter word
#: ("shreder") scores 92, two in a 10-letter word about 80; unrelated words of similar length
#: score below 70.
FUZZY_CUTOFF = 84.0
#: Words (letters and digits, spaces aside) shorter than this resolve only exactly.
FUZZY_MIN_LEN = 4
#: Concept kinds, by the top class (or class of individuals) that defines them.
KINDS = {"place": INDOOR.Place, "equipment": INDOOR.Equipment, "object": INDOOR.PortableObject,
         "role": INDOOR.Role, "function": INDOOR.Function}


@dataclass(frozen=True)
class Concept:
    """An ontology concept a text resolved to.

    Attributes
    ----------
    iri : str
    local_name : str
        E.g. ``"MailRoom"``.
    kind : str
        ``"place"``, ``"role"``, ``"equipment"``, ``"object"`` or ``"function"``.
    label : str
        The label that matched (lower case).
    score : float
        1.0 exact, 0.95 after stripping word forms, else the fuzzy ratio / 100.
    """

    iri: str
    local_name: str
    kind: str
    label: str
    score: float


def normalise(text: str) -> str:
    """Lower case, apostrophes and punctuation dropped (hyphens kept), single spaces.

    ``"Manager’s  Office"`` -> ``"managers office"``; ``"X-Ray"`` -> ``"x-ray"``.
    """
    text = str(text).lower().replace("’", "'")
    text = re.sub(r"'s\b", "s", text)
    text = re.sub(r"[^a-z0-9\- ]+", " ", text)
    return " ".join(text.split())


def _singular(word: str) -> str:
    if len(word) > 4 and word.endswith("ies"):
        return word[:-3] + "y"
    if len(word) > 4 and word.endswith(("ches", "shes", "xes", "sses")):
        return word[:-2]
    if len(word) > 3 and word.endswith("s") and not word.endswith("ss"):
        return word[:-1]
    return word


def word_forms(text: str) -> list[str]:
    """Other forms ``text`` may be a label in: possessive and plural stripped, per word.

    ``"manager's"`` -> ``["manager"]``; ``"mail rooms"`` -> ``["mail room", "mails room",
    ...]``; the first form singularises every word, the next only the last word.
    """
    words = normalise(text).split()
    forms = [" ".join(_singular(w) for w in words)]
    if words:
        forms.append(" ".join(words[:-1] + [_singular(words[-1])]))
    return [f for f in dict.fromkeys(forms) if f and f != " ".join(words)]


def concept_kinds(graph: rdflib.Graph) -> dict[rdflib.URIRef, str]:
    """The kind of every concept of an ontology: subclasses of Place, Equipment and
    PortableObject, and individuals of Role and Function."""
    kinds: dict[rdflib.URIRef, str] = {}
    for kind, top in KINDS.items():
        if kind in ("role", "function"):
            for s in graph.subjects(RDF.type, top):
                if isinstance(s, rdflib.URIRef):
                    kinds.setdefault(s, kind)
        else:
            for s in graph.transitive_subjects(RDFS.subClassOf, top):
                if isinstance(s, rdflib.URIRef):
                    kinds.setdefault(s, kind)
    return kinds


def _local(iri: str) -> str:
    return re.split(r"[#/]", str(iri))[-1]


class Lexicon:
    """An index from normalised labels to concepts (see :func:`build_lexicon`)."""

    def __init__(self, entries: dict[str, tuple[str, str]]) -> None:
        #: normalised label -> (iri, kind)
        self.entries = entries
        self._fuzzy_choices = [k for k in entries if len(k.replace(" ", "")) >= FUZZY_MIN_LEN]
        self._by_local: dict[str, str] = {}  # lower-case local name -> its first label
        for label, (iri, _) in entries.items():
            self._by_local.setdefault(_local(iri).lower(), label)

    def __len__(self) -> int:
        return len(self.entries)

    def labels_of(self, local_name: str) -> list[str]:
        """Every label of a concept (by local name)."""
        return [k for k, (iri, _) in self.entries.items() if _local(iri) == local_name]

    def _concept(self, label: str, score: float) -> Concept:
        iri, kind = self.entries[label]
        return Concept(iri=iri, local_name=_local(iri), kind=kind, label=label, score=score)

    def resolve(self, text: str, kinds: Iterable[str] | None = None,
                fuzzy: bool = True) -> Concept | None:
        """The concept ``text`` names, or None (see the module docstring for the steps).

        Parameters
        ----------
        text : str
            An English word or phrase, or a concept's local name (``"MailRoom"``).
        kinds : iterable of str, optional
            Accept only these kinds (e.g. ``{"place"}``).
        fuzzy : bool
            Allow near misses (step 3).
        """
        allowed = set(kinds) if kinds is not None else None

        def ok(label: str) -> bool:
            return label in self.entries and (allowed is None
                                              or self.entries[label][1] in allowed)

        key = normalise(text)
        if not key:
            return None
        if ok(key):
            return self._concept(key, 1.0)
        camel = str(text).strip().lower()
        if camel in self._by_local and ok(self._by_local[camel]):  # a local name: "MailRoom"
            return self._concept(self._by_local[camel], 1.0)
        for form in word_forms(text):
            if ok(form):
                return self._concept(form, 0.95)
        if not fuzzy or len(key.replace(" ", "")) < FUZZY_MIN_LEN:
            return None
        choices = [c for c in self._fuzzy_choices if ok(c)]
        best = process.extractOne(key, choices, scorer=fuzz.ratio, score_cutoff=FUZZY_CUTOFF)
        if best is None:
            return None
        return self._concept(best[0], round(best[1] / 100.0, 3))

    def resolve_sign(self, text: str, vocabulary=None) -> Concept | None:
        """The place class a sign text names: the vocabulary's class when it knows the
        text (``"MANAGER"`` -> ManagerOffice, ``"OFFICE 101"`` -> Office), else the best
        place label (exact or fuzzy)."""
        if vocabulary is None:
            from semantic.vocabulary import load_vocabulary
            vocabulary = _default_vocabulary(load_vocabulary)
        cls = vocabulary.place_class(text)
        if cls is not None:
            labels = self.labels_of(cls)
            iri = next((self.entries[lab][0] for lab in labels), str(INDOOR[cls]))
            return Concept(iri=iri, local_name=cls, kind="place", label=normalise(text),
                           score=1.0)
        return self.resolve(text, kinds={"place"})


_VOCAB_CACHE: list = []


def _default_vocabulary(loader):
    if not _VOCAB_CACHE:
        _VOCAB_CACHE.append(loader())
    return _VOCAB_CACHE[0]


def build_lexicon(graph: rdflib.Graph) -> Lexicon:
    """Index an ontology graph's labels (``rdfs:label`` and ``skos:altLabel``).

    A label given to two concepts is kept for the first (by kind order:
    place, equipment, object, role, function) - the packaged ontology has
    none; ``tests/test_semantic_lexicon.py`` checks that.
    """
    kinds = concept_kinds(graph)
    order = list(KINDS)
    entries: dict[str, tuple[str, str]] = {}
    for iri, kind in sorted(kinds.items(), key=lambda kv: (order.index(kv[1]), str(kv[0]))):
        for prop in (RDFS.label, SKOS.altLabel):
            for label in graph.objects(iri, prop):
                entries.setdefault(normalise(label), (str(iri), kind))
    # Every concept is also named by its local name split into words ("MailRoom" -> "mail room").
    for iri, kind in kinds.items():
        words = normalise(re.sub(r"(?<=[a-z0-9])(?=[A-Z])", " ", _local(iri)))
        entries.setdefault(words, (str(iri), kind))
    return Lexicon(entries)
