"""The object catalogue: the kinds of object the recogniser knows, with a picture and a size each.

One catalogue serves both sides of the simulation: sim2d's camera draws a
world's objects with the catalogue's pictures at their physical size, and the
recogniser (:mod:`semantic.recognise`) matches camera frames against the same
pictures and turns an object's apparent height into its range with the
catalogue's height. Labels are ontology class local names (``Shredder``), so a
recognised object is already an instance of a class of the indoor ontology.

The file format is described at the top of ``semantic/objects/catalogue.yaml``.
Loading checks every field and raises :class:`CatalogueError` (one paragraph
naming the file, line and field) on the first problem.
"""
from __future__ import annotations

import functools
import math
import re
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core.errors import SemmapError
from blocks.core.yamlsrc import line_of, load_versioned_mapping

__all__ = [
    "DEFAULT_PATH",
    "Catalogue",
    "CatalogueEntry",
    "CatalogueError",
    "default_catalogue",
    "load_catalogue",
]

DEFAULT_PATH = Path(__file__).with_name("catalogue.yaml")
ENTRY_KEYS = ("label", "image", "width", "height", "elevation")
_LABEL_RE = re.compile(r"[A-Z][A-Za-z0-9]*")
MAX_SIZE = 5.0  # m: a larger front face is surely a unit mistake (mm, cm)


class CatalogueError(SemmapError):
    """The object catalogue is malformed."""


@dataclass(frozen=True)
class CatalogueEntry:
    """One kind of object: its class, its front-face picture and the face's physical size.

    Attributes
    ----------
    label : str
        Ontology class local name, e.g. ``"Shredder"``.
    image : Path
        The picture of the front face (absolute path).
    width, height : float
        Physical size of the front face (m).
    elevation : float
        Height of the face's lower edge above the floor (m; 0 stands on the floor).
    line : int or None
        Line of the entry in the catalogue file (for messages).
    """

    label: str
    image: Path
    width: float
    height: float
    elevation: float = 0.0
    line: int | None = None

    @property
    def aspect(self) -> float:
        """Width over height of the front face."""
        return self.width / self.height


class Catalogue:
    """The catalogue's entries by label, with their pictures loaded on first use.

    Parameters
    ----------
    entries : iterable of CatalogueEntry
    source : path, optional
        Where the entries came from (for messages).
    """

    def __init__(self, entries: Iterable[CatalogueEntry], source: str | Path | None = None) -> None:
        self.entries: tuple[CatalogueEntry, ...] = tuple(entries)
        self.source = str(source) if source is not None else None
        self._by_label = {e.label: e for e in self.entries}
        self._images: dict[str, np.ndarray] = {}

    def __len__(self) -> int:
        return len(self.entries)

    def __contains__(self, label: object) -> bool:
        return label in self._by_label

    def __repr__(self) -> str:
        return f"Catalogue({len(self.entries)} objects, source={self.source!r})"

    @property
    def labels(self) -> list[str]:
        """The labels, in file order."""
        return [e.label for e in self.entries]

    def entry(self, label: str) -> CatalogueEntry:
        """The entry of a label.

        Raises
        ------
        CatalogueError
            When the catalogue has no such label (the message lists the known ones).
        """
        try:
            return self._by_label[label]
        except KeyError:
            import difflib
            close = difflib.get_close_matches(str(label), self.labels, n=1)
            raise CatalogueError(
                f"the object catalogue has no object {label!r}", file=self.source,
                hint=(f"Did you mean {close[0]!r}? " if close else "")
                + f"Known objects: {', '.join(self.labels)}.") from None

    def image(self, label: str) -> np.ndarray:
        """The front-face picture of a label (BGR uint8, read-only, loaded once)."""
        if label not in self._images:
            entry = self.entry(label)
            self._images[label] = _read_image(entry, self.source)
        return self._images[label]


def _read_image(entry: CatalogueEntry, source: str | None) -> np.ndarray:
    import cv2
    img = cv2.imread(str(entry.image), cv2.IMREAD_COLOR)
    if img is None:
        raise CatalogueError(f"cannot read the picture {entry.image.name!r} of {entry.label}",
                             file=source, line=entry.line, field="image",
                             hint="Give a PNG next to the catalogue file; the packaged pictures "
                                  "are made by python -m semantic.objects.make_catalogue.")
    img.setflags(write=False)
    return img


# ---- loading --------------------------------------------------------------------------------
def load_catalogue(path: str | Path | None = None, *, check_images: bool = True) -> Catalogue:
    """Load an object catalogue (default: the packaged ``semantic/objects/catalogue.yaml``).

    Parameters
    ----------
    path : path, optional
    check_images : bool
        Check that every picture file exists (the generator turns this off,
        since it is about to draw them).

    Raises
    ------
    CatalogueError
        When the file is missing, is not YAML, or any entry is malformed; the
        message names the file, the line and the field.
    """
    path = Path(path) if path is not None else DEFAULT_PATH
    doc = load_versioned_mapping(
        path, CatalogueError, what="an object catalogue", fields=("objects",),
        missing_hint="Give the path of an object catalogue YAML, or none for the packaged "
                     "semantic/objects/catalogue.yaml.")
    objects = doc.get("objects")
    if not isinstance(objects, list) or not objects:
        raise CatalogueError("'objects' must be a non-empty list of object entries", file=path,
                             line=line_of(doc, "objects") if "objects" in doc else line_of(doc),
                             field="objects")
    entries: list[CatalogueEntry] = []
    for i, raw in enumerate(objects):
        entry = _entry(raw, path, line_of(objects, i), i, check_images)
        first = next((e for e in entries if e.label == entry.label), None)
        if first is not None:
            raise CatalogueError(f"object {entry.label!r} is given twice (first on line "
                                 f"{first.line})", file=path, line=entry.line, field="label",
                                 hint="Keep one of the two entries.")
        entries.append(entry)
    return Catalogue(entries, source=path)


def _entry(raw: Any, path: Path, line: int | None, index: int,
           check_images: bool) -> CatalogueEntry:
    """Check and build one entry of the ``objects`` list."""
    if not isinstance(raw, Mapping):
        raise CatalogueError(f"object entry {index + 1} must be a mapping with 'label', 'image', "
                             f"'width' and 'height', got {raw!r}", file=path, line=line,
                             field="objects")
    line = line_of(raw) or line
    for key in raw:
        if key not in ENTRY_KEYS:
            import difflib
            close = difflib.get_close_matches(str(key), ENTRY_KEYS, n=1)
            raise CatalogueError(f"unknown field {key!r} in object entry {index + 1}", file=path,
                                 line=line_of(raw, key), field=str(key),
                                 hint=f"Did you mean {close[0]!r}?" if close else
                                 f"Known fields: {', '.join(ENTRY_KEYS)}.")

    def where(key: str) -> dict[str, Any]:
        return {"file": path, "line": line_of(raw, key) if key in raw else line, "field": key}

    label = raw.get("label")
    if not isinstance(label, str) or not _LABEL_RE.fullmatch(label):
        raise CatalogueError(f"'label' of object entry {index + 1} must be an ontology class "
                             f"name in UpperCamelCase (e.g. Shredder), got {label!r}",
                             **where("label"))
    image = raw.get("image")
    if not isinstance(image, str) or not image.lower().endswith(".png"):
        raise CatalogueError(f"'image' of {label} must be the file name of a PNG, got {image!r}",
                             **where("image"))
    image_path = (path.parent / image).resolve()
    if check_images and not image_path.is_file():
        raise CatalogueError(f"the picture {image!r} of {label} does not exist", **where("image"),
                             hint="Give a PNG relative to the catalogue file.")
    sizes = {}
    for key, default in (("width", None), ("height", None), ("elevation", 0.0)):
        value = raw.get(key, default)
        if value is None:
            raise CatalogueError(f"object {label} has no '{key}' (the physical {key} of its "
                                 "front face, in metres)", **where(key))
        low_ok = value >= 0 if key == "elevation" else value > 0
        ok = (not isinstance(value, bool) and isinstance(value, (int, float))
              and math.isfinite(value) and low_ok and value <= MAX_SIZE)
        if not ok:
            bound = ">= 0" if key == "elevation" else "> 0"
            raise CatalogueError(f"'{key}' of {label} must be a number of metres {bound} and at "
                                 f"most {MAX_SIZE:g}, got {value!r}", **where(key))
        sizes[key] = float(value)
    return CatalogueEntry(label=label, image=image_path, width=sizes["width"],
                          height=sizes["height"], elevation=sizes["elevation"], line=line)


@functools.lru_cache(maxsize=1)
def default_catalogue() -> Catalogue:
    """The packaged catalogue, loaded once per process (sim2d's camera draws with it)."""
    return load_catalogue()
