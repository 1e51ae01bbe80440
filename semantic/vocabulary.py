"""The indoor place vocabulary: the sign texts the reader may accept, and their place classes.

A door sign names a kind of place ("LIBRARY") or one place of a numbered kind
("OFFICE 101"). The vocabulary lists both as *phrases* (whole texts) and
*patterns* (texts with one slot, ``OFFICE {number}``), each under the place
class it names, so the reader can snap a noisy OCR string onto a known text
and the ontology (issue 7) can reason about what kind of room it labels.

The file format is described at the top of ``semantic/vocabulary.yaml``.
Loading checks every field and raises :class:`VocabularyError` (one
paragraph naming the file, line and field) on the first problem.
"""
from __future__ import annotations

import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from blocks.core.errors import SemmapError
from blocks.core.yamlsrc import line_of, load_versioned_mapping

__all__ = [
    "DEFAULT_PATH",
    "SLOT_TYPES",
    "Pattern",
    "PlaceEntry",
    "Vocabulary",
    "VocabularyError",
    "canonical",
    "compact",
    "load_vocabulary",
    "same_name",
]

DEFAULT_PATH = Path(__file__).with_name("vocabulary.yaml")

#: Slot name -> what the slot's token must be, exactly (upper case). Letters exclude I
#: and O, as signage does: they read as 1 and 0, and a stray I is often a plate's edge.
SLOT_TYPES: dict[str, str] = {
    "number": r"[0-9]{1,4}",
    "letter": r"[A-HJ-NP-Z]",
    "id": r"(?:[0-9]{1,4}|[A-HJ-NP-Z])",
}
ENTRY_KEYS = ("class", "is_a", "domains", "phrases", "patterns")
_CLASS_RE = re.compile(r"[A-Z][A-Za-z0-9]*")
_DOMAIN_RE = re.compile(r"[a-z][a-z0-9_]*")
_WORD_RE = re.compile(r"[A-Z0-9]+(?:-[A-Z0-9]+)*")  # a word of a phrase: LIBRARY, X-RAY
_SLOT_RE = re.compile(r"\{([a-z]+)\}")


class VocabularyError(SemmapError):
    """The place vocabulary file is malformed."""


def canonical(text: str) -> str:
    """Upper case with single spaces: the form phrases are stored and compared in."""
    return " ".join(str(text).upper().split())


def compact(text: str) -> str:
    """Letters and digits only (``"X-RAY"`` -> ``"XRAY"``, ``"MAIL ROOM"`` -> ``"MAILROOM"``).

    OCR drops and inserts spaces freely, so spelling is compared on this form too.
    """
    return "".join(ch for ch in str(text).upper() if ch.isalnum())


def same_name(a: str, b: str) -> bool:
    """Whether two sign or place names are one name: case and spacing say nothing.

    Why: a plate's ``POSTROOM`` is read ``POST ROOM`` (the vocabulary's
    spelling); every scorer that compares a name read with a name true asks
    this, so a sign read exactly is also a place planned to exactly.

    >>> same_name("POST ROOM", "Postroom"), same_name("WARD 2", "WARD B")
    (True, False)
    """
    return "".join(str(a).upper().split()) == "".join(str(b).upper().split())


@dataclass(frozen=True)
class Pattern:
    """A sign text with one slot, e.g. ``OFFICE {number}``.

    Attributes
    ----------
    text : str
        The pattern as written (canonical), e.g. ``"OFFICE {number}"``.
    place_class : str
    before, after : str
        The literal words before and after the slot (``""`` when none).
    slot : str
        The slot's type, a key of :data:`SLOT_TYPES`.
    """

    text: str
    place_class: str
    before: str
    after: str
    slot: str

    @property
    def literal(self) -> str:
        """The words without the slot, e.g. ``"OFFICE"``."""
        return " ".join(part for part in (self.before, self.after) if part)

    @property
    def slot_regex(self) -> str:
        return SLOT_TYPES[self.slot]

    def fill(self, value: str) -> str:
        """The sign text with the slot filled, e.g. ``fill("101") == "OFFICE 101"``."""
        return " ".join(part for part in (self.before, value, self.after) if part)

    def fullmatch(self, text: str) -> str | None:
        """The slot's value when ``text`` is exactly this pattern (canonical form), else None."""
        parts = [re.escape(self.before)] if self.before else []
        parts.append(f"({self.slot_regex})")
        if self.after:
            parts.append(re.escape(self.after))
        m = re.fullmatch(" ".join(parts), canonical(text))
        return m.group(1) if m else None


@dataclass(frozen=True)
class PlaceEntry:
    """One place class of the vocabulary and the sign texts that name it."""

    place_class: str
    is_a: str
    domains: tuple[str, ...]
    phrases: tuple[str, ...]
    patterns: tuple[Pattern, ...]
    line: int | None = None


class Vocabulary:
    """The place classes and the sign texts (phrases and patterns) that name them.

    Parameters
    ----------
    entries : iterable of PlaceEntry
    source : path, optional
        Where the entries came from (for messages).
    """

    def __init__(self, entries: Iterable[PlaceEntry], source: str | Path | None = None) -> None:
        self.entries: tuple[PlaceEntry, ...] = tuple(entries)
        self.source = str(source) if source is not None else None
        self._by_class = {e.place_class: e for e in self.entries}
        self.phrases: dict[str, str] = {p: e.place_class for e in self.entries for p in e.phrases}
        self.patterns: tuple[Pattern, ...] = tuple(p for e in self.entries for p in e.patterns)
        self._first_spelling: dict[str, str] = {}  # compact form -> phrase listed first
        for phrase in self.phrases:
            self._first_spelling.setdefault(compact(phrase), phrase)
        self._slotless = {compact(p.literal) for p in self.patterns}  # "MEETINGROOM", ...

    def __len__(self) -> int:
        return len(self.entries)

    def __repr__(self) -> str:
        return (f"Vocabulary({len(self.entries)} classes, {len(self.phrases)} phrases, "
                f"{len(self.patterns)} patterns, source={self.source!r})")

    @property
    def classes(self) -> list[str]:
        """The place class names, in file order."""
        return [e.place_class for e in self.entries]

    def entry(self, place_class: str) -> PlaceEntry:
        """The entry of a place class (KeyError if unknown)."""
        return self._by_class[place_class]

    def spelling(self, text: str) -> str | None:
        """The phrase listed first among those spelt like ``text`` ignoring spaces and
        hyphens (``"MAILROOM"`` -> ``"MAIL ROOM"``), or None: one canonical text per sign."""
        return self._first_spelling.get(compact(text))

    def may_lack_slot(self, text: str) -> bool:
        """Whether ``text`` is a pattern's words without its slot ("MEETING ROOM" of
        ``MEETING ROOM {id}``): a reading of it may have lost the plate's number."""
        return compact(text) in self._slotless

    def place_class(self, text: str) -> str | None:
        """The place class a sign text names exactly, or None.

        Case and spacing do not matter (``"mail room"``, ``"MAILROOM"``); the
        spelling and any slot must be exact: fuzzy matching of OCR output is
        the reader's job (:func:`blocks.signs.text.match_vocabulary`).
        """
        text = canonical(text)
        if text in self.phrases:
            return self.phrases[text]
        found = self._first_spelling.get(compact(text))
        if found is not None:
            return self.phrases[found]
        for pattern in self.patterns:
            if pattern.fullmatch(text) is not None:
                return pattern.place_class
        return None


# ---- loading --------------------------------------------------------------------------------
def load_vocabulary(path: str | Path | None = None) -> Vocabulary:
    """Load a place vocabulary (default: the packaged ``semantic/vocabulary.yaml``).

    Raises
    ------
    VocabularyError
        When the file is missing, is not YAML, or any entry is malformed; the
        message names the file, the line and the field.
    """
    path = Path(path) if path is not None else DEFAULT_PATH
    doc = load_versioned_mapping(
        path, VocabularyError, what="a vocabulary file", fields=("places",),
        missing_hint="Give the path of a vocabulary YAML, or none for the packaged "
                     "semantic/vocabulary.yaml.")
    places = doc.get("places")
    if not isinstance(places, list) or not places:
        raise VocabularyError("'places' must be a non-empty list of place entries", file=path,
                              line=line_of(doc, "places") if "places" in doc else line_of(doc),
                              field="places")
    entries: list[PlaceEntry] = []
    owner: dict[str, tuple[str, str]] = {}  # compact phrase / pattern -> (class, as written)
    for i, raw in enumerate(places):
        entry = _entry(raw, path, line_of(places, i), i)
        if any(e.place_class == entry.place_class for e in entries):
            raise VocabularyError(f"place class {entry.place_class!r} is given twice", file=path,
                                  line=entry.line, field="class",
                                  hint="Merge the two entries into one.")
        texts = [(compact(p), p, "phrases") for p in entry.phrases]
        texts += [(p.text, p.text, "patterns") for p in entry.patterns]
        for key, written, field_name in texts:
            other = owner.get(key)
            if other is not None and other[0] != entry.place_class:
                raise VocabularyError(
                    f"{field_name[:-1]} {written!r} of {entry.place_class} is the same text as "
                    f"{other[1]!r} of {other[0]} (ignoring spaces and hyphens), so a sign "
                    "reading it could not be classified",
                    file=path, line=entry.line, field=field_name,
                    hint="Keep the text under one class only.")
            owner[key] = (entry.place_class, written)
        entries.append(entry)
    return Vocabulary(entries, source=path)


def _entry(raw: Any, path: Path, line: int | None, index: int) -> PlaceEntry:
    """Check and build one entry of the ``places`` list."""
    if not isinstance(raw, Mapping):
        raise VocabularyError(f"place entry {index + 1} must be a mapping with 'class', 'is_a', "
                              f"'domains' and 'phrases' or 'patterns', got {raw!r}",
                              file=path, line=line, field="places")
    line = line_of(raw) or line
    for key in raw:
        if key not in ENTRY_KEYS:
            import difflib
            close = difflib.get_close_matches(str(key), ENTRY_KEYS, n=1)
            raise VocabularyError(f"unknown field {key!r} in place entry {index + 1}", file=path,
                                  line=line_of(raw, key), field=str(key),
                                  hint=f"Did you mean {close[0]!r}?" if close else
                                  f"Known fields: {', '.join(ENTRY_KEYS)}.")

    def where(key: str) -> dict[str, Any]:
        return {"file": path, "line": line_of(raw, key) if key in raw else line, "field": key}

    names = {}
    for key in ("class", "is_a"):
        value = raw.get(key)
        if not isinstance(value, str) or not _CLASS_RE.fullmatch(value):
            raise VocabularyError(f"'{key}' of place entry {index + 1} must be a class name in "
                                  f"UpperCamelCase (e.g. MailRoom), got {value!r}", **where(key))
        names[key] = value
    domains = raw.get("domains")
    if (not isinstance(domains, list) or not domains
            or not all(isinstance(d, str) and _DOMAIN_RE.fullmatch(d) for d in domains)):
        raise VocabularyError(f"'domains' of {names['class']} must be a non-empty list of lower "
                              f"case names (generic, office, hospital, school), got {domains!r}",
                              **where("domains"))
    phrases = _texts(raw, "phrases", names["class"], where)
    patterns = tuple(_pattern(text, names["class"], where)
                     for text in _texts(raw, "patterns", names["class"], where))
    if not phrases and not patterns:
        raise VocabularyError(f"place entry {names['class']} has neither 'phrases' nor "
                              "'patterns': no sign could name it", **where("phrases"))
    return PlaceEntry(place_class=names["class"], is_a=names["is_a"], domains=tuple(domains),
                      phrases=phrases, patterns=patterns, line=line)


def _texts(raw: Mapping, key: str, cls: str, where) -> tuple[str, ...]:
    """The canonical texts of a ``phrases`` or ``patterns`` list (empty when absent)."""
    if key not in raw:
        return ()
    values = raw[key]
    if not isinstance(values, list):
        raise VocabularyError(f"'{key}' of {cls} must be a list of texts, got {values!r}",
                              **where(key))
    out = []
    for value in values:
        if not isinstance(value, str) or not value.strip():
            raise VocabularyError(f"'{key}' of {cls} must hold texts, got {value!r}",
                                  **where(key), hint="Quote texts YAML would read otherwise "
                                                     "(numbers, YES/NO/ON/OFF).")
        if key == "patterns":  # slots stay lower case: OFFICE {number}
            text = " ".join(w.lower() if "{" in w else w.upper() for w in value.split())
            words = _SLOT_RE.sub("X", text).split()
        else:
            text = canonical(value)
            words = text.split()
        if not all(_WORD_RE.fullmatch(w) for w in words):
            raise VocabularyError(f"{key[:-1]} {value!r} of {cls} may hold only letters, digits, "
                                  "spaces and hyphens (and {slot} in patterns)", **where(key))
        if text in out:
            raise VocabularyError(f"{key[:-1]} {value!r} of {cls} is given twice", **where(key))
        out.append(text)
    return tuple(out)


def _pattern(text: str, cls: str, where) -> Pattern:
    """Parse ``"OFFICE {number}"``: exactly one whole-word slot of a known type."""
    words = text.split()
    slots = [i for i, w in enumerate(words) if "{" in w or "}" in w]
    if len(slots) != 1 or not _SLOT_RE.fullmatch(words[slots[0]]):
        raise VocabularyError(f"pattern {text!r} of {cls} must hold exactly one slot as a whole "
                              f"word ({', '.join('{' + s + '}' for s in SLOT_TYPES)})",
                              **where("patterns"))
    k = slots[0]
    slot = words[k][1:-1]
    if slot not in SLOT_TYPES:
        raise VocabularyError(f"pattern {text!r} of {cls} has an unknown slot {{{slot}}}",
                              **where("patterns"),
                              hint=f"Known slots: {', '.join('{' + s + '}' for s in SLOT_TYPES)}.")
    if len(words) < 2:
        raise VocabularyError(f"pattern {text!r} of {cls} needs at least one word besides its "
                              "slot", **where("patterns"))
    canonical_text = " ".join(words[:k] + ["{" + slot + "}"] + words[k + 1:])
    return Pattern(text=canonical_text, place_class=cls, before=" ".join(words[:k]),
                   after=" ".join(words[k + 1:]), slot=slot)
