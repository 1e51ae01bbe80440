"""Labels and synonyms resolve English words and sign texts to ontology concepts."""
from __future__ import annotations

from collections import defaultdict

import pytest
import rdflib
from rdflib import OWL, RDF, RDFS
from rdflib.namespace import SKOS

from semantic.kb import DEFAULT_ONTOLOGY
from semantic.lexicon import FUZZY_MIN_LEN, INDOOR, build_lexicon, normalise, word_forms
from semantic.vocabulary import load_vocabulary


@pytest.fixture(scope="module")
def onto():
    return rdflib.Graph().parse(DEFAULT_ONTOLOGY)


@pytest.fixture(scope="module")
def lex(onto):
    return build_lexicon(onto)


@pytest.mark.parametrize("text, local, kind", [
    ("mail room", "MailRoom", "place"), ("post room", "MailRoom", "place"),
    ("MAILROOM", "MailRoom", "place"), ("kitchenette", "Kitchen", "place"),
    ("pantry", "Kitchen", "place"), ("manager", "Manager", "role"), ("boss", "Manager", "role"),
    ("director", "Manager", "role"), ("laptop", "Laptop", "object"),
    ("notebook computer", "Laptop", "object"), ("paper shredder", "Shredder", "equipment"),
    ("Shredder", "Shredder", "equipment"), ("mail handling", "MailHandling", "function"),
    ("ServerRoom", "ServerRoom", "place"),
])
def test_exact_labels(lex, text, local, kind):
    c = lex.resolve(text)
    assert c is not None and (c.local_name, c.kind, c.score) == (local, kind, 1.0)


@pytest.mark.parametrize("text, local", [
    ("manager's", "Manager"), ("Manager’s", "Manager"), ("books", "Book"),
    ("libraries", "Library"), ("mail rooms", "MailRoom"), ("photocopiers", "Photocopier"),
    ("nurses", "Nurse"), ("keys", "Key"),
])
def test_plurals_and_possessives(lex, text, local):
    c = lex.resolve(text)
    assert c is not None and c.local_name == local and c.score == 0.95


def test_fuzzy_near_misses_but_never_short_words(lex):
    assert lex.resolve("shreder").local_name == "Shredder"
    assert lex.resolve("secretery").local_name == "Secretary"
    assert 0.84 <= lex.resolve("coffe machine").score < 1.0
    assert lex.resolve("lap") is None  # not "lab": words under FUZZY_MIN_LEN letters are exact
    assert lex.resolve("icu").local_name == "IntensiveCare"
    assert lex.resolve("xyzzy") is None and lex.resolve("") is None
    assert lex.resolve("shreder", fuzzy=False) is None
    assert FUZZY_MIN_LEN == 4


def test_kinds_filter(lex):
    assert lex.resolve("manager", kinds={"place"}) is None or \
        lex.resolve("manager", kinds={"place"}).kind == "place"
    assert lex.resolve("research", kinds={"function"}).local_name == "Research"


def test_word_forms_and_normalise():
    assert normalise("  Manager’s   OFFICE!") == "managers office"
    assert word_forms("manager's") == ["manager"]
    assert "mail room" in word_forms("mail rooms")


def test_every_label_names_one_concept(onto):
    owners = defaultdict(set)
    for prop in (RDFS.label, SKOS.altLabel):
        for s, o in onto.subject_objects(prop):
            assert str(o) == str(o).lower(), f"label {o!r} of {s} is not lower case"
            owners[normalise(o)].add(s)
    shared = {k: v for k, v in owners.items() if len(v) > 1}
    assert not shared


def test_vocabulary_classes_exist_and_resolve_back(onto, lex):
    """Every place class of the sign vocabulary is an ontology class with the same local
    name and is_a parent, its labels resolve back to it, and its sign texts resolve to it."""
    voc = load_vocabulary()
    for entry in voc.entries:
        iri = INDOOR[entry.place_class]
        assert (iri, RDF.type, OWL.Class) in onto, entry.place_class
        assert (iri, RDFS.subClassOf, INDOOR[entry.is_a]) in onto, entry.place_class
        labels = lex.labels_of(entry.place_class)
        assert labels, f"{entry.place_class} has no label"
        for label in labels:
            c = lex.resolve(label, kinds={"place"})
            assert c is not None and c.local_name == entry.place_class, (label, c)
        for phrase in entry.phrases:
            assert lex.resolve_sign(phrase, voc).local_name == entry.place_class, phrase
        for pattern in entry.patterns:
            text = pattern.fill("101" if pattern.slot == "number" else "B")
            assert lex.resolve_sign(text, voc).local_name == entry.place_class, text


def test_signs_versus_words(lex):
    """A door reading MANAGER is the manager's office; the word "manager" is the role."""
    voc = load_vocabulary()
    assert lex.resolve_sign("MANAGER", voc).local_name == "ManagerOffice"
    assert lex.resolve("MANAGER").local_name == "Manager"
    assert lex.resolve_sign("OFFICE 101", voc).local_name == "Office"
    assert lex.resolve_sign("LIBRAR", voc).local_name == "Library"  # not in the vocabulary
    assert lex.resolve_sign("QWERTY", voc) is None
