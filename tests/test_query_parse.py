"""The text query parser: English commands and questions to objectives (issue 8, part 1).

Every case states the full objectives (action, the concepts of object, owner,
destination and source, time and day), so a wrong reading in any slot fails.
"""
from __future__ import annotations

import json

import pytest
import rdflib
from rdflib import RDF, RDFS

from semantic.kb import load_ontology
from semantic.lexicon import INDOOR, build_lexicon
from semantic.query import ParseError, Request, parse_command
from semantic.timetable import EXAMPLES, load_timetable


@pytest.fixture(scope="module")
def lex():
    return build_lexicon(load_ontology())


@pytest.fixture(scope="module")
def people():
    return [p.name for p in load_timetable(EXAMPLES["office"]).people]


def objectives(req: Request) -> tuple:
    """(kind, action, object, owner, destination, source, time, day), mentions by concept."""
    def c(m):
        return None if m is None else m.concept
    return (req.kind, req.action, c(req.object), c(req.owner), c(req.destination), c(req.source),
            req.time, req.day)


# text, (kind, action, object, owner, destination, source, time, day)
CASES = [
    # -- commands: the examples and their paraphrases
    ("fetch the manager's mail", ("command", "fetch", "Mail", "Manager", None, None, None, None)),
    ("Fetch the Manager's mail!", ("command", "fetch", "Mail", "Manager", None, None, None, None)),
    ("could you fetch the boss's mail", ("command", "fetch", "Mail", "Manager", None, None,
                                         None, None)),
    ("please fetch the director’s post, thanks", ("command", "fetch", "Mail", "Manager", None,
                                                  None, None, None)),
    ("get the manager's laptop", ("command", "fetch", "Laptop", "Manager", None, None, None,
                                  None)),
    ("bring the manager his mail", ("command", "bring", "Mail", "Manager", "Manager", None,
                                    None, None)),
    ("Bring the boss her letters.", ("command", "bring", "Mail", "Manager", "Manager", None,
                                     None, None)),
    # "admin" is a label of the Administration office in the packaged ontology.
    ("please take the admin's laptop to the maintenance room",
     ("command", "take", "Laptop", "Administration", "Maintenance", None, None, None)),
    ("send the admin laptop to maintenance", ("command", "send", "Laptop", "Administration",
                                              "Maintenance", None, None, None)),
    ("deliver the mail to the manager", ("command", "deliver", "Mail", None, "Manager", None,
                                         None, None)),
    ("can you deliver the parcel to the mail clerk?", ("command", "deliver", "Parcel", None,
                                                       "MailClerk", None, None, None)),
    ("give the manager the parcel", ("command", "deliver", "Parcel", None, "Manager", None,
                                     None, None)),
    ("bring me the mail", ("command", "bring", "Mail", None, None, None, None, None)),
    ("pick up the parcel from the mail room", ("command", "fetch", "Parcel", None, None,
                                               "MailRoom", None, None)),
    ("bring the book from the library to the manager", ("command", "bring", "Book", None,
                                                        "Manager", "Library", None, None)),
    ("take the mail to the manager's office", ("command", "take", "Mail", None, "ManagerOffice",
                                               None, None, None)),
    ("fetch the mail of the manager", ("command", "fetch", "Mail", "Manager", None, None, None,
                                       None)),
    ("carry the documents to the copy room", ("command", "take", "Document", None, "CopyRoom",
                                              None, None, None)),
    ("I need you to send the keys to the janitor at 4 pm", ("command", "send", "Key", None,
                                                            "Janitor", None, "16:00", None)),
    ("go to the kitchen", ("command", "go", None, None, "Kitchen", None, None, None)),
    ("take me to the lab", ("command", "go", None, None, "Laboratory", None, None, None)),
    ("please go back to the lobby", ("command", "go", None, None, "Lobby", None, None, None)),
    ("head to the post room", ("command", "go", None, None, "MailRoom", None, None, None)),
    ("go to the head teacher", ("command", "go", None, None, "Principal", None, None, None)),
    ("go to office 101", ("command", "go", None, None, "OFFICE 101", None, None, None)),
    ("find the shredder", ("command", "find", "Shredder", None, None, None, None, None)),
    ("could you look for the paper shredder", ("command", "find", "Shredder", None, None, None,
                                               None, None)),
    ("show me the printer", ("command", "find", "Printer", None, None, None, None, None)),
    ("find the manager", ("command", "find", "Manager", None, None, None, None, None)),
    # -- questions
    ("where is the shredder?", ("question", "where", "Shredder", None, None, None, None, None)),
    ("where's the photocopier", ("question", "where", "Photocopier", None, None, None, None,
                                 None)),
    ("where can I find a printer?", ("question", "where", "Printer", None, None, None, None,
                                     None)),
    ("where is the admin laptop", ("question", "where", "Laptop", "Administration", None, None,
                                   None, None)),
    ("where does the librarian work?", ("question", "where", "Librarian", None, None, None,
                                        None, None)),
    ("who works in the mail room?", ("question", "who", "MailRoom", None, None, None, None,
                                     None)),
    ("who is in the kitchen at noon?", ("question", "who", "Kitchen", None, None, None, "12:00",
                                        None)),
    ("who is the manager?", ("question", "who", "Manager", None, None, None, None, None)),
    ("how do I get to the lab?", ("question", "route", None, None, "Laboratory", None, None,
                                  None)),
    ("how can I reach the server room", ("question", "route", None, None, "ServerRoom", None,
                                         None, None)),
    ("show me the way to the library", ("question", "route", None, None, "Library", None, None,
                                        None)),
    ("which way is the kitchen?", ("question", "route", None, None, "Kitchen", None, None,
                                   None)),
    # -- times and days (the timetable's weekly slots: HH:MM and mon..sun)
    ("where is the manager at 10:30?", ("question", "where", "Manager", None, None, None,
                                        "10:30", None)),
    ("where is the teacher at 2 pm", ("question", "where", "Teacher", None, None, None, "14:00",
                                      None)),
    ("where will the teacher be on Monday at 1:30 p.m.?", ("question", "where", "Teacher", None,
                                                           None, None, "13:30", "mon")),
    ("where is the sysadmin on wednesdays at 15.30", ("question", "where", "SystemAdministrator",
                                                      None, None, None, "15:30", "wed")),
    ("where is the researcher at 9 o'clock on fri", ("question", "where", "Researcher", None,
                                                     None, None, "09:00", "fri")),
    ("where is the manager at 12 am", ("question", "where", "Manager", None, None, None, "00:00",
                                       None)),
    ("where is the manager now", ("question", "where", "Manager", None, None, None, None, None)),
]

# People from the office timetable: names resolve exactly, first names and titles optional.
PEOPLE_CASES = [
    ("where is Dr Lovelace at 10:00 on Monday?", ("question", "where", "Dr Ada Lovelace", None,
                                                  None, None, "10:00", "mon")),
    ("fetch Turing's laptop", ("command", "fetch", "Laptop", "Alan Turing", None, None, None,
                               None)),
    ("take the report to Katherine Johnson", ("command", "take", "Document", None,
                                              "Katherine Johnson", None, None, None)),
    ("go to Ada's office", ("command", "go", None, "Dr Ada Lovelace", "Office", None, None,
                            None)),
]


@pytest.mark.parametrize("text, expected", CASES, ids=[c[0] for c in CASES])
def test_commands_and_questions(lex, text, expected):
    req = parse_command(text, lex)
    assert objectives(req) == expected
    assert req.text == text


@pytest.mark.parametrize("text, expected", PEOPLE_CASES, ids=[c[0] for c in PEOPLE_CASES])
def test_people_from_a_timetable(lex, people, text, expected):
    assert objectives(parse_command(text, lex, people=people)) == expected


@pytest.mark.parametrize("text, slot, concept, typed", [
    ("fetch the managr's mail", "owner", "Manager", "managr"),
    ("go to the kitchn", "destination", "Kitchen", "kitchn"),
    ("where is the shreder?", "object", "Shredder", "shreder"),
    ("take the laptp to the libary", "destination", "Library", "libary"),
    ("send the managr laptop to maintenance", "owner", "Manager", "managr"),
    ("go to ofice 101", "destination", "OFFICE 101", "ofice 101"),
])
def test_near_misses_resolve_as_fuzzy(lex, text, slot, concept, typed):
    mention = getattr(parse_command(text, lex), slot)
    assert (mention.concept, mention.fuzzy, mention.text) == (concept, True, typed)


def test_exact_words_are_not_fuzzy(lex):
    req = parse_command("fetch the managr's mail", lex)
    assert req.object.fuzzy is False and req.owner.label == "manager"
    req = parse_command("bring the manager's letters", lex)  # a plural is exact, not a near miss
    assert (req.object.concept, req.object.fuzzy, req.owner.fuzzy) == ("Mail", False, False)


@pytest.mark.parametrize("text, word", [
    ("go to the lba", "lba"),      # "lab" misspelt: short words resolve only exactly
    ("fetch the kye", "kye"),      # "key"
    ("go to the lbb", "lbb"),
])
def test_short_misspelt_words_do_not_resolve(lex, text, word):
    with pytest.raises(ParseError) as info:
        parse_command(text, lex)
    assert info.value.words == (word,) and f'"{word}"' in str(info.value)


@pytest.mark.parametrize("text, words, says", [
    ("", (), "empty"),
    ("   ", (), "empty"),
    ("fetch the unicorn", ("unicorn",), "not a word of the ontology"),
    ("dance", ("dance",), "not understood at the start"),
    ("asdf qwer zxcv", ("asdf",), "not understood at the start"),
    ("gone to the kitchen", ("gone",), "not understood at the start"),
    ("fetch the purple mail", ("purple",), "not a word of the ontology"),
    ("fetch the kitchen", ("kitchen",), "is a place"),
    ("go to the mail", ("mail",), "is an object"),
    ("fetch his mail", ("his",), "does not say whose"),
    ("where is the teacher at 25:00", ("25:00",), "is not a time"),
    ("where is the teacher at 13 pm", ("13 pm",), "is not a time"),
    ("fetch the mail to the lab to the kitchen", (), "two destinations"),
    ("fecth the mail", ("fecth",), 'Did you mean "fetch"'),
    ("fetch the", (), "stops too early"),
])
def test_errors_name_the_words_not_understood(lex, text, words, says):
    with pytest.raises(ParseError) as info:
        parse_command(text, lex)
    err = info.value
    message = str(err)
    assert err.words == words and says in message
    assert message.startswith(f'could not understand "{text.strip()}"')
    for word in words:
        assert f'"{word}"' in message
    assert "\n" not in message and "Traceback" not in message
    assert "commands look like" in message.lower() or "does not say" in message \
        or "two destinations" in message or "not a time" in message


def test_to_dict_is_stable_json(lex):
    d = parse_command("please take the admin's laptop to the maintenance room at 2 pm", lex
                      ).to_dict()
    assert list(d) == ["text", "kind", "action", "object", "owner", "destination", "source",
                       "time", "day"]
    assert d["object"] == {"text": "laptop", "concept": "Laptop", "kind": "object",
                           "label": "laptop", "fuzzy": False}
    assert d["owner"]["text"] == "admin" and d["source"] is None and d["time"] == "14:00"
    assert json.loads(json.dumps(d)) == d


def test_the_vocabulary_is_the_ontologys(lex):
    """Another ontology, another vocabulary, the same grammar."""
    g = rdflib.Graph()
    for top in ("Place", "Equipment", "PortableObject"):
        g.add((INDOOR[top], RDF.type, rdflib.OWL.Class))
    g.add((INDOOR.Scroll, RDFS.subClassOf, INDOOR.PortableObject))
    g.add((INDOOR.Scroll, RDFS.label, rdflib.Literal("scroll", lang="en")))
    g.add((INDOOR.Tower, RDFS.subClassOf, INDOOR.Place))
    g.add((INDOOR.Tower, RDFS.label, rdflib.Literal("tower", lang="en")))
    g.add((INDOOR.Wizard, RDF.type, INDOOR.Role))
    g.add((INDOOR.Wizard, RDFS.label, rdflib.Literal("wizard", lang="en")))
    other = build_lexicon(g)
    req = parse_command("take the wizard's scroll to the tower", other)
    assert objectives(req) == ("command", "take", "Scroll", "Wizard", "Tower", None, None, None)
    with pytest.raises(ParseError, match='"mail"'):
        parse_command("fetch the manager's mail", other)
