"""The sign reader: text normalisation, vocabulary matching, plate rectification and OCR."""
from __future__ import annotations

import math
import sys

import cv2
import numpy as np
import pytest

from blocks.core.errors import SemmapError
from blocks.signs.read import OcrResult, ReaderError, SignReader, plate_size, rectify_plate
from blocks.signs.text import match_reading, match_vocabulary, normalise, truncated
from semantic.vocabulary import VocabularyError, load_vocabulary
from sim2d.camera import CameraSpec, focal_length, render, sign_plate_image, visible_signs
from sim2d.world import Sign, load_world, make_world
from sim2d.worlds import world_path

SPEC = CameraSpec()


@pytest.fixture(scope="module")
def vocab():
    return load_vocabulary()


@pytest.fixture(scope="module")
def reader(vocab):
    return SignReader(vocab)


@pytest.fixture(scope="module")
def worlds():
    return {name: load_world(world_path(name)) for name in ("office", "hospital")}


# ---- normalise ------------------------------------------------------------------------------
@pytest.mark.parametrize("raw, expected", [
    ("OFF1CE 1O1", "OFFICE 101"),  # digit in a word, letter in a number
    ("Off1ce.1O1", "OFFICE 101"),  # case, punctuation between the words
    ("OFFICE101", "OFFICE 101"),  # space lost before the number
    ("  mail   room ", "MAIL ROOM"),
    ("|MAIL.ROOM|", "MAIL ROOM"),  # plate edges read as bars
    ("MA1L R00M", "MAIL ROOM"),
    ("ST4IRS", "ST4IRS"),  # 4 is not a look-alike here: left alone
    ("STAIR5", "STAIRS"),  # one look-alike digit glued to a word is a letter
    ("ADMlN", "ADMIN"),  # an l among capitals is an I
    ("LAB5", "LABS"),  # ... and so is this one ("LAB 5" needs its space)
    ("ROOM12", "ROOM 12"),  # two digits glued on are a number
    ("WARD 8", "WARD 8"),  # a lone character: only the sign can tell 8 from B
    ("NURSE'S STATION", "NURSES STATION"),
    ("x\u2013ray", "X-RAY"),
    ("OFFICE 2O5", "OFFICE 205"),
    ("?!", ""),
])
def test_normalise(raw, expected):
    assert normalise(raw) == expected


# ---- vocabulary -----------------------------------------------------------------------------
def test_vocabulary_covers_the_world_signs_by_class(vocab, worlds):
    for world in worlds.values():
        for sign in world.signs:
            place = vocab.place_class(sign.text)
            assert place is not None, sign.text
            m = match_vocabulary(sign.text, vocab)
            assert m is not None and m.text == sign.text and m.score == 1.0
    assert vocab.place_class("MAIL ROOM") == "MailRoom"
    assert vocab.place_class("MANAGER") == "ManagerOffice"
    assert vocab.place_class("NURSES STATION") == "NursesStation"


def test_vocabulary_is_generic_not_a_copy_of_the_worlds(vocab):
    # numbered and lettered places the worlds do not have, and synonyms
    assert vocab.place_class("OFFICE 205") == "Office"
    assert vocab.place_class("WARD 7") == "Ward"
    assert vocab.place_class("WARD F") == "Ward"
    assert vocab.place_class("CLASSROOM 12") == "Classroom"
    assert vocab.place_class("LIFT") == "Elevator"
    assert vocab.place_class("operating theatre") == "OperatingRoom"
    assert vocab.place_class("X-RAY") == vocab.place_class("XRAY") == "Radiology"
    assert vocab.place_class("TOILETS") == "Toilet"
    assert vocab.place_class("OFFICE 1O1") is None  # exact lookup: no OCR guessing here
    assert vocab.place_class("BANANA") is None
    assert any(p.text == "OFFICE {number}" or p.text == "OFFICE {id}" for p in vocab.patterns)
    assert vocab.entry("Office").is_a == "Room"


@pytest.mark.parametrize("body, field", [
    ("places:\n  - {class: Kitchen, is_a: Room, domains: [office], phrazes: [KITCHEN]}\n",
     "phrazes"),
    ("places:\n  - {class: kitchen, is_a: Room, domains: [office], phrases: [KITCHEN]}\n",
     "class"),
    ("places:\n  - {class: Office, is_a: Room, domains: [office], patterns: ['OFFICE {num}']}\n",
     "patterns"),
    ("places:\n  - {class: Gate, is_a: Room, domains: [generic], phrases: [NO]}\n",  # a bool
     "phrases"),
    (("places:\n  - {class: A, is_a: Room, domains: [office], phrases: [MAIL ROOM]}\n"
      "  - {class: B, is_a: Room, domains: [office], phrases: [MAILROOM]}\n"), "phrases"),
    ("places: []\n", "places"),
])
def test_malformed_vocabulary_names_file_and_field(tmp_path, body, field):
    path = tmp_path / "vocab.yaml"
    path.write_text(body)
    with pytest.raises(VocabularyError) as err:
        load_vocabulary(path)
    assert isinstance(err.value, SemmapError)
    assert err.value.field == field
    text = str(err.value)
    assert str(path) in text and "\n" not in text


# ---- matching -------------------------------------------------------------------------------
def test_match_fixes_confusions_and_spacing(vocab):
    m = match_vocabulary("OFFICE 1O2", vocab)
    assert (m.text, m.place_class, m.score, m.slot) == ("OFFICE 102", "Office", 1.0, "102")
    assert match_vocabulary("NURSESSTATION", vocab).text == "NURSES STATION"
    assert match_vocabulary("MAILROOM", vocab).text == "MAIL ROOM"
    assert match_vocabulary("Ward B", vocab).text == "WARD B"
    assert match_vocabulary("WARDD", vocab).text == "WARD D"  # space before the letter lost
    fuzzy = match_vocabulary("LIBRARV", vocab)
    assert fuzzy.text == "LIBRARY" and 0.75 <= fuzzy.score < 1.0


@pytest.mark.parametrize("raw, expected", [
    ("CLASSROOM2", "CLASSROOM 2"),  # spaced-out letters lose the space before the number:
    ("STORE1", "STORE 1"),  # read as a letter, these were CLASSROOM Z, STORE and LABS
    ("LAB1", "LAB 1"),
    ("CLASSRO0M5", "CLASSROOM 5"),
    ("LAB5", "LAB 5"),  # LABS and LAB 5 both exist: the OCR saw a digit
    ("STAIR5", "STAIRS"),  # no STAIR {number}: a misread letter
    ("WARDD", "WARD D"),
])
def test_a_glued_digit_is_what_the_vocabulary_makes_of_it(vocab, raw, expected):
    assert match_vocabulary(raw, vocab).text == expected


def test_numbers_are_read_exactly_never_invented(vocab):
    assert match_vocabulary("OFFICE 10", vocab).text == "OFFICE 10"  # not a known OFFICE 101
    assert match_vocabulary("OFFICE 1 1", vocab) is None  # a stray digit: no reading
    assert match_vocabulary("LIBRARY 2", vocab) is None  # nor is the number dropped
    assert match_vocabulary("101", vocab) is None  # a number alone names no place


def test_no_match_for_garbage_unknown_words_or_short_misreads(vocab):
    for text in ("XQZW KL", "BANANA", "", "  ", "LB", "ICO", "IC"):
        assert match_vocabulary(text, vocab) is None, text
    assert match_vocabulary("ICU", vocab).text == "ICU"
    assert match_vocabulary("LIBRARV", vocab, min_score=0.9) is None  # the threshold holds


@pytest.mark.parametrize("raw, cut", [
    ("CLASSRO", True),  # the end of the plate cut off: its number may have gone with it
    ("TROOM", True),  # IT ROOM hidden in part behind a wall's edge
    ("CONSULTING ROO", True),
    ("ONSULTING ROOM 2", True),  # a number read, but the plate's start is lost
    ("MEETINGROO3", False),  # a letter missing inside: the OCR's slip, not a cut
    ("MAILROOM", False),
    ("MEETING ROOM", False),
    ("LIBRARV", False),
    ("WARDD", False),
])
def test_a_reading_cut_at_an_end_is_told_from_a_misspelt_one(vocab, raw, cut):
    assert truncated(raw, match_reading(raw, vocab)) is cut


def test_a_patterns_words_alone_may_lack_the_slot(vocab):
    assert vocab.may_lack_slot("MEETING ROOM") and vocab.may_lack_slot("office")
    assert not vocab.may_lack_slot("LIBRARY") and not vocab.may_lack_slot("MEETING ROOM 2")


class ScriptedReader(SignReader):
    """A reader whose OCR reads each view as scripted: ``{view: (text, score)}``."""

    def __init__(self, vocabulary, script):
        super().__init__(vocabulary)
        self.script = script

    def _crops(self, image, corners):
        return [(name, lambda name=name: name) for name in self.views]

    def ocr(self, image, detect=True):
        text, score = self.script[image]
        return OcrResult(text, score, 1, None)


def scripted_read(vocab, **script):
    return ScriptedReader(vocab, script).read(np.zeros((20, 60, 3), np.uint8))


def test_a_confident_reading_missing_its_number_asks_the_other_views(vocab):
    """The line view loses a small trailing digit at the crop's edge ("MEETING ROOM" of a
    MEETING ROOM 3 plate); the rectified view, with its margin, reads it."""
    r = scripted_read(vocab, line=("MEETING ROOM", 0.95), rectified=("MEETING ROOM3", 0.9),
                      bbox=("MEETINGROOM", 0.9))
    assert r.text == "MEETING ROOM 3" and r.confidence > 0.75
    assert r.extra["views_tried"] == ["line", "rectified"]
    whole = scripted_read(vocab, line=("LIBRARY", 0.95), rectified=("LIBRARV", 0.9),
                          bbox=("LIBRARY", 0.9))
    assert whole.text == "LIBRARY" and whole.extra["views_tried"] == ["line"]


def test_a_slot_read_as_a_look_alike_letter_must_agree_with_the_other_views(vocab):
    r = scripted_read(vocab, line=("MEETING ROOM S", 0.95), rectified=("MEETING ROOM 5", 0.9),
                      bbox=("MEETING ROOM5", 0.9))
    assert r.confidence < 0.5  # S or 5: the views disagree, and the reading is not trusted
    ward = scripted_read(vocab, line=("WARD B", 0.95), rectified=("WARD B", 0.9),
                         bbox=("WARDB", 0.9))
    assert ward.text == "WARD B" and ward.confidence > 0.75


def test_a_plate_whose_text_is_cut_off_is_not_read(vocab):
    """Where the rectified plate's text stops short, the quad holds part of a plate:
    no view's reading of it is trusted, however whole it looks."""
    r = scripted_read(vocab, line=("CLASSRO", 0.95), rectified=("CLASSRO", 0.9),
                      bbox=("CLASSROOM", 0.95))
    assert r.text == "" and r.confidence == 0.0 and r.extra["cut"]
    # the loose bbox view dropping a slanted plate's last letter is no cut
    s = scripted_read(vocab, line=("STAIRWAY", 0.6), rectified=("STAIRWAY", 0.6),
                      bbox=("STAIRWA", 0.9))
    assert s.text == "STAIRWAY" and not s.extra["cut"]


# ---- rectification --------------------------------------------------------------------------
def test_rectify_plate_undoes_a_perspective_warp():
    texture = sign_plate_image("OFFICE 101", 300, 100)
    quad = np.array([[40.0, 30.0], [250.0, 60.0], [245.0, 140.0], [45.0, 150.0]])
    src = np.array([[-0.5, -0.5], [299.5, -0.5], [299.5, 99.5], [-0.5, 99.5]], np.float32)
    M = cv2.getPerspectiveTransform(src, quad.astype(np.float32))
    canvas = cv2.warpPerspective(texture, M, (300, 200), borderValue=(150, 178, 196))
    out = rectify_plate(canvas, quad, out_height=64, margin=0.0)
    assert out.shape == (64, 192, 3)
    expected = cv2.resize(texture, (192, 64), interpolation=cv2.INTER_AREA)
    grey = [cv2.cvtColor(x, cv2.COLOR_BGR2GRAY).astype(float).ravel() for x in (out, expected)]
    assert np.corrcoef(*grey)[0, 1] > 0.9
    mirrored = rectify_plate(canvas, quad[[1, 0, 3, 2]], out_height=64, margin=0.0)
    grey_m = cv2.cvtColor(mirrored, cv2.COLOR_BGR2GRAY).astype(float).ravel()
    assert np.corrcoef(grey_m, grey[1])[0, 1] < 0.7  # the corner order matters
    margin = rectify_plate(canvas, quad, out_height=64)  # default margin: 15 % a side
    assert margin.shape == (64 + 2 * 10, 192 + 2 * 10, 3)
    assert plate_size(quad) == pytest.approx(min(115.0, 205.0 / 3), rel=0.05)


# ---- reading rendered plates ----------------------------------------------------------------
def _shot(world, text, distance, angle_deg, plate_px=None, zoom=None, seed=0):
    """Frame and ground truth of one sign seen from ``distance`` at ``angle_deg`` off its normal."""
    index = next(i for i, s in enumerate(world.signs) if s.text == text)
    sign = world.signs[index]
    a = sign.facing + math.radians(angle_deg)
    cam_xy = (sign.x + distance * math.cos(a), sign.y + distance * math.sin(a))
    cam = (*cam_xy, math.atan2(sign.y - cam_xy[1], sign.x - cam_xy[0]))
    tilt = math.atan2(sign.z - SPEC.mount_z, distance)
    if zoom is None:  # the plate about plate_px tall
        zoom = min(max(plate_px * distance / (focal_length(SPEC, 1.0) * sign.height), 1.0), 10.0)
    img = render(world, cam, tilt, zoom, SPEC, np.random.default_rng(seed))
    truth = [v for v in visible_signs(world, cam, tilt, zoom, SPEC) if v["index"] == index]
    assert truth and truth[0]["visible_fraction"] == 1.0, "the test's view does not show the plate"
    return img, truth[0]


GOOD = [  # world, text, distance (m), viewing angle (deg), plate height (px)
    ("office", "OFFICE 102", 1.2, 0, 60),
    ("office", "MAIL ROOM", 2.0, 40, 50),
    ("office", "SERVER ROOM", 1.5, -30, 80),
    ("hospital", "NURSES STATION", 2.5, 20, 45),
    ("hospital", "WARD B", 1.8, -35, 70),
    ("hospital", "RADIOLOGY", 1.0, 10, 45),
]
BAD = [  # almost edge-on; far, blurred and tiny
    ("office", "OFFICE 101", 1.5, 80),
    ("hospital", "PHARMACY", 1.5, 80),
]


def test_reader_reads_rendered_plates_and_is_unsure_of_bad_views(reader, worlds):
    good = []
    for name, text, distance, angle, px in GOOD:
        img, truth = _shot(worlds[name], text, distance, angle, plate_px=px)
        reading = reader.read(img, corners=truth["corners"])
        assert reading.text == text, (text, reading)
        assert reading.extra["place_class"] == reader.vocabulary.place_class(text)
        assert reading.extra["ocr_ms"] > 0
        good.append(reading.confidence)
    bad = []
    for name, text, distance, angle in BAD:
        img, truth = _shot(worlds[name], text, distance, angle, zoom=1.0)
        bad.append((text, reader.read(img, corners=truth["corners"])))
    far_world = make_world([[-8, 0, 8, 0], [8, 0, 8, 14], [8, 14, -8, 14], [-8, 14, -8, 0]],
                           signs=[Sign("LIBRARY", 0.0, 0.1, math.pi / 2)])
    img, truth = _shot(far_world, "LIBRARY", 9.0, 0, zoom=1.0)
    bad.append(("LIBRARY", reader.read(img, corners=truth["corners"])))
    for text, reading in bad:  # empty, or (right or wrong) with little confidence
        assert reading.text == "" or reading.confidence < 0.5, (text, reading)
    assert min(good) > 0.75
    assert min(good) > max(r.confidence for _, r in bad)


def test_reader_without_corners_reads_a_crop(reader, worlds):
    img, truth = _shot(worlds["office"], "OFFICE 102", 1.2, 0, plate_px=60)
    x0, y0, x1, y1 = truth["bbox"]
    reading = reader.read(img[max(0, y0 - 8):y1 + 8, max(0, x0 - 8):x1 + 8])
    assert reading.text == "OFFICE 102" and reading.confidence > 0.5


def test_missing_ocr_package_is_a_clear_user_error(monkeypatch):
    monkeypatch.setitem(sys.modules, "rapidocr_onnxruntime", None)  # import now fails
    with pytest.raises(ReaderError) as err:
        _ = SignReader().engine
    assert isinstance(err.value, SemmapError)
    assert "rapidocr-onnxruntime" in str(err.value)
