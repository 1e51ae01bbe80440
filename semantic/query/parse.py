"""English commands and questions to objectives: the parser of the text query planner.

A user types "please take the admin's laptop to the maintenance room" or "where is
the teacher at 2 pm?"; the planner needs the action (take / where), the thing
(``Laptop``), whose it is (``Administration``), where it goes (``Maintenance``)
and when. Parsing has two stages, so the vocabulary is the ontology's and the
sentence patterns are the grammar's:

1. **Syntax.** ``grammar.lark`` (LALR, built once per process) knows only
   function words: verbs, prepositions, determiners, question words, politeness,
   times and days. Every content phrase is a generic run of words (``noun``)
   labelled with its role in the sentence (object, recipient, destination,
   source, beneficiary).
2. **Words.** Each phrase is resolved through :class:`semantic.lexicon.Lexicon`
   (the ontology's ``rdfs:label`` and ``skos:altLabel``), exact first and then as
   a near miss (:data:`semantic.lexicon.FUZZY_CUTOFF`; short words never), and
   must be of a kind its role accepts: something carried is an object or
   equipment, a destination is a place or a person (see :data:`SLOT_KINDS`).
   A phrase is tried whole first ("mail room", "manager's office"), then split
   into owner and thing ("admin laptop", "the manager's mail", "the mail of the
   manager"). Swapping the ontology changes what is understood without touching
   the grammar.

Two kinds of words come from outside the ontology: people's names (``people``,
e.g. from a timetable, matched exactly: "Dr Lovelace", "Ada") give mentions of
kind ``"person"``, and a place word followed by a number ("office 101", "room
12") gives a mention of kind ``"name"`` whose concept is the name as a sign
would print it (``"OFFICE 101"``); finding that sign on the map is the
planner's business.

Nothing is guessed: a word that is neither a function word of the grammar nor
a label (exact or near miss) raises :class:`ParseError`, one paragraph quoting
the command, naming the word and listing what is understood.
"""
from __future__ import annotations

import difflib
import functools
import re
from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

from lark import Lark, Token, Tree
from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedInput, UnexpectedToken

from blocks.core.errors import SemmapError
from semantic.lexicon import KINDS, Concept, Lexicon, normalise
from semantic.timetable import DAYS

__all__ = ["ACTIONS", "GRAMMAR", "Mention", "ParseError", "Request", "SLOT_KINDS",
           "parse_command"]

GRAMMAR = Path(__file__).with_name("grammar.lark")

#: Verbs of the grammar to the planner's actions (commands), by the first word of the verb.
VERB_ACTIONS = {
    "fetch": "fetch", "get": "fetch", "grab": "fetch", "collect": "fetch", "retrieve": "fetch",
    "pick": "fetch", "bring": "bring", "take": "take", "carry": "take", "send": "send",
    "deliver": "deliver", "give": "deliver", "hand": "deliver",
    "go": "go", "head": "go", "walk": "go", "move": "go", "drive": "go", "navigate": "go",
    "return": "go", "come": "go", "proceed": "go", "visit": "go", "lead": "go", "guide": "go",
    "escort": "go", "find": "find", "locate": "find", "look": "find", "search": "find",
    "show": "find",
}
#: Actions of commands and of questions ("route": how do I get to ...).
ACTIONS = {"command": ("fetch", "bring", "take", "send", "deliver", "go", "find"),
           "question": ("where", "who", "route")}
#: Verbs that, with "me", mean a guided walk: "take me to the lab" is ``go``.
GUIDE_VERBS = ("take", "bring", "get", "carry")
#: Kinds each role in a sentence accepts. ``person`` and ``name`` are not lexicon kinds:
#: they come from ``people`` and from numbered place names (see the module docstring).
SLOT_KINDS: dict[str, frozenset[str]] = {
    "carried": frozenset({"object", "equipment"}),
    "sought": frozenset({"object", "equipment", "place", "role", "person", "name"}),
    "who": frozenset({"place", "role", "person", "name"}),
    "owner": frozenset({"role", "person", "place", "name"}),
    "destination": frozenset({"place", "role", "person", "name"}),
    "source": frozenset({"place", "role", "person", "name", "equipment"}),
}
#: How an error names what a slot wants.
SLOT_NAMES = {"carried": "something to carry (an object)",
              "sought": "something to find (an object, equipment, place or person)",
              "who": "a place or a role", "owner": "an owner (a person, role or place)",
              "destination": "a place or a person to go to",
              "source": "a place or a person to take it from"}
#: Words before a person's name that the name itself may lack.
TITLES = frozenset({"dr", "mr", "mrs", "ms", "miss", "prof", "sir"})
_KIND_NAMES = {"object": "an object", "equipment": "equipment", "place": "a place",
               "role": "a role", "function": "an activity", "person": "a person",
               "name": "a numbered place name"}
_PATTERNS = ('"fetch the <role>\'s <object>"', '"take the <object> to the <place>"',
             '"bring the <role> his <object>"', '"go to the <place>"', '"find the <equipment>"',
             '"where is the <thing or role> at 10:30?"', '"who works in the <place>?"',
             '"how do I get to the <place>?"')


class ParseError(SemmapError):
    """A command the parser does not understand; the message names the words concerned.

    Attributes
    ----------
    command : str
        The command as typed.
    words : tuple of str
        The words not understood (as typed), empty when the command is empty.
    """

    def __init__(self, command: str, why: str, *, words: Sequence[str] = (),
                 hint: str | None = None) -> None:
        examples = f"Commands look like {', '.join(_PATTERNS)}."
        super().__init__(f'could not understand "{command.strip()}": {why}',
                         hint=f"{_sentence(hint)} {examples}" if hint else examples)
        self.command = command
        self.words = tuple(words)


class _UnknownWords(ParseError):
    """Words that are not labels: gathered over the whole command before reporting."""

    def __init__(self, command: str, words: Sequence[str], phrase: str, slot: str,
                 lexicon: Lexicon) -> None:
        self.phrase, self.slot, self.lexicon = phrase, slot, lexicon
        hint = " ".join(filter(None, (_did_you_mean(lexicon, words), _known(lexicon, slot))))
        if words:
            listed = " and ".join(f'"{w}"' for w in words)
            why = listed + (" is not a word" if len(words) == 1 else " are not words") + \
                " of the ontology, nor close to one"
        else:
            why = f'"{phrase}" names nothing known as {SLOT_NAMES[slot]}'
        super().__init__(command, why, words=words or [phrase], hint=hint)

    @staticmethod
    def merge(errors: Sequence[_UnknownWords]) -> _UnknownWords:
        """One error naming the unknown words of several phrases."""
        if len(errors) == 1:
            return errors[0]
        first = errors[0]
        words = [w for e in errors for w in e.words]
        return _UnknownWords(first.command, words, first.phrase, first.slot, first.lexicon)


@dataclass(frozen=True)
class Mention:
    """A phrase of the command resolved to a concept.

    Attributes
    ----------
    text : str
        The words as typed ("managr", "Dr Lovelace").
    concept : str
        The ontology's local name (``"Manager"``, ``"MailRoom"``), a person's full name
        (kind ``"person"``) or a numbered place name as signs print it (``"OFFICE 101"``,
        kind ``"name"``).
    kind : str
        A lexicon kind (``"object"``, ``"equipment"``, ``"place"``, ``"role"``), or
        ``"person"`` or ``"name"``.
    label : str
        The label that matched ("manager" for "managr"), so a near miss can be shown.
    fuzzy : bool
        Matched as a near miss, not exactly (plurals and possessives count as exact).
    """

    text: str
    concept: str
    kind: str
    label: str
    fuzzy: bool = False


@dataclass(frozen=True)
class Request:
    """The objectives of one command or question.

    Attributes
    ----------
    text : str
        The command as typed.
    kind : str
        ``"command"`` or ``"question"``.
    action : str
        Commands: fetch, bring, take, send, deliver, go, find. Questions: where, who,
        route ("how do I get to ...").
    object : Mention or None
        What the request is about: the thing to carry or find, the person or thing asked
        about ("where is the manager"), the place asked about ("who works in the mail room").
    owner : Mention or None
        Whose it is: "the manager's mail", "the admin laptop", "bring the manager his
        mail"; for a request without an object, the destination's ("go to Ada's office").
    destination : Mention or None
        Where it goes or where to go: a place or a person. None means the one asking
        ("fetch the mail", "bring me the mail") or, for questions, not asked.
    source : Mention or None
        Where to take it from ("from the kitchen").
    time : str or None
        ``"HH:MM"`` (24 h) when the command gives a time ("at 2 pm" -> ``"14:00"``).
    day : str or None
        A timetable day (:data:`semantic.timetable.DAYS`: ``"mon"`` ...) when given.
    """

    text: str
    kind: str
    action: str
    object: Mention | None = None
    owner: Mention | None = None
    destination: Mention | None = None
    source: Mention | None = None
    time: str | None = None
    day: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """A stable JSON form: every field, mentions as dicts (None stays None)."""
        return asdict(self)


# ---- entry point ----------------------------------------------------------------------------
def parse_command(text: str, lexicon: Lexicon, people: Iterable[str] = ()) -> Request:
    """Parse an English command or question into a :class:`Request`.

    Parameters
    ----------
    text : str
        E.g. ``"fetch the manager's mail"``, ``"where is the shredder?"``.
    lexicon : Lexicon
        The ontology's words (:func:`semantic.lexicon.build_lexicon`).
    people : iterable of str, optional
        Names of people the caller knows (e.g. a timetable's), so "where is Dr Lovelace"
        and "Turing's laptop" resolve; matched exactly, titles and first names optional.

    Raises
    ------
    ParseError
        The command is empty, does not follow the grammar, or holds a word that is not a
        label (nor a near miss of one), or a phrase of the wrong kind for its place.
    """
    if not str(text).strip():
        raise ParseError(str(text), "the command is empty")
    prepared = _prepare(str(text))
    index = _people_index(people)
    try:
        tree = _parser().parse(prepared)
    except UnexpectedInput as exc:
        raise _syntax_error(str(text), prepared, exc, lexicon, index) from None
    _check_whole_words(str(text), prepared, tree)
    return _Builder(str(text), lexicon, index).request(tree)


@functools.lru_cache(maxsize=1)
def _parser() -> Lark:
    """The LALR parser, built once: building takes ~0.1 s, a parse well under 1 ms.

    The contextual lexer reads a function word as one only where the grammar expects
    it, so labels holding one ("work bench", "head teacher") stay content words.
    """
    return Lark(GRAMMAR.read_text(encoding="utf-8"), parser="lalr", lexer="contextual",
                maybe_placeholders=False, keep_all_tokens=True)


def _prepare(text: str) -> str:
    """Lower case, curly apostrophes straightened and symbols blanked, keeping every
    character's position, so token positions index the text as typed.

    An apostrophe survives only after a letter (possessives, "where's", "o'clock"):
    quotes around a word ('fetch') must not read as a possessive.
    """
    out = []
    for i, ch in enumerate(text):
        low = ch.lower()
        low = low if len(low) == 1 else ch
        if low in "'\u2019\u2018":
            prev = text[i - 1] if i else " "
            low = "'" if prev.isalpha() else " "
        elif not (low.isalnum() or low.isspace() or low in ",.!?;:-"):
            low = " "
        out.append(low)
    return "".join(out)


# ---- resolving phrases ------------------------------------------------------------------------
@dataclass(frozen=True)
class _Span:
    """A run of words of the command (a ``noun``), or some of them.

    Attributes
    ----------
    source : str
        The whole command as typed.
    words : tuple of str
        The words, lower case (the lexer's tokens).
    offsets : tuple of (int, int)
        Each word's start and end in ``source``.
    numbered : bool
        The last word is a number ("office 101").
    """

    source: str
    words: tuple[str, ...]
    offsets: tuple[tuple[int, int], ...]
    numbered: bool = False

    @property
    def text(self) -> str:
        """The words as typed."""
        return self.source[self.offsets[0][0]:self.offsets[-1][1]]

    @property
    def key(self) -> str:
        """The words as a lexicon key."""
        return " ".join(self.words)

    def part(self, start: int, stop: int | None = None) -> _Span:
        """The words ``start:stop`` as a span."""
        stop = len(self.words) if stop is None else stop
        return _Span(self.source, self.words[start:stop], self.offsets[start:stop],
                     self.numbered and stop == len(self.words))


def _people_index(people: Iterable[str]) -> list[tuple[str, frozenset[str]]]:
    """Each person's full name with the words a mention of them may use (titles aside)."""
    index = []
    for name in people:
        words = frozenset(w for w in normalise(name).split() if w not in TITLES)
        if words:
            index.append((" ".join(str(name).split()), words))
    return index


class _Builder:
    """Turns a parse tree into a :class:`Request`, resolving its phrases (one command)."""

    def __init__(self, text: str, lexicon: Lexicon,
                 people: list[tuple[str, frozenset[str]]]) -> None:
        self.text = text
        self.lexicon = lexicon
        self.people = people

    # -- the request -------------------------------------------------------------------------
    def request(self, tree: Tree) -> Request:
        """The request of a parsed ``start`` tree."""
        node = next(c for c in tree.children if isinstance(c, Tree))
        kind, action = self._action(node)
        slots = _Slots(self.text)
        _all_or_unknown([lambda c=child: self._fill(slots, c, action)
                         for child in node.children if isinstance(child, Tree)])
        if slots.pronoun is not None:
            self._resolve_pronoun(slots)
        if action == "go" and slots.destination is None and not slots.to_me:
            raise ParseError(self.text, "it does not say where to go",
                             hint='Say e.g. "go to the <place>" or "take me to the <place>".')
        return Request(text=self.text, kind=kind, action=action, object=slots.object,
                       owner=slots.owner, destination=slots.destination, source=slots.source,
                       time=slots.time, day=slots.day)

    def _action(self, node: Tree) -> tuple[str, str]:
        """The request kind and action of the request node (its rule and verb)."""
        rule = str(node.data)
        if rule in ACTIONS["question"]:
            return "question", rule
        verb = next((c for c in node.children if isinstance(c, Tree)
                     and c.data in ("move_verb", "go_verb", "find_verb")), None)
        word = str(verb.children[0]) if verb is not None else "show"
        if rule == "guide":
            if word not in GUIDE_VERBS:
                raise ParseError(self.text, f'"{word} me to" is not understood',
                                 words=[word], hint='Say "take me to the <place>" or '
                                                    '"go to the <place>".')
            return "command", "go"
        return "command", VERB_ACTIONS[word]

    def _fill(self, slots: _Slots, child: Tree, action: str) -> None:
        """Put one labelled part of the sentence into its slot."""
        role = str(child.data)
        if role in ("move_verb", "go_verb", "find_verb"):
            return
        if role == "when":
            self._when(slots, child)
        elif role == "me":
            slots.set_destination(None, to_me=True)
        elif role == "object":
            slot = _object_slot(action)
            head, owner, pronoun = self._phrase(child.children[0], slot, compound=slot != "who")
            slots.object = head
            slots.set_owner(owner)
            slots.pronoun = pronoun
        elif role == "recipient":
            sub = child.children[0]
            if isinstance(sub, Tree) and sub.data == "me":
                slots.set_destination(None, to_me=True)
            else:
                head, owner, _ = self._phrase(sub, "destination")
                slots.set_destination(head)
                slots.set_owner(owner)
            slots.recipient = slots.destination
        elif role in ("destination", "beneficiary"):
            head, owner, _ = self._phrase(child.children[0], "destination")
            slots.set_destination(head)
            slots.set_owner(owner)
        elif role == "source":
            head, owner, _ = self._phrase(child.children[0], "source")
            if slots.source is not None:
                raise ParseError(self.text, "it names two places to take it from",
                                 words=[head.text])
            slots.source = head
            slots.set_owner(owner)

    def _resolve_pronoun(self, slots: _Slots) -> None:
        """ "bring the manager his mail": the pronoun's owner is the recipient."""
        who = slots.recipient
        if who is None or who.kind not in ("role", "person"):
            raise ParseError(self.text, f'"{slots.pronoun}" does not say whose it is here',
                             words=[slots.pronoun],
                             hint='Name the owner, e.g. "fetch the <role>\'s <object>", or '
                                  'the recipient, e.g. "bring the <role> his <object>".')
        slots.set_owner(who)

    # -- phrases ------------------------------------------------------------------------------
    def _phrase(self, tree: Tree, slot: str, compound: bool = False
                ) -> tuple[Mention, Mention | None, str | None]:
        """Resolve a phrase tree: (the thing, its owner or None, an owning pronoun or None)."""
        form = str(tree.data)
        nouns = [c for c in tree.children if isinstance(c, Tree) and c.data == "noun"]
        if form == "plain":
            head, owner = self._noun(nouns[0], slot, compound)
            return head, owner, None
        if form == "pronoun_owned":
            pronoun = next(c for c in tree.children
                           if isinstance(c, Tree) and c.data == "pron_poss").children[0]
            head, owner = self._noun(nouns[0], slot, compound=False)
            return head, owner, self._typed(pronoun)
        joiner = "'s" if form == "owned" else " of"
        whole = self._whole_label(nouns, joiner, slot)
        if whole is not None:
            return whole, None, None
        slots = ("owner", slot) if form == "owned" else (slot, "owner")
        first, second = _all_or_unknown([lambda n=n, s=s: self._noun(n, s)[0]
                                         for n, s in zip(nouns, slots)])
        return (second, first, None) if form == "owned" else (first, second, None)

    def _whole_label(self, nouns: list[Tree], joiner: str, slot: str) -> Mention | None:
        """An owner-and-thing phrase that is itself a label: "manager's office", "head of
        department". Exact only: a near miss of a compound label would hide the owner."""
        first, last = self._span(nouns[0]), self._span(nouns[-1])
        start, end = first.offsets[0][0], last.offsets[-1][1]
        key = f"{first.key}{joiner} {last.key}"
        found = self._lookup(key, SLOT_KINDS[slot], fuzzy=False)
        return None if found is None else _mention(self.text[start:end], *found)

    def _noun(self, tree: Tree, slot: str, compound: bool = False
              ) -> tuple[Mention, Mention | None]:
        """Resolve one run of words for a slot: (thing, owner from a compound or None).

        Exact readings win over near misses: the whole phrase, then owner + thing
        splits ("admin laptop"), each exactly; then the same with near misses. A phrase
        that names a concept of the wrong kind is an error saying so.
        """
        span = self._span(tree)
        kinds = SLOT_KINDS[slot]
        for fuzzy in (False, True):
            found = self._whole(span, kinds, fuzzy)
            if found is not None:
                return found, None
            if compound:
                split = self._split(span, kinds, fuzzy)
                if split is not None:
                    return split
            other = self._whole(span, frozenset(_KIND_NAMES), fuzzy)
            if other is not None:
                raise self._wrong_kind(other, slot)
        raise self._unknown(span, slot)

    def _split(self, span: _Span, kinds: frozenset[str], fuzzy: bool
               ) -> tuple[Mention, Mention] | None:
        """Owner words then thing words ("admin laptop"), the longest thing first."""
        for i in range(1, len(span.words)):
            head = self._whole(span.part(i), kinds, fuzzy)
            if head is None:
                continue
            owner = self._whole(span.part(0, i), SLOT_KINDS["owner"], fuzzy)
            if owner is not None:
                return head, owner
        return None

    def _whole(self, span: _Span, kinds: frozenset[str], fuzzy: bool) -> Mention | None:
        """The span as one mention of an accepted kind: a numbered place name, a label,
        or a person; exactly, or also as a near miss when ``fuzzy``."""
        if span.numbered:
            return self._numbered(span, kinds, fuzzy) if "name" in kinds else None
        found = self._lookup(span.key, kinds, fuzzy)
        if found is not None:
            return _mention(span.text, *found)
        if "person" in kinds:
            return self._person(span)
        return None

    def _numbered(self, span: _Span, kinds: frozenset[str], fuzzy: bool) -> Mention | None:
        """ "office 101": a place word and a number, the name a sign would print."""
        found = self._lookup(" ".join(span.words[:-1]), frozenset({"place"}), fuzzy)
        if found is None:
            return None
        place, near = found
        return Mention(text=span.text, concept=f"{place.label.upper()} {span.words[-1]}",
                       kind="name", label=place.label, fuzzy=near)

    def _lookup(self, key: str, kinds: frozenset[str], fuzzy: bool
                ) -> tuple[Concept, bool] | None:
        """A lexicon concept of one of ``kinds`` and whether it is a near miss: exact
        first, then (when ``fuzzy``) a near miss, so the flag is known."""
        lex_kinds = kinds & set(KINDS)
        if not lex_kinds:
            return None
        concept = self.lexicon.resolve(key, kinds=lex_kinds, fuzzy=False)
        if concept is not None:
            return concept, False
        if fuzzy:
            concept = self.lexicon.resolve(key, kinds=lex_kinds, fuzzy=True)
            if concept is not None:
                return concept, True
        return None

    def _person(self, span: _Span) -> Mention | None:
        """A person the caller named whose name holds every word of the span."""
        words = {w for w in span.words if w not in TITLES} or set(span.words)
        matches = [name for name, known in self.people if words <= known]
        if len(matches) > 1:
            raise ParseError(self.text, f'"{span.text}" could be {" or ".join(matches)}',
                             words=[span.text], hint="Give the full name.")
        if not matches:
            return None
        return Mention(text=span.text, concept=matches[0], kind="person", label=matches[0])

    # -- times --------------------------------------------------------------------------------
    def _when(self, slots: _Slots, tree: Tree) -> None:
        """A time of day ("at 2 pm") or a day ("on monday"); "now" sets neither."""
        for part in tree.children:
            if isinstance(part, Token) and part.type == "DAY":
                if slots.day is not None:
                    raise ParseError(self.text, "it gives two days", words=[str(part)])
                slots.day = DAYS[DAYS.index(str(part)[:3])]
            elif isinstance(part, Tree) and part.data == "clock":
                if slots.time is not None:
                    raise ParseError(self.text, "it gives two times", words=[self._typed(part)])
                slots.time = self._clock(part)

    def _clock(self, tree: Tree) -> str:
        """ "HH:MM" of a clock phrase: 10:30, 2 pm, 2:15 p.m., 14, 1430, 9 o'clock, noon."""
        tokens = [t for t in tree.scan_values(lambda v: isinstance(v, Token))]
        first = str(tokens[0])
        if first in ("noon", "midday"):
            return "12:00"
        if first == "midnight":
            return "00:00"
        if tokens[0].type == "TIME":
            hour, minute = (int(x) for x in re.split(r"[:.h]", first))
        elif len(first) in (3, 4):
            hour, minute = int(first[:-2]), int(first[-2:])
        else:
            hour, minute = int(first), 0
        ampm = next((str(t) for t in tokens[1:] if t.type == "AMPM"), None)
        if ampm is not None:
            if not 1 <= hour <= 12:
                raise ParseError(self.text, f'"{self._typed(tree)}" is not a time',
                                 words=[self._typed(tree)],
                                 hint="With am/pm the hour is 1 to 12.")
            hour = hour % 12 + (12 if ampm.startswith("p") else 0)
        if not (0 <= hour <= 23 and 0 <= minute <= 59):
            raise ParseError(self.text, f'"{self._typed(tree)}" is not a time',
                             words=[self._typed(tree)], hint='Write e.g. "at 10:30" or "at 2 pm".')
        return f"{hour:02d}:{minute:02d}"

    # -- text and errors ----------------------------------------------------------------------
    def _span(self, tree: Tree) -> _Span:
        """The span of a ``noun`` tree."""
        tokens = [t for t in tree.children if isinstance(t, Token)]
        return _Span(self.text, tuple(str(t) for t in tokens),
                     tuple((t.start_pos, t.end_pos) for t in tokens),
                     tokens[-1].type == "NUMBER")

    def _typed(self, node: Tree | Token) -> str:
        """The text as typed under a tree or token."""
        if isinstance(node, Token):
            return self.text[node.start_pos:node.end_pos]
        tokens = list(node.scan_values(lambda v: isinstance(v, Token)))
        return self.text[tokens[0].start_pos:tokens[-1].end_pos]

    def _wrong_kind(self, found: Mention, slot: str) -> ParseError:
        """ "fetch the kitchen": the phrase is known, but not as what its place needs."""
        what = _KIND_NAMES.get(found.kind, found.kind)
        return ParseError(self.text, f'"{found.text}" is {what} ({found.label}), but here the '
                          f"command needs {SLOT_NAMES[slot]}", words=[found.text],
                          hint=_known(self.lexicon, slot))

    def _unknown(self, span: _Span, slot: str) -> _UnknownWords:
        """A phrase that names nothing: name the words that are not labels at all."""
        unknown = [span.part(i, i + 1).text for i, word in enumerate(span.words)
                   if not word.isdigit() and not self._known_word(word)]
        return _UnknownWords(self.text, unknown, span.text, slot, self.lexicon)

    def _known_word(self, word: str) -> bool:
        """Whether a single word is a label, a near miss of one, a name or a title."""
        return (word in TITLES or self.lexicon.resolve(word) is not None
                or any(word in known for _, known in self.people))


class _Slots:
    """The objectives being gathered, with the checks that no slot is filled twice."""

    def __init__(self, text: str) -> None:
        self.text = text  # the command, for error messages
        self.object: Mention | None = None
        self.owner: Mention | None = None
        self.destination: Mention | None = None
        self.source: Mention | None = None
        self.recipient: Mention | None = None
        self.pronoun: str | None = None
        self.time: str | None = None
        self.day: str | None = None
        self.to_me = False

    def set_owner(self, owner: Mention | None) -> None:
        """Record whose it is (None: nothing to record); two different owners are an error."""
        if owner is None:
            return
        if self.owner is not None and self.owner.concept != owner.concept:
            raise ParseError(self.text, f'it names two owners, "{self.owner.text}" and '
                             f'"{owner.text}"', words=[owner.text])
        self.owner = owner

    def set_destination(self, where: Mention | None, to_me: bool = False) -> None:
        """Record where it goes (``to_me``: to the one asking); a second one is an error."""
        if self.destination is not None or self.to_me:
            second = f'"{where.text}"' if where is not None else "the one asking"
            raise ParseError(self.text, f"it names two destinations (the second is {second})",
                             hint="Give one place or person to go to.")
        self.destination = where
        self.to_me = to_me


# ---- helpers ------------------------------------------------------------------------------
def _all_or_unknown(calls: Sequence[Any]) -> list[Any]:
    """Run every call; if some met unknown words, raise one error naming all of them, so
    "fetch the wizard's scroll" names both words, not just the first."""
    results, unknown = [], []
    for call in calls:
        try:
            results.append(call())
        except _UnknownWords as exc:
            unknown.append(exc)
    if unknown:
        raise _UnknownWords.merge(unknown)
    return results


def _object_slot(action: str) -> str:
    """What the object of an action must be: carried (fetch...), sought (find, where) or
    asked about (who)."""
    if action == "who":
        return "who"
    return "sought" if action in ("find", "where") else "carried"


def _mention(text: str, concept: Concept, fuzzy: bool) -> Mention:
    """A mention of a lexicon concept."""
    return Mention(text=text, concept=concept.local_name, kind=concept.kind, label=concept.label,
                   fuzzy=fuzzy)


def _did_you_mean(lexicon: Lexicon, words: Sequence[str]) -> str:
    """ "Did you mean ...?" for unknown words close to a label: a hint, never a reading."""
    close = [m for w in words for m in difflib.get_close_matches(normalise(w), lexicon.entries,
                                                                  n=1, cutoff=0.7)]
    quoted = " or ".join(f'"{c}"' for c in close)
    return f"Did you mean {quoted}?" if close else ""


def _known(lexicon: Lexicon, slot: str) -> str:
    """Examples of what a slot understands, from the lexicon (one label per concept)."""
    kinds = SLOT_KINDS[slot] & set(KINDS)
    tops = {str(iri) for iri in KINDS.values()}
    seen: dict[str, str] = {}
    for label, (iri, kind) in lexicon.entries.items():
        if kind in kinds and iri not in tops:
            seen.setdefault(iri, label)
    examples = sorted(seen.values(), key=lambda s: (len(s.split()), s))[:8]
    extra = [k for k in ("person", "name") if k in SLOT_KINDS[slot]]
    more = " and people's names" if "person" in extra else ""
    return f"Known words for {SLOT_NAMES[slot]} include {', '.join(examples)}{more}."


def _syntax_error(text: str, prepared: str, exc: UnexpectedInput, lexicon: Lexicon,
                  people: list[tuple[str, frozenset[str]]]) -> ParseError:
    """A ParseError for text that does not follow the grammar, naming where it went wrong.

    The parser stops at the first token it cannot take, which may come after the real
    culprit ("go ot the kitchen" stops at "the"): an earlier word that is neither a
    function word nor a label is named instead.
    """
    if isinstance(exc, UnexpectedEOF) or (isinstance(exc, UnexpectedToken)
                                          and exc.token.type == "$END"):
        last = prepared.rstrip(" ,.!?;:-").split()
        tail = f' after "{last[-1]}"' if last else ""
        return ParseError(text, f"it stops too early{tail}")
    if isinstance(exc, UnexpectedToken):
        start, end = exc.token.start_pos, exc.token.end_pos
    elif isinstance(exc, UnexpectedCharacters):
        start = exc.pos_in_stream
        match = re.match(r"\S+", prepared[start:])
        end = start + (match.end() if match else 1)
    else:  # pragma: no cover - the LALR parser raises only the above
        start, end = 0, len(text)
    start, end = _whole_word(prepared, start, end)
    culprit = _first_unknown(prepared[:start], lexicon, people)
    if culprit is not None:
        return _not_understood(text, *culprit, expected=None)
    expected = getattr(exc, "expected", None) or getattr(exc, "allowed", None) or ()
    return _not_understood(text, start, end, expected=expected)


def _first_unknown(prepared: str, lexicon: Lexicon, people: list[tuple[str, frozenset[str]]]
                   ) -> tuple[int, int] | None:
    """Offsets of the first word that is neither a function word, nor (close to) a label,
    nor part of a person's name."""
    known = set(_keywords()) | TITLES | {w for _, words in people for w in words}
    for match in re.finditer(r"[^\W\d_][\w\-]*", prepared):
        if match.group() not in known and lexicon.resolve(match.group()) is None:
            return match.start(), match.end()
    return None


def _not_understood(text: str, start: int, end: int, expected: Iterable[str] | None
                    ) -> ParseError:
    """ "<word>" is not understood after "<the words before it>", with "did you mean" among
    the function words the grammar ``expected`` there (terminal names; None: no hint)."""
    word = text[start:end]
    before = " ".join(text[:start].split()[-3:])
    where = f'after "{before}"' if before else "at the start"
    close = [] if expected is None else [
        k for k in difflib.get_close_matches(word.lower(), _keywords(expected), n=1, cutoff=0.75)
        if k != word.lower()]
    return ParseError(text, f'"{word}" is not understood {where}', words=[word],
                      hint=f'Did you mean "{close[0]}"?' if close else None)


def _check_whole_words(text: str, prepared: str, tree: Tree) -> None:
    """Refuse a parse that read a function word off the front of a longer word.

    Where the grammar expects only function words the lexer does not look for
    WORD, so "gone" would lex as "go" + "ne"; every token must end where its word
    ends (letters followed by a letter, or digits by a digit, are one word).
    """
    for token in tree.scan_values(lambda v: isinstance(v, Token)):
        end = token.end_pos
        if end >= len(prepared) or not token:
            continue
        nxt, last = prepared[end], token[-1]
        if (last.isalpha() and nxt.isalpha()) or (last.isdigit() and nxt.isdigit()):
            raise _not_understood(text, *_whole_word(prepared, token.start_pos, end),
                                  expected=None)


def _whole_word(prepared: str, start: int, end: int) -> tuple[int, int]:
    """Widen a token to the word around it: where the grammar expects only function
    words, the lexer may have read "a" off the front of "asdf"."""
    while start > 0 and prepared[start - 1].isalnum():
        start -= 1
    while end < len(prepared) and (prepared[end].isalnum() or prepared[end] == "-"):
        end += 1
    return start, end


def _keywords(names: Iterable[str] = ()) -> tuple[str, ...]:
    """The grammar's function words (its literal terminals), only those of the terminal
    ``names`` when given: the words a "did you mean" may offer."""
    wanted = set(names)
    return tuple(sorted({t.pattern.value for t in _parser().terminals
                         if t.pattern.type == "str" and t.pattern.value.isalpha()
                         and (not wanted or t.name in wanted)}))


def _sentence(text: str) -> str:
    """``text`` ending with a full stop (or its own ? or !)."""
    text = text.strip()
    return text if text.endswith((".", "?", "!")) else text + "."
