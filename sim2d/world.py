"""Worlds: a ROS map_server floor plan (YAML + PGM/PNG) plus start pose and door signs.

A world file is a map_server YAML (``image``, ``resolution``, ``origin``,
``negate``, ``occupied_thresh``, ``free_thresh``) with extra keys:

``start: [x, y, theta]``
    The robot's start pose (m, m, rad). Several robots: ``starts: [[x, y, theta], ...]``.
``signs: [{text, x, y, facing}]``
    Sign plates on walls; ``facing`` in degrees points into free space.
    Optional per sign: ``width``, ``height`` (plate size, m), ``z`` (height of
    the plate's centre above the floor, m) and its look: ``plate`` and ``ink``
    (RGB 0-255: the plate's and the letters' colours), ``font`` (one of
    :data:`SIGN_FONTS`) and ``spacing`` (extra space between letters, as a
    fraction of the letter height).
``colours: {wall, floor, ceiling, skirting}``
    The camera's colours of the building (RGB 0-255 each, all optional).
``walls: [[x1, y1, x2, y2], ...]``
    Walls as line segments (m), instead of or beside the image.
``wall_thickness``
    Thickness of the vector walls (m, default 0.1).

Ground truth for scoring a semantic map (all optional, so older files still load):

``places: [{name, kind, polygon: [[x, y], ...]}]``
    The true places: ``name`` is the sign text for signed rooms (``"MAIL ROOM"``)
    or a plain name (``"CORRIDOR"``), ``kind`` an ontology class local name
    (``MailRoom``, ``Corridor``, ``Hall``; see semantic/vocabulary.yaml). The
    polygon outlines the place's clear interior (>= 3 corners, m); a ring such
    as a corridor loop is one polygon whose hole is reached by a zero-width slit,
    so even-odd point-in-polygon tests work on it.
``doors: [{x, y, width, between: [placeA, placeB]}]``
    True doors and openings: centre on the wall's centre line, clear width (m)
    and the names of the two places they join (names from ``places``). A door
    with ``closed: true`` is shut: the image has a wall there.
``objects: [{label, x, y}]``
    Objects in the world (``label`` an ontology class local name such as
    ``Shredder``), at a point in free space. Optional, for the camera:
    ``scale`` (times the catalogue size), ``light`` (brightness factor) and
    ``cover`` (the fraction of its height hidden from below by something in
    front of it, 0 to 0.8).
``timetable: FILE``
    A timetable file, relative to the world file.
``commands: FILE``
    English commands with their right answers on this floor (see
    ``semantic/query``), relative to the world file.
``generator: {kind, seed, version}``
    Written by the building generator (:mod:`sim2d.worlds.building`): what
    made this floor, for sweeps and reports.

Walls become line segments with a radius ("capsules"): the image's wall
pixels are traced into contours through the centres of their border pixels,
simplified, and given a radius of half a pixel, so the capsule's surface lies
on the pixel edges.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blocks.core.errors import GraphError, SemmapError
from blocks.core.yamlsrc import LineDict, line_of, load_yaml_file


class WorldError(SemmapError):
    """A world file is malformed."""


#: Fonts a sign may be lettered in (OpenCV's Hershey faces, by their short names).
SIGN_FONTS = ("duplex", "simplex", "plain", "complex", "triplex")


@dataclass(frozen=True)
class Sign:
    """A rectangular sign plate on a wall, facing into free space."""

    text: str
    x: float
    y: float
    facing: float  # radians, world frame, the plate's outward normal
    width: float = 0.6
    height: float = 0.2
    z: float = 1.2  # height of the plate's centre above the floor
    plate: tuple[int, int, int] = (238, 238, 238)  # RGB of the plate
    ink: tuple[int, int, int] = (15, 15, 15)  # RGB of the letters (and the border)
    font: str = "duplex"  # one of SIGN_FONTS
    spacing: float = 0.0  # extra space between letters, fraction of the letter height

    def corners(self) -> np.ndarray:
        """The plate's 4 corners (x, y, z), left-to-right as seen from the front, top first."""
        # A viewer in front looks along -normal; their right is (-sin f, cos f).
        tx, ty = -math.sin(self.facing), math.cos(self.facing)  # left-to-right direction
        hw, hh = self.width / 2, self.height / 2
        return np.array([
            [self.x - tx * hw, self.y - ty * hw, self.z + hh],
            [self.x + tx * hw, self.y + ty * hw, self.z + hh],
            [self.x + tx * hw, self.y + ty * hw, self.z - hh],
            [self.x - tx * hw, self.y - ty * hw, self.z - hh],
        ])


@dataclass(frozen=True)
class TruePlace:
    """A ground-truth place: its name (sign text for signed rooms), class and outline."""

    name: str
    kind: str  # ontology class local name (MailRoom, Corridor, Hall, ...)
    polygon: np.ndarray  # (N, 2) corners in metres, world frame, not closed


@dataclass(frozen=True)
class TrueDoor:
    """A ground-truth door or opening between two places."""

    x: float
    y: float
    width: float  # clear width, m
    between: tuple[str, str]  # the names of the two places it joins
    closed: bool = False  # a shut door: a wall in the image, no way through


@dataclass(frozen=True)
class WorldObject:
    """An object standing in the world (label: ontology class local name)."""

    label: str
    x: float
    y: float
    scale: float = 1.0  # times the catalogue's width and height
    light: float = 1.0  # brightness factor (lighting)
    cover: float = 0.0  # fraction of its height hidden from below by a box in front


@dataclass
class World:
    """A loaded world: wall capsules, signs, start poses and the source occupancy grid."""

    name: str
    segments: np.ndarray  # (S, 5): x1, y1, x2, y2, radius (m)
    signs: list[Sign]
    starts: list[tuple[float, float, float]]
    resolution: float = 0.05
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)
    occupied: np.ndarray | None = None  # (H, W) bool, row 0 at the top (image order)
    source: str = ""
    extra: dict[str, Any] = field(default_factory=dict)
    places: list[TruePlace] = field(default_factory=list)
    doors: list[TrueDoor] = field(default_factory=list)
    objects: list[WorldObject] = field(default_factory=list)
    timetable: Path | None = None
    commands: Path | None = None  # English commands with their right answers on this floor
    colours: dict[str, tuple[int, int, int]] = field(default_factory=dict)  # camera colours
    generator: dict[str, Any] = field(default_factory=dict)  # kind, seed, version if generated

    def place(self, name: str) -> TruePlace | None:
        """The true place called ``name``, or None."""
        return next((p for p in self.places if p.name == name), None)

    @property
    def start(self) -> tuple[float, float, float]:
        return self.starts[0]

    def bounds(self) -> tuple[float, float, float, float]:
        """(xmin, ymin, xmax, ymax) of everything in the world, in metres."""
        boxes = []
        if len(self.segments):
            s = self.segments
            boxes.append((min(s[:, 0].min(), s[:, 2].min()), min(s[:, 1].min(), s[:, 3].min()),
                          max(s[:, 0].max(), s[:, 2].max()), max(s[:, 1].max(), s[:, 3].max())))
        if self.occupied is not None:
            h, w = self.occupied.shape
            ox, oy = self.origin[:2]
            boxes.append((ox, oy, ox + w * self.resolution, oy + h * self.resolution))
        for x, y, _ in self.starts:
            boxes.append((x, y, x, y))
        if not boxes:
            return (0.0, 0.0, 1.0, 1.0)
        arr = np.array(boxes)
        return (float(arr[:, 0].min()), float(arr[:, 1].min()),
                float(arr[:, 2].max()), float(arr[:, 3].max()))


# ---- the bitmap ----------------------------------------------------------------------------
def occupancy_from_image(pixels: np.ndarray, negate: bool, occupied_thresh: float,
                         free_thresh: float) -> tuple[np.ndarray, np.ndarray]:
    """map_server semantics: (occupied, free) boolean masks from a grey image.

    With ``negate`` false, black (0) is occupied: p = (255 - value) / 255.
    """
    value = pixels.astype(np.float64)
    p = value / 255.0 if negate else (255.0 - value) / 255.0
    return p > occupied_thresh, p < free_thresh


def segments_from_occupancy(occupied: np.ndarray, resolution: float,
                            origin: tuple[float, float, float],
                            tolerance_px: float = 0.7) -> np.ndarray:
    """Trace wall pixels into simplified line segments (x1, y1, x2, y2, radius), metres.

    Contours run through the centres of the walls' border pixels; a radius of
    half a pixel puts each capsule's surface on the pixel edges. A lone pixel
    becomes a zero-length segment (a round post).
    """
    import cv2

    mask = occupied.astype(np.uint8)
    if not mask.any():
        return np.zeros((0, 5))
    contours, _ = cv2.findContours(mask, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    h = occupied.shape[0]
    ox, oy, yaw = origin
    c, s = math.cos(yaw), math.sin(yaw)
    out = []
    for contour in contours:
        pts = contour[:, 0, :].astype(np.float64)
        if len(pts) > 2:
            pts = cv2.approxPolyDP(pts.astype(np.float32), tolerance_px, True)[:, 0, :]
            pts = pts.astype(np.float64)
            closed = np.vstack([pts, pts[:1]])
        else:
            closed = np.vstack([pts, pts[-1:]]) if len(pts) == 1 else pts
        # pixel (col, row) centre -> map frame (y up), then rotate by the origin yaw
        mx = (closed[:, 0] + 0.5) * resolution
        my = (h - 1 - closed[:, 1] + 0.5) * resolution
        wx, wy = ox + c * mx - s * my, oy + s * mx + c * my
        for i in range(len(closed) - 1):
            out.append((wx[i], wy[i], wx[i + 1], wy[i + 1], resolution / 2))
    return np.asarray(out, dtype=np.float64).reshape(-1, 5)


# ---- loading --------------------------------------------------------------------------------
def _number(doc: LineDict, key: str, file: Path, default: Any = None, *,
            positive: bool = False, lo: float | None = None, hi: float | None = None,
            where: str = "") -> float:
    name = f"{where}.{key}" if where else key
    value = doc.get(key, default)
    if value is None:
        owner = where or "the world"
        raise WorldError(f"{owner} has no '{key}'", file=file, line=line_of(doc),
                         field=name, hint=f"Add '{key}:' (see sim2d/worlds/*.yaml).")
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise WorldError(f"'{name}' must be a number, got {value!r}", file=file,
                         line=line_of(doc, key), field=name)
    if positive and value <= 0 or lo is not None and value < lo or hi is not None and value > hi:
        bounds = "> 0" if positive else f"in [{lo}, {hi}]"
        raise WorldError(f"'{name}' must be {bounds}, got {value!r}", file=file,
                         line=line_of(doc, key), field=name)
    return float(value)


def _pose(value: Any, file: Path, line: int | None, key: str) -> tuple[float, float, float]:
    ok = isinstance(value, list) and len(value) == 3 and all(
        isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in value)
    if not ok:
        raise WorldError(f"'{key}' must be [x, y, theta] in metres and radians, got {value!r}",
                         file=file, line=line, field=key)
    return (float(value[0]), float(value[1]), float(value[2]))


def _signs(doc: LineDict, file: Path) -> list[Sign]:
    raw = doc.get("signs") or []
    if not isinstance(raw, list):
        raise WorldError("'signs' must be a list of {text, x, y, facing}", file=file,
                         line=line_of(doc, "signs"), field="signs")
    signs = []
    for i, item in enumerate(raw):
        line = line_of(raw, i)
        if not isinstance(item, dict):
            raise WorldError("each sign must be a mapping {text, x, y, facing}", file=file,
                             line=line, field=f"signs[{i}]")
        unknown = set(item) - set(SIGN_KEYS)
        if unknown:
            raise WorldError(f"sign {i} has unknown field(s) {sorted(map(str, unknown))}",
                             file=file, line=line, field=f"signs[{i}]",
                             hint="A sign has text, x, y, facing (degrees) and optionally "
                                  "width, height, z, plate, ink, font, spacing.")
        text = item.get("text")
        if not isinstance(text, str) or not text.strip():
            raise WorldError(f"sign {i} needs a non-empty 'text'", file=file, line=line,
                             field=f"signs[{i}].text")
        values = {}
        for key in ("x", "y", "facing"):
            values[key] = _number(item, key, file, where=f"signs[{i}]")
        for key, default in (("width", 0.6), ("height", 0.2), ("z", 1.2)):
            values[key] = _number(item, key, file, default, positive=True, where=f"signs[{i}]")
        style = {key: _rgb(item, key, file, f"signs[{i}]") for key in ("plate", "ink")
                 if key in item}
        font = item.get("font", "duplex")
        if font not in SIGN_FONTS:
            raise WorldError(f"sign {i} has font {font!r}", file=file,
                             line=line_of(item, "font") or line, field=f"signs[{i}].font",
                             hint=f"Use one of {', '.join(SIGN_FONTS)}.")
        spacing = _number(item, "spacing", file, 0.0, lo=0.0, hi=2.0, where=f"signs[{i}]")
        signs.append(Sign(text=text.strip(), x=values["x"], y=values["y"],
                          facing=math.radians(values["facing"]), width=values["width"],
                          height=values["height"], z=values["z"], font=font, spacing=spacing,
                          **style))
    return signs


def _rgb(item: dict, key: str, file: Path, where: str) -> tuple[int, int, int]:
    """An RGB colour ``[r, g, b]`` with components 0-255."""
    value = item.get(key)
    ok = isinstance(value, list) and len(value) == 3 and all(
        isinstance(v, int) and not isinstance(v, bool) and 0 <= v <= 255 for v in value)
    if not ok:
        raise WorldError(f"'{where}.{key}' must be a colour [r, g, b] of integers 0-255, got "
                         f"{value!r}", file=file, line=line_of(item, key), field=f"{where}.{key}")
    return (int(value[0]), int(value[1]), int(value[2]))


def _colours(doc: LineDict, file: Path) -> dict[str, tuple[int, int, int]]:
    raw = doc.get("colours")
    if raw is None:
        return {}
    if not isinstance(raw, dict):
        raise WorldError("'colours' must be a mapping {wall, floor, ceiling, skirting}",
                         file=file, line=line_of(doc, "colours"), field="colours")
    unknown = set(raw) - set(COLOUR_KEYS)
    if unknown:
        raise WorldError(f"'colours' has unknown field(s) {sorted(map(str, unknown))}", file=file,
                         line=line_of(doc, "colours"), field="colours",
                         hint=f"Colours may be given for {', '.join(COLOUR_KEYS)}.")
    return {key: _rgb(raw, key, file, "colours") for key in COLOUR_KEYS if key in raw}


def _entries(doc: LineDict, key: str, file: Path, shape: str, allowed: set[str]) -> list:
    """The list under ``key`` as (index, line, mapping) triples, checked for unknown fields."""
    raw = doc.get(key)
    if raw is None:
        return []
    if not isinstance(raw, list):
        raise WorldError(f"'{key}' must be a list of {shape}", file=file,
                         line=line_of(doc, key), field=key)
    out = []
    for i, item in enumerate(raw):
        line = line_of(raw, i)
        if not isinstance(item, dict):
            raise WorldError(f"each entry of '{key}' must be a mapping {shape}, got {item!r}",
                             file=file, line=line, field=f"{key}[{i}]")
        unknown = set(item) - allowed
        if unknown:
            raise WorldError(f"{key}[{i}] has unknown field(s) {sorted(map(str, unknown))}",
                             file=file, line=line, field=f"{key}[{i}]",
                             hint=f"An entry of '{key}' is {shape}.")
        out.append((i, line, item))
    return out


def _name(item: dict, key: str, file: Path, line: int | None, where: str) -> str:
    value = item.get(key)
    if not isinstance(value, str) or not value.strip():
        raise WorldError(f"{where} needs a non-empty text '{key}', got {value!r}", file=file,
                         line=line, field=f"{where}.{key}",
                         hint=f"Add '{key}: ...' to {where}.")
    return value.strip()


def _places(doc: LineDict, file: Path) -> list[TruePlace]:
    places: list[TruePlace] = []
    for i, line, item in _entries(doc, "places", file, "{name, kind, polygon: [[x, y], ...]}",
                                  {"name", "kind", "polygon"}):
        where = f"places[{i}]"
        name = _name(item, "name", file, line, where)
        kind = _name(item, "kind", file, line, where)
        raw = item.get("polygon")
        ok = isinstance(raw, list) and len(raw) >= 3 and all(
            isinstance(p, list) and len(p) == 2 and all(
                isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                for v in p) for p in raw)
        if not ok:
            raise WorldError(f"{where} ({name!r}) needs a 'polygon' of at least 3 [x, y] corners "
                             f"in metres, got {raw!r}", file=file,
                             line=line_of(item, "polygon") or line, field=f"{where}.polygon",
                             hint="Write the outline as polygon: [[x1, y1], [x2, y2], "
                                  "[x3, y3], ...].")
        polygon = np.asarray(raw, dtype=np.float64)
        twice_area = float(np.sum(polygon[:, 0] * np.roll(polygon[:, 1], -1)
                                  - np.roll(polygon[:, 0], -1) * polygon[:, 1]))
        if abs(twice_area) < 1e-9:
            raise WorldError(f"{where} ({name!r}) has a polygon of zero area", file=file,
                             line=line_of(item, "polygon") or line, field=f"{where}.polygon",
                             hint="Give the corners of the place's outline in order.")
        if any(p.name == name for p in places):
            raise WorldError(f"two places are called {name!r}", file=file, line=line,
                             field=f"{where}.name", hint="Give each place a unique name.")
        places.append(TruePlace(name=name, kind=kind, polygon=polygon))
    return places


def _doors(doc: LineDict, file: Path, places: list[TruePlace]) -> list[TrueDoor]:
    names = {p.name for p in places}
    doors = []
    for i, line, item in _entries(doc, "doors", file, "{x, y, width, between: [placeA, placeB]}",
                                  {"x", "y", "width", "between", "closed"}):
        where = f"doors[{i}]"
        x = _number(item, "x", file, where=where)
        y = _number(item, "y", file, where=where)
        width = _number(item, "width", file, positive=True, where=where)
        between = item.get("between")
        if not (isinstance(between, list) and len(between) == 2
                and all(isinstance(b, str) and b.strip() for b in between)):
            raise WorldError(f"{where} needs 'between: [placeA, placeB]', two place names, got "
                             f"{between!r}", file=file, line=line_of(item, "between") or line,
                             field=f"{where}.between",
                             hint="Name the two places the door joins, as in 'places'.")
        pair = (between[0].strip(), between[1].strip())
        for b in pair:
            if b not in names:
                import difflib
                close = difflib.get_close_matches(b, sorted(names), n=1)
                raise WorldError(f"{where} joins {b!r}, which is not in 'places'", file=file,
                                 line=line_of(item, "between") or line, field=f"{where}.between",
                                 hint=f"Did you mean {close[0]!r}?" if close else
                                 "Add the place to 'places' or fix the name.")
        closed = item.get("closed", False)
        if not isinstance(closed, bool):
            raise WorldError(f"{where}.closed must be true or false, got {closed!r}", file=file,
                             line=line_of(item, "closed") or line, field=f"{where}.closed")
        doors.append(TrueDoor(x=x, y=y, width=width, between=pair, closed=closed))
    return doors


def _objects(doc: LineDict, file: Path) -> list[WorldObject]:
    objects = []
    for i, line, item in _entries(doc, "objects", file, "{label, x, y}",
                                  {"label", "x", "y", "scale", "light", "cover"}):
        where = f"objects[{i}]"
        label = _name(item, "label", file, line, where)
        objects.append(WorldObject(
            label=label, x=_number(item, "x", file, where=where),
            y=_number(item, "y", file, where=where),
            scale=_number(item, "scale", file, 1.0, lo=0.2, hi=5.0, where=where),
            light=_number(item, "light", file, 1.0, lo=0.1, hi=3.0, where=where),
            cover=_number(item, "cover", file, 0.0, lo=0.0, hi=0.8, where=where)))
    return objects


def _side_file(doc: LineDict, file: Path, key: str) -> Path | None:
    """A file named under ``key`` (timetable, commands), relative to the world file."""
    raw = doc.get(key)
    if raw is None:
        return None
    if not isinstance(raw, str) or not raw.strip():
        raise WorldError(f"'{key}' must be a file name, got {raw!r}", file=file,
                         line=line_of(doc, key), field=key,
                         hint="Give a path relative to the world file.")
    path = (file.parent / raw.strip()).resolve()
    if not path.is_file():
        raise WorldError(f"{key} file '{raw}' not found (looked for {path})", file=file,
                         line=line_of(doc, key), field=key,
                         hint="The path is relative to the world file's folder.")
    return path


def _generator(doc: LineDict, file: Path) -> dict[str, Any]:
    raw = doc.get("generator")
    if raw is None:
        return {}
    if not isinstance(raw, dict) or not {"kind", "seed"} <= set(raw):
        raise WorldError(f"'generator' must be a mapping {{kind, seed, version}}, got {raw!r}",
                         file=file, line=line_of(doc, "generator"), field="generator")
    return dict(raw)


def _vector_walls(doc: LineDict, file: Path) -> np.ndarray:
    raw = doc.get("walls") or []
    if not isinstance(raw, list):
        raise WorldError("'walls' must be a list of [x1, y1, x2, y2]", file=file,
                         line=line_of(doc, "walls"), field="walls")
    radius = _number(doc, "wall_thickness", file, 0.1, positive=True) / 2
    rows = []
    for i, wall in enumerate(raw):
        ok = isinstance(wall, list) and len(wall) == 4 and all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            for v in wall)
        if not ok:
            raise WorldError(f"wall {i} must be [x1, y1, x2, y2] in metres, got {wall!r}",
                             file=file, line=line_of(raw, i), field=f"walls[{i}]")
        rows.append((*map(float, wall), radius))
    return np.asarray(rows, dtype=np.float64).reshape(-1, 5)


WORLD_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh",
              "mode", "start", "starts", "signs", "walls", "wall_thickness", "name", "doc",
              "places", "doors", "objects", "timetable", "commands", "colours", "generator")
SIGN_KEYS = ("text", "x", "y", "facing", "width", "height", "z", "plate", "ink", "font",
             "spacing")
COLOUR_KEYS = ("wall", "floor", "ceiling", "skirting")


def load_world(path: str | Path) -> World:
    """Load a world file; every problem is a WorldError naming the file, line and field."""
    path = Path(path)
    try:
        doc = load_yaml_file(path)
    except GraphError as exc:  # YAML syntax, duplicate keys, missing file: a world error here
        raise WorldError(exc.message, file=exc.file, line=exc.line,
                         hint=exc.hint if "include" not in (exc.hint or "") else
                         "Give a world library name (see sim2d/worlds) or a path to a world "
                         "YAML.") from None
    if not isinstance(doc, dict):
        raise WorldError("a world file must be a YAML mapping (map_server format)", file=path)
    for key in doc:
        if key not in WORLD_KEYS:
            import difflib
            close = difflib.get_close_matches(str(key), WORLD_KEYS, n=1)
            raise WorldError(f"unknown world field {key!r}", file=path, line=line_of(doc, key),
                             field=str(key), hint=f"Did you mean {close[0]!r}?" if close else
                             f"Known fields: {', '.join(WORLD_KEYS)}.")
    if "image" not in doc and "walls" not in doc:
        raise WorldError("the world has neither 'image' nor 'walls'", file=path, field="image",
                         hint="Give a floor-plan image (map_server format) or a 'walls' list.")
    resolution = _number(doc, "resolution", path, 0.05 if "image" not in doc else None,
                         positive=True)
    origin_raw = doc.get("origin", [0.0, 0.0, 0.0])
    origin = _pose(origin_raw, path, line_of(doc, "origin"), "origin")
    negate = doc.get("negate", 0)
    if negate not in (0, 1, True, False):
        raise WorldError(f"'negate' must be 0 or 1, got {negate!r}", file=path,
                         line=line_of(doc, "negate"), field="negate")
    occ_t = _number(doc, "occupied_thresh", path, 0.65, lo=0.0, hi=1.0)
    free_t = _number(doc, "free_thresh", path, 0.196, lo=0.0, hi=1.0)
    if free_t > occ_t:
        raise WorldError(f"free_thresh {free_t} is above occupied_thresh {occ_t}", file=path,
                         line=line_of(doc, "free_thresh"), field="free_thresh")
    occupied = None
    segments = [_vector_walls(doc, path)]
    if "image" in doc:
        image = doc["image"]
        if not isinstance(image, str) or not image:
            raise WorldError("'image' must be a file name", file=path,
                             line=line_of(doc, "image"), field="image")
        pixels = read_grey_image(path.parent / image, path, line_of(doc, "image"))
        occupied, _ = occupancy_from_image(pixels, bool(negate), occ_t, free_t)
        segments.insert(0, segments_from_occupancy(occupied, resolution, origin))
    if "starts" in doc:
        raw = doc["starts"]
        if not isinstance(raw, list) or not raw:
            raise WorldError("'starts' must be a non-empty list of [x, y, theta]", file=path,
                             line=line_of(doc, "starts"), field="starts")
        starts = [_pose(p, path, line_of(raw, i), f"starts[{i}]") for i, p in enumerate(raw)]
    elif "start" in doc:
        starts = [_pose(doc["start"], path, line_of(doc, "start"), "start")]
    else:
        raise WorldError("the world has no 'start: [x, y, theta]'", file=path, field="start",
                         hint="Add the robot's start pose in metres and radians.")
    world = World(name=str(doc.get("name") or path.stem), segments=np.vstack(segments),
                  signs=_signs(doc, path), starts=starts, resolution=resolution,
                  origin=origin, occupied=occupied, source=str(path))
    world.places = _places(doc, path)
    world.doors = _doors(doc, path, world.places)
    world.objects = _objects(doc, path)
    world.timetable = _side_file(doc, path, "timetable")
    world.commands = _side_file(doc, path, "commands")
    world.colours = _colours(doc, path)
    world.generator = _generator(doc, path)
    for i, obj in enumerate(world.objects):
        if world_is_occupied(world, obj.x, obj.y):
            raise WorldError(f"object {i} ({obj.label}) at ({obj.x:.2f}, {obj.y:.2f}) is inside "
                             "a wall", file=path, line=line_of(doc["objects"], i),
                             field=f"objects[{i}]", hint="Move it into free space.")
    for i, (x, y, _) in enumerate(world.starts):
        if world_is_occupied(world, x, y):
            raise WorldError(f"start pose {i} ({x:.2f}, {y:.2f}) is inside a wall", file=path,
                             line=line_of(doc, "starts" if "starts" in doc else "start"),
                             field="start", hint="Move it into free space.")
    return world


def read_grey_image(image_path: Path, world_file: Path, line: int | None) -> np.ndarray:
    """A PGM/PNG as an 8-bit grey array (row 0 at the top)."""
    import cv2

    if not image_path.is_file():
        raise WorldError(f"image '{image_path.name}' not found next to the world file",
                         file=world_file, line=line, field="image")
    pixels = cv2.imread(str(image_path), cv2.IMREAD_UNCHANGED)
    if pixels is None:
        raise WorldError(f"cannot read image '{image_path.name}' (not a PGM/PNG?)",
                         file=world_file, line=line, field="image")
    if pixels.ndim == 3:
        channels = pixels.shape[2]
        pixels = cv2.cvtColor(pixels, cv2.COLOR_BGRA2GRAY if channels == 4 else cv2.COLOR_BGR2GRAY)
    if pixels.dtype == np.uint16:
        pixels = (pixels // 257).astype(np.uint8)
    return pixels.astype(np.uint8)


def world_is_occupied(world: World, x: float, y: float, margin: float = 0.0) -> bool:
    """Is the point inside a wall (an occupied pixel) or within ``margin`` of a wall capsule?

    The capsules trace wall outlines only, so the inside of a thick wall needs the grid.
    """
    if world.occupied is not None:
        h, w = world.occupied.shape
        ox, oy, yaw = world.origin
        c, s = math.cos(-yaw), math.sin(-yaw)
        mx, my = c * (x - ox) - s * (y - oy), s * (x - ox) + c * (y - oy)
        col, row = int(math.floor(mx / world.resolution)), h - 1 - int(
            math.floor(my / world.resolution))
        if 0 <= row < h and 0 <= col < w and world.occupied[row, col]:
            return True
    if not len(world.segments):
        return False
    return bool(distance_to_segments(np.array([x, y]), world.segments).min() <= margin)


def distance_to_segments(point: np.ndarray, segments: np.ndarray) -> np.ndarray:
    """Distance from a point to each capsule's surface (negative inside)."""
    p = np.asarray(point, dtype=np.float64)
    a, b, r = segments[:, 0:2], segments[:, 2:4], segments[:, 4]
    d = b - a
    length2 = np.einsum("ij,ij->i", d, d)
    t = np.where(length2 > 0, np.einsum("ij,ij->i", p - a, d) / np.where(length2 > 0, length2, 1), 0)
    closest = a + np.clip(t, 0, 1)[:, None] * d
    return np.hypot(*(p - closest).T) - r


def make_world(walls: list[list[float]] | np.ndarray, start=(0.0, 0.0, 0.0),
               signs: list[Sign] | None = None, thickness: float = 0.1,
               name: str = "made") -> World:
    """Build a world in code (tests, generators): walls as [x1, y1, x2, y2] rows."""
    arr = np.asarray(walls, dtype=np.float64).reshape(-1, 4)
    segments = np.hstack([arr, np.full((len(arr), 1), thickness / 2)])
    return World(name=name, segments=segments, signs=list(signs or []), starts=[tuple(start)])
