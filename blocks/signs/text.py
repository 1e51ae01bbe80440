"""Text of door signs: clean up OCR output and snap it onto the place vocabulary.

OCR of a small, blurred, slanted plate makes three kinds of mistakes: it
changes spacing and case ("OFFICE101", "Ward B"), it adds punctuation noise
from the plate's edges and texture ("|MAIL.ROOM"), and it swaps look-alike
glyphs (O/0, I/l/1, S/5, B/8, Z/2, G/6). :func:`normalise` undoes the
first two and fixes the swaps *by context*: inside a token that is mostly
digits a letter becomes its look-alike digit, inside a word a digit becomes
its look-alike letter ("OFF1CE 1O1" -> "OFFICE 101").

:func:`match_vocabulary` then finds the vocabulary text the reading is
closest to (rapidfuzz's Levenshtein ratio, on the spaced and on the compact
form, so dropped or inserted spaces cost nothing). The words of a sign may be
misspelt; its number may not: a pattern's slot (``OFFICE {number}``) takes
the read token verbatim, and a digit the match cannot account for rejects
it, so "OFFICE 10" stays "OFFICE 10" and never becomes a known "OFFICE 101".
"""
from __future__ import annotations

import re
import unicodedata
from dataclasses import dataclass

from rapidfuzz import fuzz, process

from semantic.vocabulary import SLOT_TYPES, Pattern, Vocabulary, compact

__all__ = ["LOOKALIKE_LETTERS", "MIN_SCORE", "SHORT", "Match", "best_match", "match_reading",
           "match_vocabulary", "normalise", "readings", "truncated"]

#: Default acceptance threshold of :func:`match_vocabulary` (a 0..1 similarity).
MIN_SCORE = 0.75
#: Score of a pattern read without the space before its letter slot ("WARDD" ->
#: "WARD D"): every letter is there, but so is the phrase "WARD" with one extra letter.
GLUED = 0.95
#: Phrases (and pattern words) of at most this many letters must be read exactly:
#: one wrong letter in three is no evidence for the word.
SHORT = 3

# look-alike glyphs, applied by context (before upper-casing, so 'l' is still 'l')
_TO_DIGIT = {"O": "0", "o": "0", "Q": "0", "D": "0", "I": "1", "l": "1", "i": "1",
             "S": "5", "s": "5", "B": "8", "Z": "2", "z": "2", "G": "6", "b": "6"}
#: Capitals the OCR writes for a digit (S for 5, B for 8): a slot read as one may be a number.
LOOKALIKE_LETTERS = frozenset(ch for ch in _TO_DIGIT if ch.isupper())
_TO_LETTER = {"0": "O", "1": "I", "5": "S", "8": "B", "2": "Z", "6": "G"}
_APOSTROPHES = "'`\u2018\u2019\u00b4"
_DASHES = "\u2010\u2011\u2012\u2013\u2014\u2212_"
_NOISE = re.compile(r"[^0-9A-Za-z\- ]+")  # everything else is punctuation noise: a space


@dataclass(frozen=True)
class Match:
    """The vocabulary text a reading was snapped onto.

    Attributes
    ----------
    text : str
        The vocabulary text, slot filled with the read value (``"OFFICE 102"``).
    place_class : str
        Its place class (``"Office"``).
    score : float
        Similarity of the reading to the text's words, 0..1 (1 = exact).
    slot : str or None
        The value read into a pattern's slot (``"102"``), None for a phrase.
    """

    text: str
    place_class: str
    score: float
    slot: str | None = None


# ---- normalisation --------------------------------------------------------------------------
def normalise(raw: str, *, glued_digit: str = "letter") -> str:
    """Clean up an OCR string: upper case, single spaces, no punctuation, look-alikes fixed.

    Parameters
    ----------
    raw : str
        What the OCR read, e.g. ``"Off1ce.1O1"``.
    glued_digit : {"letter", "number"}
        What one look-alike digit glued to the end of a word is: a misread
        letter ("STAIR5" -> "STAIRS", the default) or a number whose space
        was lost ("LAB1" -> "LAB 1"). Only the vocabulary can tell:
        :func:`match_reading` tries both.

    Returns
    -------
    str
        Upper-case words of letters, digits and inner hyphens, separated by
        single spaces, e.g. ``"OFFICE 101"``; ``""`` when nothing is left.

    Notes
    -----
    A token mostly of digits (or as many digits as letters, starting with a
    digit) is a number: its look-alike letters become digits. A token mostly
    of letters is a word: its look-alike digits become letters. A word glued
    to a trailing number is split first ("OFFICE1O1" -> "OFFICE 101").
    A single look-alike digit glued to a word is a misread letter
    ("STAIR5" -> "STAIRS") unless ``glued_digit`` says otherwise. Single
    characters are left alone: "WARD 8" may be ward 8 or a misread ward B, and only the
    sign can tell.
    """
    text = unicodedata.normalize("NFKC", str(raw))
    text = "".join(ch for ch in text if ch not in _APOSTROPHES)  # NURSE'S -> NURSES
    text = "".join("-" if ch in _DASHES else ch for ch in text)
    # '|' inside a token is a 1 (or an I); on its own it is a plate edge: noise
    text = re.sub(r"(?<=[0-9A-Za-z])\|(?=[0-9A-Za-z])", "l", text)
    text = _NOISE.sub(" ", text)
    words = []
    for token in text.split():
        words.extend(_fix_token(part) for part in _split_glued(token, glued_digit == "number"))
    return " ".join(w for w in words if w)


def readings(raw: str) -> list[str]:
    """The normalised texts an OCR string may stand for, the more literal first.

    Plates whose letters are spaced out often lose the space before their
    number ("CLASSROOM2", "LAB1"); a word misread with a digit for its last
    letter ("STAIR5") looks the same. Both readings are given, the one that
    keeps the digit first.
    """
    out = []
    for text in (normalise(raw, glued_digit="number"), normalise(raw)):
        if text and text not in out:
            out.append(text)
    return out


def _split_glued(token: str, lone_digit_is_number: bool = False) -> list[str]:
    """Split a word glued to a trailing number: ``OFFICE101`` -> ``[OFFICE, 101]``."""
    if "-" in token:
        return [token]
    i = len(token)
    while i > 0 and (token[i - 1].isdigit() or token[i - 1] in _TO_DIGIT):
        i -= 1
    run = token[i:]
    first_digit = next((k for k, ch in enumerate(run) if ch.isdigit()), None)
    if first_digit is None:
        return [token]
    cut = i + first_digit
    number, word = token[cut:], token[:cut]
    digits = sum(ch.isdigit() for ch in number)
    if digits * 2 < len(number) or sum(ch.isalpha() for ch in word) < 2:
        return [token]
    if len(number) == 1 and number in _TO_LETTER and not lone_digit_is_number:
        return [token]  # STAIR5: one look-alike digit glued on is a misread letter, not a number
    return [word, number]


def _fix_token(token: str) -> str:
    """Fix look-alike glyphs in one token by its majority (see :func:`normalise`)."""
    parts = token.split("-")
    if len(parts) > 1:  # X-RAY: each part on its own; no leading, trailing or double hyphens
        return "-".join(p for p in (_fix_token(p) for p in parts) if p)
    if len(token) <= 1:
        return token.upper()
    digits = sum(ch.isdigit() for ch in token)
    letters = sum(ch.isalpha() for ch in token)
    if digits == 0:
        upper = sum(ch.isupper() for ch in token)
        if "l" in token and upper * 2 > letters:
            token = token.replace("l", "I")  # ADMlN: an l among capitals is an I
        return token.upper()
    if letters == 0:
        return token
    if digits > letters or (digits == letters and token[0].isdigit()):
        return "".join(_TO_DIGIT.get(ch, ch) for ch in token).upper()
    return "".join(_TO_LETTER.get(ch, ch) for ch in token).upper()


# ---- matching -------------------------------------------------------------------------------
def _similarity(read: str, target: str) -> float:
    """0..1 similarity of two word strings, blind to spacing; short targets must be exact."""
    a, b = compact(read), compact(target)
    if not a or not b:
        return 0.0
    if len(b) <= SHORT:
        return 1.0 if a == b else 0.0
    return max(fuzz.ratio(read, target), fuzz.ratio(a, b)) / 100.0


def _slot_value(token: str, slot: str) -> str | None:
    """The slot value a read token gives, or None: the token must *be* the value.

    Look-alikes are fixed by the slot's context (a number slot turns "1O2"
    into "102", a letter slot turns "8" into "B"), but nothing is added or
    dropped, so a short or garbled number never becomes a longer known one.
    """
    if re.fullmatch(SLOT_TYPES[slot], token):
        return token
    if slot == "number" and any(ch.isdigit() for ch in token) and len(token) <= 4:
        value = "".join(_TO_DIGIT.get(ch, ch) for ch in token)
        return value if value.isdigit() else None
    if slot == "letter" and len(token) == 1 and token in _TO_LETTER:
        value = _TO_LETTER[token]
        return value if re.fullmatch(SLOT_TYPES[slot], value) else None
    return None


def _pattern_match(words: list[str], pattern: Pattern) -> Match | None:
    """Match a reading (its words) against a pattern: literal words fuzzily, the slot exactly."""
    n_before = len(pattern.before.split())
    n_after = len(pattern.after.split())
    if n_after == 0 and pattern.slot != "number" and len(words[-1]) > 1:
        # "WARDD": the space before a letter lost; the letters are all there
        packed, literal = compact(" ".join(words)), compact(pattern.before)
        if len(packed) == len(literal) + 1 and packed.startswith(literal) \
                and re.fullmatch(SLOT_TYPES[pattern.slot], packed[-1]):
            return Match(pattern.fill(packed[-1]), pattern.place_class, GLUED, packed[-1])
    if len(words) < 2:
        return None
    if n_after == 0:
        k = len(words) - 1  # slot is the last word
    elif n_before == 0:
        k = 0
    elif len(words) == n_before + 1 + n_after:
        k = n_before
    else:
        return None
    value = _slot_value(words[k], pattern.slot)
    if value is None:
        return None
    rest = words[:k] + words[k + 1:]
    if any(ch.isdigit() for w in rest for ch in w):
        return None  # a digit the match cannot account for: never drop part of a number
    score = _similarity(" ".join(rest), pattern.literal)
    return Match(pattern.fill(value), pattern.place_class, score, value) if score > 0 else None


def best_match(text: str, vocabulary: Vocabulary) -> Match | None:
    """The vocabulary text closest to a normalised reading, whatever its score (None if none).

    Phrases are compared whole; a reading holding a digit matches only a
    pattern whose slot takes that digit's token (or a phrase with digits).
    """
    text = " ".join(text.split())
    if not text:
        return None
    best: Match | None = None
    has_digit = any(ch.isdigit() for ch in text)
    phrases = [p for p in vocabulary.phrases if not has_digit or any(c.isdigit() for c in p)]
    # exact first (short phrases can only match so); spacing is no information, so the
    # reading takes the spelling listed first ("MAILROOM" -> "MAIL ROOM")
    exact = vocabulary.spelling(text) if not has_digit else None
    if exact is not None:
        return Match(exact, vocabulary.phrases[exact], 1.0)
    longer = [p for p in phrases if len(compact(p)) > SHORT]
    if longer:
        spaced = process.extractOne(text, longer, scorer=fuzz.ratio)
        packed = process.extractOne(compact(text), [compact(p) for p in longer],
                                    scorer=fuzz.ratio)
        for phrase, score in ((spaced[0], spaced[1]), (longer[packed[2]], packed[1])):
            if best is None or score / 100.0 > best.score:
                phrase = vocabulary.spelling(phrase) or phrase
                best = Match(phrase, vocabulary.phrases[phrase], score / 100.0)
    words = text.split()
    for pattern in vocabulary.patterns:
        m = _pattern_match(words, pattern)
        if m is not None and (best is None or m.score > best.score):
            best = m
    return best


def match_reading(raw: str, vocabulary: Vocabulary) -> Match | None:
    """The vocabulary text closest to any reading of an OCR string (:func:`readings`).

    The best score wins; on a tie, the reading that keeps a glued digit a
    digit ("LAB5" on a floor with both "LABS" and "LAB {number}" is "LAB 5":
    what the OCR saw was a digit).
    """
    best: Match | None = None
    for text in readings(raw):
        m = best_match(text, vocabulary)
        if m is not None and (best is None or m.score > best.score):
            best = m
    return best


def truncated(raw: str, match: Match) -> bool:
    """Whether a reading is its match's words with letters missing at one end.

    A plate cut by the frame's edge or hidden in part behind a wall reads as
    the start or the end of its text ("CLASSRO" of a CLASSROOM 3 plate, "TROOM"
    of IT ROOM); the fuzzy match would complete the words, but not the number
    or the word that was cut off with them. A letter missing inside the text
    ("MEETINGROO3") is the OCR's slip, not a cut.
    """
    read = compact(normalise(raw))
    words = compact(match.text)
    if match.slot is not None:
        slot = compact(match.slot)
        if not (read.endswith(slot) and words.endswith(slot)):
            return False
        # the slot closes both: only the start can be cut off
        read, words = read[:len(read) - len(slot)], words[:len(words) - len(slot)]
        return len(read) < len(words) and words.endswith(read)
    return len(read) < len(words) and (words.startswith(read) or words.endswith(read))


def match_vocabulary(text: str, vocabulary: Vocabulary, min_score: float = MIN_SCORE
                     ) -> Match | None:
    """Snap a reading onto the vocabulary, or None when nothing is close enough.

    Parameters
    ----------
    text : str
        The reading; it is normalised here too (normalising twice is harmless).
    vocabulary : Vocabulary
        The phrases and patterns to match (:func:`semantic.vocabulary.load_vocabulary`).
    min_score : float
        Least similarity (0..1) to accept. 0.75 allows about one wrong letter
        in four; shorter words and slots must be exact anyway.

    Returns
    -------
    Match or None
        The best vocabulary text, its place class and score; None when the
        best score is below ``min_score`` (garbage, an unknown word, a number
        without its words).
    """
    m = match_reading(text, vocabulary)
    return m if m is not None and m.score >= min_score else None
