"""The semantic map: places segmented from the occupancy map, labelled by the signs read,
furnished with the objects seen, and reasoned over by the knowledge base.

This is the paper's semantic knowledge mapping module (section 2.4) as plain
functions: :func:`build_semantic_map` joins the spatial hierarchy (places,
doors) and the conceptual one (the ontology's place kinds, functions,
equipment, roles) the way Galindo et al.'s semantic maps do, and
:func:`write_semantic_map` writes what a user or the query planner reads:
``semantic_map.ttl``, ``places.geojson`` and a picture.
"""
from __future__ import annotations

import math
import time
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from blocks.maps.mapio import OccupancyMap

from .kb import KnowledgeBase, OwlPass
from .places import PlaceMap, attach_signs, segment_places
from .vocabulary import Vocabulary, canonical, load_vocabulary

__all__ = ["SemanticMap", "build_semantic_map", "sign_place_id", "write_semantic_map"]

#: The kind given to a segmented place no sign names, by its shape.
UNSIGNED_KIND = {"corridor": "Corridor", "hall": "Hall", "room": "Room"}
#: How far (m) in front of its plate a room known only by its sign is anchored: in the
#: corridor, at its door, where a plan to it stops.
DOOR_ANCHOR = 0.5


@dataclass
class SemanticMap:
    """A place map joined to a reasoned knowledge base.

    Attributes
    ----------
    places
        The segmented places, doors and place graph.
    kb
        The knowledge base holding places, doors, signs, objects and people.
    names
        Place id -> the sign text that names it (signed places only).
    kinds
        Place id -> ontology class local name (every place).
    sign_places
        Index into the signs list -> the id of the place the sign labels (or None).
    unentered
        Id -> (name, (x, y)) of each room known only by its sign: the map has no
        room behind the plate to segment (the robot has not been inside), so the
        room is a place of the knowledge base without an outline, anchored at
        its door (not in ``places``, ``names`` or ``kinds``).
    object_places
        Index into the objects list -> the id of the place the object is in (or None).
    timings_ms
        Milliseconds spent segmenting, building and reasoning.
    """

    places: PlaceMap
    kb: KnowledgeBase
    names: dict[str, str]
    kinds: dict[str, str]
    sign_places: dict[int, str | None]
    unentered: dict[str, tuple[str, tuple[float, float]]] = field(default_factory=dict)
    object_places: dict[int, str | None] = field(default_factory=dict)
    timings_ms: dict[str, float] = field(default_factory=dict)


def sign_place_id(index: int) -> str:
    """The id of the place a sign anchors before the map is segmented (see :func:`live_kb`)."""
    return f"S{index + 1}"


def _place_kind(text: str, vocabulary: Vocabulary) -> str | None:
    return vocabulary.place_class(text) if text else None


def build_semantic_map(occupancy: OccupancyMap, signs: list[Mapping[str, Any]],
                       objects: Iterable[Mapping[str, Any]] = (), *,
                       ontology: str | Path | None = None, timetable: Any = None,
                       vocabulary: Vocabulary | None = None,
                       segment_options: Mapping[str, Any] | None = None,
                       path: np.ndarray | None = None) -> SemanticMap:
    """Segment the map into places, label them with the signs and reason over them.

    Parameters
    ----------
    occupancy
        The occupancy map to segment (the offline map in the main pipeline).
    signs
        Read signs as in ``signs.json``: ``{text, x, y, facing (deg), ...}``.
    objects
        Observed objects: ``{label, x, y, ...}`` (ontology class names as labels).
    ontology
        An ontology file to use instead of the packaged one.
    timetable
        A loaded :class:`semantic.timetable.Timetable`, or None.
    vocabulary
        The sign vocabulary that gives each sign text its place class.
    segment_options
        Keyword arguments for :func:`semantic.places.segment_places`.
    path
        The robot's path (N, 2+), which helps tell the corridor from the rooms.

    Returns
    -------
    SemanticMap
        With the knowledge base already reasoned.
    """
    vocabulary = vocabulary or load_vocabulary()
    timings: dict[str, float] = {}
    t0 = time.perf_counter()
    options = dict(segment_options or {})
    if path is not None:
        options["path"] = path
    pm = segment_places(occupancy, **options)
    sign_places = attach_signs(pm, list(signs))
    timings["segment_ms"] = (time.perf_counter() - t0) * 1e3

    t0 = time.perf_counter()
    names: dict[str, str] = {}
    kinds: dict[str, str] = {}
    for i, place_id in sign_places.items():
        if place_id is None:
            continue
        text = str(signs[i].get("text", ""))
        kind = _place_kind(text, vocabulary)
        if kind is not None and place_id not in kinds:
            names[place_id] = text
            kinds[place_id] = kind
    for place in pm.places:
        kinds.setdefault(place.id, UNSIGNED_KIND.get(place.kind_hint, "Room"))
    unentered = _unentered_rooms(signs, sign_places, names, vocabulary)

    kb = KnowledgeBase(ontology, vocabulary=vocabulary)
    for place in pm.places:
        kb.add_place(place.id, kinds[place.id], name=names.get(place.id),
                     centroid=tuple(place.centroid), polygon=place.polygon, area=place.area)
    for i, (place_id, anchor) in unentered.items():
        text = str(signs[i]["text"])
        kb.add_place(place_id, _place_kind(text, vocabulary), name=text, centroid=anchor)
    for door in pm.doors:
        kb.add_door(door.id, door.a, door.b, x=door.x, y=door.y, width=door.width)
    for i, sign in enumerate(signs):
        text = str(sign.get("text", ""))
        place_id = sign_places.get(i) or unentered.get(i, (None,))[0]
        kb.add_sign(f"sign_{i + 1}", text, x=float(sign["x"]), y=float(sign["y"]),
                    facing_deg=float(sign.get("facing", 0.0)), place_id=place_id,
                    place_class=_place_kind(text, vocabulary))
    object_places: dict[int, str | None] = {}
    for i, obj in enumerate(objects):
        place_id = pm.place_at(float(obj["x"]), float(obj["y"]))
        object_places[i] = place_id
        kb.add_object(f"object_{i + 1}", str(obj["label"]), x=float(obj["x"]),
                      y=float(obj["y"]), place_id=place_id, observed=True)
    if timetable is not None:
        kb.add_timetable(timetable)
    timings["build_ms"] = (time.perf_counter() - t0) * 1e3
    t0 = time.perf_counter()
    kb.reason()
    timings["reason_ms"] = (time.perf_counter() - t0) * 1e3
    return SemanticMap(places=pm, kb=kb, names=names, kinds=kinds, sign_places=sign_places,
                       unentered={pid: (str(signs[i]["text"]), anchor)
                                  for i, (pid, anchor) in unentered.items()},
                       object_places=object_places,
                       timings_ms=timings)


def _unentered_rooms(signs: list[Mapping[str, Any]], sign_places: Mapping[int, str | None],
                     names: Mapping[str, str], vocabulary: Vocabulary
                     ) -> dict[int, tuple[str, tuple[float, float]]]:
    """Sign index -> (place id, door anchor) for each room known only by its sign.

    Why: a plate read on a door the robot never went through names a room the
    map has no outline for, and dropping it loses what the robot did learn:
    that this room is behind that door.  A user asking to go there is taken
    to the door.  Only signs that name a place class count, once per name,
    and not when a segmented place already carries the name.
    """
    taken = {canonical(text) for text in names.values()}
    out: dict[int, tuple[str, tuple[float, float]]] = {}
    for i, sign in enumerate(signs):
        text = str(sign.get("text", ""))
        facing = math.radians(float(sign.get("facing", float("nan"))))
        if (sign_places.get(i) is not None or canonical(text) in taken
                or _place_kind(text, vocabulary) is None or not math.isfinite(facing)):
            continue
        taken.add(canonical(text))
        anchor = (float(sign["x"]) + DOOR_ANCHOR * math.cos(facing),
                  float(sign["y"]) + DOOR_ANCHOR * math.sin(facing))
        out[i] = (sign_place_id(i), anchor)
    return out


def live_kb(signs: list[Mapping[str, Any]], objects: Iterable[Mapping[str, Any]] = (), *,
            ontology: str | Path | None = None, timetable: Any = None,
            vocabulary: Vocabulary | None = None, owl: OwlPass | None = None) -> KnowledgeBase:
    """The knowledge base while the robot runs, before there is a map to segment.

    Each read sign stands for the place it labels (``S1``, ``S2``, ... placed
    just behind the plate), so what the signs imply (the room's function, its
    default equipment, who works there) is known as soon as a sign is read;
    observed objects are given to the nearest sign's place within 4 m.
    :func:`build_semantic_map` replaces these anchors with segmented places.

    Parameters
    ----------
    signs, objects, ontology, timetable, vocabulary
        As for :func:`build_semantic_map`.
    owl : OwlPass, optional
        The previous live base's OWL pass (its ``owl``): this base's OWL closure
        then follows from it incrementally, the same as from scratch.

    Returns
    -------
    KnowledgeBase
        Not yet reasoned: call ``reason()``.
    """
    vocabulary = vocabulary or load_vocabulary()
    kb = KnowledgeBase(ontology, vocabulary=vocabulary, owl=owl)
    anchors = []
    for i, sign in enumerate(signs):
        text = str(sign.get("text", ""))
        kind = _place_kind(text, vocabulary)
        facing = math.radians(float(sign.get("facing", 0.0)))
        x = float(sign["x"]) - 1.0 * math.cos(facing)  # behind the plate, in the room
        y = float(sign["y"]) - 1.0 * math.sin(facing)
        place_id = sign_place_id(i)
        anchors.append((place_id, x, y))
        kb.add_place(place_id, kind, name=text or None, centroid=(x, y))
        kb.add_sign(f"sign_{i + 1}", text, x=float(sign["x"]), y=float(sign["y"]),
                    facing_deg=float(sign.get("facing", 0.0)), place_id=place_id,
                    place_class=kind)
    for i, obj in enumerate(objects):
        ox, oy = float(obj["x"]), float(obj["y"])
        near = min(anchors, key=lambda a: math.hypot(a[1] - ox, a[2] - oy), default=None)
        place_id = near[0] if near and math.hypot(near[1] - ox, near[2] - oy) < 4.0 else None
        kb.add_object(f"object_{i + 1}", str(obj["label"]), x=ox, y=oy, place_id=place_id,
                      observed=True)
    if timetable is not None:
        kb.add_timetable(timetable)
    return kb


def write_semantic_map(out_dir: str | Path, sm: SemanticMap, occupancy: OccupancyMap, *,
                       signs: list[Mapping[str, Any]] | None = None,
                       objects: list[Mapping[str, Any]] | None = None,
                       picture: str = "maps/semantic.png") -> list[Path]:
    """Write ``semantic_map.ttl``, ``places.geojson`` and the picture into ``out_dir``.

    Parameters
    ----------
    out_dir
        The run's output folder.
    sm
        The semantic map.
    occupancy
        The map the places were segmented from (drawn underneath them).
    signs, objects
        Drawn on the picture when given.
    picture
        The picture's path relative to ``out_dir``.

    Returns
    -------
    list of Path
        The files written.
    """
    from .place_io import draw_place_map, write_places_geojson
    out = Path(out_dir)
    ttl = out / "semantic_map.ttl"
    geojson = out / "places.geojson"
    png = out / picture
    sm.kb.serialize(ttl)
    kinds = {**sm.kinds, **{pid: sm.kb.place_kind(pid) or "Room" for pid in sm.unentered}}
    write_places_geojson(geojson, sm.places, names=sm.names, kinds=kinds, unentered=sm.unentered)
    labels = {p.id: sm.names.get(p.id) or sm.kinds.get(p.id, "") for p in sm.places.places}
    draw_place_map(png, sm.places, occupancy, labels=labels, signs=signs, objects=objects,
                   unentered=sm.unentered,
                   title="semantic map: places, doors, signs and objects")
    return [ttl, geojson, png]
