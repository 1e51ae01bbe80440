"""The textual sign reader: rectify a plate, OCR it, and snap the text onto the vocabulary.

The detector hands over the plate's quadrilateral in a zoomed frame. The
reader warps that quad to a fronto-parallel 3:1 plate image (so slant and
perspective are gone before the OCR sees the text), runs RapidOCR (PP-OCRv4
recognition, and detection when needed; ONNX models shipped inside the
``rapidocr_onnxruntime`` wheel: nothing is downloaded), cleans the string up
and matches it against the place vocabulary (:mod:`blocks.signs.text`).

Views, in order, until one is confident enough and complete (a pattern's words
alone, "MEETING ROOM", may have lost the plate's number at the crop's edge, and a
slot read as a look-alike letter, "ROOM S", may be a digit: both ask the next views):

``line``
    The plate inside its border, grey and contrast-stretched, given to the
    recogniser alone as one line of text (~25 ms). A plate holds one line, so
    the detector is not needed; it would split "WARD D" and drop the lone "D".
``rectified``
    The warped plate with a margin, through detector and recogniser: it
    survives a quad that is a little off, which cuts letters from ``line``.
``bbox``
    The unwarped box around the quad, scaled up: no warp artefacts at all.

Confidence of a view = vocabulary match score x OCR score, where the OCR
score is bounded by the least sure character of a slot ("OFFICE 1?2": the
number must be read exactly). Then the reading's confidence is scaled by the
plate's legibility (its effective size in pixels, :func:`plate_size`) and cut
when two views read different texts. A clean read of a known text scores
near 1, a fuzzy correction ("LIBRARV" -> "LIBRARY") costs in proportion, and a
reading matching nothing scores 0: the correlation stage weighs readings by it.
A rectified view whose text stops short of its match's ("CLASSRO" of CLASSROOM,
"TROOM" of IT ROOM: :func:`~blocks.signs.text.truncated`) shows a plate cut by
the frame or hidden in part behind a wall, and the whole reading is dropped:
what the other views make of the rest is no better, and a cut plate would be a
false sign (its number, or its first word, lost).
"""
from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from blocks.core.errors import SemmapError
from semantic.vocabulary import Vocabulary, load_vocabulary

from .text import LOOKALIKE_LETTERS, MIN_SCORE, Match, match_reading, truncated
from .types import PLATE_HEIGHT, PLATE_WIDTH, Reading

__all__ = ["OCR_OPTIONS", "VIEWS", "OcrResult", "ReaderError", "SignReader", "bbox_crop",
           "plate_line", "plate_size", "rectify_plate"]

ASPECT = PLATE_WIDTH / PLATE_HEIGHT  # 3:1
VIEWS = ("line", "rectified", "bbox")
#: Legibility of a plate by its effective size in the frame, ``min(height, width / 3)``
#: (px; foreshortening narrows the letters): the OCR's own score is overconfident on
#: tiny plates (rendered plates: ~10 % wrong reads at 8-12 px, 1 % or less from 14 px),
#: so the confidence is scaled by a ramp from 0 at ILLEGIBLE_PX to 1 at LEGIBLE_PX.
ILLEGIBLE_PX = 4.0
LEGIBLE_PX = 14.0
BORDER = 0.07  # the plate's dark border and a little more, as a fraction of its height
#: RapidOCR options: plates are rectified upright, so no angle classifier; the
#: detector runs at 128 px on the short side (its default 736 px is for
#: documents and costs ~10x more here); boxes down to an OCR score of 0.3 are
#: kept so that poor readings come back as low-confidence text, not silence.
#: (ONNX Runtime threads: see ``SignReader(threads=...)``.)
OCR_OPTIONS: dict[str, Any] = {
    "use_cls": False,
    "print_verbose": False,
    "text_score": 0.3,
    "det_limit_side_len": 128,
    "det_limit_type": "min",
}


class ReaderError(SemmapError):
    """The OCR engine is missing or cannot start."""


# ---- image preparation ----------------------------------------------------------------------
def rectify_plate(image: np.ndarray, corners, out_height: int = 64,
                  margin: float = 0.15) -> np.ndarray:
    """Warp a plate's quadrilateral to a fronto-parallel 3:1 plate image.

    Parameters
    ----------
    image : ndarray (H, W[, 3]) uint8
    corners : array-like (4, 2)
        Pixel corners top-left, top-right, bottom-right, bottom-left (image
        order, pixel centres at integers, as :class:`~blocks.signs.types.PlateDetection`).
    out_height : int
        Height of the plate itself in the output (px); its width is 3x that.
    margin : float
        Extra border around the plate, as a fraction of ``out_height`` on each
        side: the OCR's detector finds text poorly when it touches the edge,
        and a slightly wrong quad still keeps the letters inside.

    Returns
    -------
    ndarray (out_height + 2 m, 3 out_height + 2 m[, 3]) uint8, ``m = round(margin * out_height)``
        Pixels outside the source image repeat its edge.
    """
    if out_height < 8:
        raise ValueError(f"out_height must be at least 8 px, got {out_height}")
    quad = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    if not np.all(np.isfinite(quad)):
        raise ValueError(f"plate corners must be finite, got {quad.tolist()}")
    h = int(out_height)
    w = round(ASPECT * h)
    m = round(margin * h)
    dst = np.array([[m, m], [m + w, m], [m + w, m + h], [m, m + h]], dtype=np.float64) - 0.5
    M = cv2.getPerspectiveTransform(quad.astype(np.float32), dst.astype(np.float32))
    # shrinking a big plate: smooth first, or the warp aliases the strokes away
    src_height = (np.hypot(*(quad[3] - quad[0])) + np.hypot(*(quad[2] - quad[1]))) / 2
    src = image
    if src_height > 2.0 * h:
        src = cv2.GaussianBlur(image, (0, 0), 0.4 * src_height / h)
    return cv2.warpPerspective(src, M, (w + 2 * m, h + 2 * m), flags=cv2.INTER_CUBIC,
                               borderMode=cv2.BORDER_REPLICATE)


def plate_size(corners) -> float:
    """Effective size of a plate in the frame (px): ``min(height, width / 3)``.

    The height is the mean of the left and right edges, the width the mean of
    the top and bottom ones; a plate seen obliquely is narrow, and its letters
    with it, so the smaller of the two says how many pixels a letter gets.
    """
    c = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    height = (np.hypot(*(c[3] - c[0])) + np.hypot(*(c[2] - c[1]))) / 2
    width = (np.hypot(*(c[1] - c[0])) + np.hypot(*(c[2] - c[3]))) / 2
    return float(min(height, width / ASPECT))


def plate_line(image: np.ndarray, corners, out_height: int = 64) -> np.ndarray:
    """The rectified plate inside its border, grey, contrast stretched: one line of text
    for the recogniser alone (``(out_height - 2 b, 3 out_height - 2 b)`` uint8).

    A door plate holds one line, so when its quad is known the text detector
    is not needed, and it can do harm: it may cut "WARD D" into two boxes and
    misread the lone letter, which the recogniser reads right in context.
    """
    plate = rectify_plate(image, corners, out_height, margin=0.0)
    b = max(1, round(BORDER * out_height))
    inner = plate[b:-b, b:-b]
    if inner.ndim == 3:
        inner = cv2.cvtColor(inner, cv2.COLOR_BGR2GRAY)
    return _stretch(inner)


def bbox_crop(image: np.ndarray, corners, out_height: int = 96,
              margin: float = 0.15) -> np.ndarray:
    """The axis-aligned box around a quad (plus a margin), scaled to ``out_height`` px.

    The unwarped view of the plate: the OCR then sees the text as the camera
    did, which helps when the quad is off (a wrong quad distorts the letters).
    """
    quad = np.asarray(corners, dtype=np.float64).reshape(4, 2)
    (x0, y0), (x1, y1) = quad.min(axis=0), quad.max(axis=0)
    pad = margin * max(y1 - y0, 1.0)
    H, W = image.shape[:2]
    x0, x1 = max(0, math.floor(x0 - pad)), min(W, math.ceil(x1 + pad) + 1)
    y0, y1 = max(0, math.floor(y0 - pad)), min(H, math.ceil(y1 + pad) + 1)
    crop = image[y0:y1, x0:x1]
    if crop.size == 0:
        return np.zeros((out_height, out_height, *image.shape[2:]), dtype=image.dtype)
    scale = out_height / crop.shape[0]
    size = (max(1, round(crop.shape[1] * scale)), int(out_height))
    return cv2.resize(crop, size, interpolation=cv2.INTER_CUBIC if scale > 1 else cv2.INTER_AREA)


def _stretch(image: np.ndarray) -> np.ndarray:
    """Stretch contrast between the 1st and 99th grey percentiles (far plates are dim)."""
    lo, hi = np.percentile(image, (1, 99))
    if hi - lo < 8:
        return image
    return cv2.convertScaleAbs(image, alpha=255.0 / (hi - lo), beta=-255.0 * lo / (hi - lo))


# ---- the reader -----------------------------------------------------------------------------
@dataclass(frozen=True)
class OcrResult:
    """What the OCR read in one crop.

    Attributes
    ----------
    text : str
        The text, boxes joined left to right ('' when none).
    score : float
        The recogniser's mean character probability (one line), or the least
        box score (several boxes).
    boxes : int
        Number of text boxes (1 for a line read whole).
    probs : ndarray or None
        Each character's probability, aligned with ``text`` (line reads only).
    """

    text: str
    score: float
    boxes: int
    probs: np.ndarray | None = None

    def slot_probability(self, match: Match) -> float | None:
        """Least probability of the characters read into ``match``'s slot (None if unknown).

        The slot is the match's trailing word when the text ends with it (all
        the packaged patterns), else any character of the reading counts.
        """
        if match.slot is None or self.probs is None:
            return None
        chars = [i for i, ch in enumerate(self.text) if ch.isalnum()]
        n = len(match.slot)
        if match.text.endswith(match.slot) and len(chars) >= n:
            chars = chars[-n:]
        return float(min(self.probs[i] for i in chars)) if chars else None


@dataclass(frozen=True)
class _View:
    """What one crop of the plate read as."""

    name: str
    raw: str
    ocr_score: float
    boxes: int
    guess: Match | None  # the closest vocabulary text, accepted or not
    matched: Match | None  # the accepted one
    confidence: float
    cut: bool = False  # the text read is its match's with an end cut off ("CLASSRO")


class SignReader:
    """Reads door-sign plates: rectify, OCR (RapidOCR), normalise, match the vocabulary.

    The OCR engine loads once, on the first read (about 0.2 s; the models are
    in the ``rapidocr_onnxruntime`` wheel).

    Parameters
    ----------
    vocabulary : Vocabulary, optional
        The sign texts to accept (default: the packaged vocabulary).
    min_score : float
        Least vocabulary match score to accept a reading.
    out_height : int
        Plate height (px) of the rectified image given to the OCR.
    views : sequence of str
        The crops to try, in order, some of ``"line"``, ``"rectified"`` and
        ``"bbox"`` (see the module's docstring). The reader stops at the first
        view whose confidence reaches ``good_enough`` and otherwise keeps the
        most confident one.
    good_enough : float
        Confidence at which the remaining views are skipped.
    threads : int or None
        ONNX Runtime threads per inference; None lets it take every core. One
        is as fast for these small inputs when the machine is idle, and much
        faster when it is busy (the rest of the dataflow runs too).
    """

    def __init__(self, vocabulary: Vocabulary | None = None, min_score: float = MIN_SCORE,
                 out_height: int = 64, views: Sequence[str] = VIEWS,
                 good_enough: float = 0.75, threads: int | None = 1) -> None:
        unknown = [v for v in views if v not in VIEWS]
        if unknown or not views:
            raise ValueError(f"views must be some of {', '.join(VIEWS)}; got {list(views)}")
        self.vocabulary = vocabulary if vocabulary is not None else load_vocabulary()
        self.min_score = float(min_score)
        self.out_height = int(out_height)
        self.views = tuple(views)
        self.good_enough = float(good_enough)
        self.threads = threads
        self._engine = None

    # -- engine --
    @property
    def engine(self):
        """The RapidOCR engine, built on first use."""
        if self._engine is None:
            self._engine = _make_engine(self.threads)
        return self._engine

    def ocr(self, image: np.ndarray, detect: bool = True) -> OcrResult:
        """Run the OCR on a crop.

        Parameters
        ----------
        image : ndarray (H, W[, 3]) uint8
        detect : bool
            Find text boxes first (RapidOCR's detector) and join them left to
            right; without it the whole crop is recognised as one line of text,
            which also gives each character's probability.
        """
        engine = self.engine
        if image.ndim == 2:
            image = cv2.cvtColor(image, cv2.COLOR_GRAY2BGR)
        if not detect:
            try:  # the recogniser itself, for per-character probabilities
                (text, score, info), = engine.text_rec(image, True)[0]
                probs = np.asarray(info[4], dtype=np.float64)
                if len(probs) != len(text):
                    raise ValueError("character probabilities do not match the text")
            except (AttributeError, TypeError, ValueError, IndexError):  # another rapidocr
                result, _ = engine(image, use_det=False)
                text, score = (str(result[0][0]), float(result[0][1])) if result else ("", 0.0)
                probs = None
            keep = [i for i, ch in enumerate(text) if not ch.isspace()]
            lo, hi = (keep[0], keep[-1] + 1) if keep else (0, 0)
            text = text[lo:hi]
            probs = probs[lo:hi] if probs is not None else None
            return OcrResult(text, float(score) if text else 0.0, int(bool(text)), probs)
        try:  # detector and recogniser by hand, for per-character probabilities
            boxes, _ = engine.text_det(image)
            if boxes is None or len(boxes) == 0:
                return OcrResult("", 0.0, 0, None)
            boxes = sorted(boxes, key=lambda b: float(np.mean(np.asarray(b)[:, 0])))
            lines, _ = engine.text_rec(engine.get_crop_img_list(image, boxes), True)
            items = [(str(t), float(sc), np.asarray(info[4], dtype=np.float64))
                     for t, sc, info in lines]
            if any(len(p) != len(t) for t, _, p in items):
                raise ValueError("character probabilities do not match the text")
        except (AttributeError, TypeError, ValueError, IndexError):  # another rapidocr
            result, _ = engine(image)
            items = [(str(r[1]), float(r[2]), None) for r in sorted(
                result or [], key=lambda r: float(np.mean(np.asarray(r[0])[:, 0])))]
        items = [(t.strip(), sc, p[len(t) - len(t.lstrip()):len(t.rstrip())] if p is not None
                  else None) for t, sc, p in items if sc >= engine.text_score and t.strip()]
        if not items:
            return OcrResult("", 0.0, 0, None)
        text = " ".join(t for t, _, _ in items)
        probs = None
        if all(p is not None for _, _, p in items):  # a space between boxes is certain
            probs = np.concatenate([np.append(p, 1.0) for _, _, p in items])[:-1]
        # a reading is only as good as its weakest box (often the lone number or letter)
        return OcrResult(text, min(sc for _, sc, _ in items), len(items), probs)

    # -- reading --
    def read(self, image: np.ndarray, corners=None, vocabulary: Vocabulary | None = None
             ) -> Reading:
        """Read one plate.

        Parameters
        ----------
        image : ndarray (H, W, 3) uint8
            The frame (or a crop of it) showing the plate.
        corners : array-like (4, 2), optional
            The plate's quad in ``image`` (TL, TR, BR, BL). Without it the
            whole image is read (scaled up when small).
        vocabulary : Vocabulary, optional
            Overrides the reader's vocabulary for this call.

        Returns
        -------
        Reading
            ``raw_text`` as the OCR read it, ``text`` the matched vocabulary
            text ('' when nothing matched), ``confidence`` in [0, 1] (0 when
            nothing matched; see the module's docstring), ``ocr_score`` and
            ``match_score`` of the view used. ``extra`` holds ``ocr_ms`` (OCR
            time, all views), ``view`` (the view used), ``views_tried``,
            ``boxes``, ``place_class``, ``best_guess`` (the closest vocabulary
            text and score, even when rejected), ``plate_px`` and
            ``legibility`` (None without corners) and ``disagreement`` (the
            differing texts of the views, or None).
        """
        image = np.asarray(image)
        if image.ndim not in (2, 3) or image.size == 0:
            raise ValueError(f"image must be an (H, W[, 3]) array, got shape {image.shape}")
        if image.dtype != np.uint8:
            image = np.clip(image, 0, 255).astype(np.uint8)
        vocab = vocabulary if vocabulary is not None else self.vocabulary
        views: list[_View] = []
        ocr_ms = 0.0
        for name, make in self._crops(image, corners):
            crop = make()
            t0 = time.perf_counter()
            res = self.ocr(crop, detect=name != "line")
            ocr_ms += (time.perf_counter() - t0) * 1e3
            guess = match_reading(res.text, vocab)
            matched = guess if guess is not None and guess.score >= self.min_score else None
            # the rectified views hold the plate itself, so where their text stops the plate
            # stops (the loose, unwarped bbox view may drop a slanted plate's edge letter)
            cut = name != "bbox" and matched is not None and truncated(res.text, matched)
            confidence = 0.0
            if matched is not None:
                # the slot must be read exactly: its least sure glyph bounds the confidence
                slot = res.slot_probability(matched)
                confidence = matched.score * (res.score if slot is None else min(res.score, slot))
            views.append(_View(name, res.text, res.score, res.boxes, guess, matched, confidence,
                               cut))
            if confidence >= self.good_enough and not _worth_a_second_view(matched, vocab):
                break
        tried = [v.name for v in views]
        # a view whose text is the start of another's ("WARD" of "WARD D") missed a box:
        # the detector drops lone letters and digits, the line recogniser does not
        texts = [v.matched.text.split() for v in views if v.matched]
        views = [v for v in views if v.matched is None or not any(
            len(t) > len(v.matched.text.split()) and t[:len(v.matched.text.split())]
            == v.matched.text.split() for t in texts)]
        best = max(views, key=lambda v: (v.confidence, v.ocr_score))
        if any(v.cut for v in views):
            # one view shows the plate's text cut off: the quad holds part of a plate (cut
            # by the frame or hidden behind a wall), and what the others read is no better
            best = replace(best, matched=None, confidence=0.0)
        size = legibility = None
        confidence = best.confidence
        if corners is not None:
            size = plate_size(corners)
            legibility = float(np.clip((size - ILLEGIBLE_PX) / (LEGIBLE_PX - ILLEGIBLE_PX), 0, 1))
            confidence *= legibility
        # two views of one plate read as different texts: neither is to be trusted much
        for other in views:
            if other.matched is not None and best.matched is not None \
                    and other.matched.text != best.matched.text:
                confidence *= 1.0 - other.confidence
        matched, guess = best.matched, best.guess
        extra = {"ocr_ms": round(ocr_ms, 2), "view": best.name,
                 "plate_px": None if size is None else round(size, 1), "legibility": legibility,
                 "views_tried": tried, "boxes": best.boxes, "cut": any(v.cut for v in views),
                 "place_class": matched.place_class if matched else None,
                 "best_guess": (guess.text, round(guess.score, 3)) if guess else None,
                 "disagreement": sorted({v.matched.text for v in views if v.matched}) if
                 len({v.matched.text for v in views if v.matched}) > 1 else None}
        return Reading(raw_text=best.raw, text=matched.text if matched else "",
                       confidence=float(confidence), ocr_score=float(best.ocr_score),
                       match_score=float(matched.score) if matched else 0.0, extra=extra)

    def _crops(self, image: np.ndarray, corners) -> list[tuple[str, Any]]:
        """The views to try, as (name, lazy crop) pairs."""
        if corners is None:
            def whole() -> np.ndarray:
                h = image.shape[0]
                if h >= 2 * self.out_height:
                    return image
                s = 2 * self.out_height / h
                return cv2.resize(image, None, fx=s, fy=s, interpolation=cv2.INTER_CUBIC)
            return [("image", whole)]
        quad = np.asarray(corners, dtype=np.float64).reshape(4, 2)
        makers = {
            "line": lambda: plate_line(image, quad, self.out_height),
            "rectified": lambda: rectify_plate(image, quad, self.out_height),
            "bbox": lambda: bbox_crop(image, quad, int(1.5 * self.out_height)),
        }
        return [(name, makers[name]) for name in self.views]


def _worth_a_second_view(match: Match, vocabulary: Vocabulary) -> bool:
    """Whether a confident reading still needs the other views: a pattern's words alone
    ("MEETING ROOM" of ``MEETING ROOM {id}``) may have lost the plate's number at the
    crop's edge, and a slot's look-alike letter ("ROOM S") may be a digit ("ROOM 5")."""
    if match.slot is None:
        return vocabulary.may_lack_slot(match.text)
    return match.slot in LOOKALIKE_LETTERS


def _make_engine(threads: int | None):
    """Build RapidOCR from the models in its wheel (never downloading anything)."""
    try:
        import rapidocr_onnxruntime
        from rapidocr_onnxruntime import RapidOCR
    except ImportError as exc:
        raise ReaderError(f"the sign reader needs the OCR package rapidocr-onnxruntime, which "
                          f"cannot be imported ({exc})",
                          hint="Install it with `pip install rapidocr-onnxruntime` (its models "
                               "ship in the wheel; nothing is downloaded at run time).") from None
    models = Path(rapidocr_onnxruntime.__file__).parent / "models"
    missing = [name for name in ("ch_PP-OCRv4_det_infer.onnx", "ch_PP-OCRv4_rec_infer.onnx",
                                 "ch_ppocr_mobile_v2.0_cls_infer.onnx")
               if not (models / name).is_file()]
    if missing:
        raise ReaderError(f"the OCR models {', '.join(missing)} are missing from {models}",
                          hint="Reinstall rapidocr-onnxruntime (1.4 ships its models in the "
                               "wheel); the reader never downloads models.")
    options = dict(OCR_OPTIONS)
    if threads is not None:
        options["intra_op_num_threads"] = int(threads)
        options["inter_op_num_threads"] = 1
    try:
        return RapidOCR(**options)
    except Exception as exc:  # noqa: BLE001  onnxruntime or a broken install: say what
        raise ReaderError(f"the OCR engine (RapidOCR) failed to start: {exc}",
                          hint="Check the rapidocr-onnxruntime and onnxruntime installation.") \
            from None
