"""Place maps out: a GeoJSON file of places and doors, and a PNG of the map coloured by place.

GeoJSON coordinates are map-frame metres (x, y), not longitude/latitude: the
file is for viewers and tools that take planar coordinates (QGIS with a local
CRS, shapely, geojson.io's raw view) and for the ontology export.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any, Iterable, Mapping

import numpy as np

from blocks.core.atomic import atomic_write_figure, atomic_write_text
from blocks.maps.mapio import OccupancyMap, display_sized, map_rgba
from semantic.places import PlaceMap


def _ring(polygon: np.ndarray) -> list[list[float]]:
    """A closed GeoJSON ring (first corner repeated), counter-clockwise, 3 decimals."""
    pts = [[round(float(x), 3), round(float(y), 3)] for x, y in polygon]
    if pts and pts[0] != pts[-1]:
        pts.append(list(pts[0]))
    return pts


def places_geojson(pm: PlaceMap, names: Mapping[str, str] | None = None,
                   kinds: Mapping[str, str] | None = None,
                   unentered: Mapping[str, tuple[str, tuple[float, float]]] | None = None
                   ) -> dict[str, Any]:
    """The place map as a GeoJSON FeatureCollection (a dict).

    Parameters
    ----------
    pm
        The segmentation.
    names
        Place id -> name (sign text), optional.
    kinds
        Place id -> kind (ontology class); defaults to the place's kind hint
        (``"corridor"`` / ``"room"``).
    unentered
        Id -> (name, (x, y)) of the rooms known only by their signs
        (:attr:`semantic.semantic_map.SemanticMap.unentered`), optional.

    Returns
    -------
    dict
        One Polygon feature per place (properties ``id``, ``name``, ``kind``,
        ``kind_hint``, ``area`` m^2, ``centroid`` [x, y]), one Point feature
        per door (``id``, ``kind: "door"``, ``width`` m, ``between`` [id, id])
        and one Point feature per room known only by its sign, at its door
        (``id``, ``name``, ``kind``, ``entered: false``).
    """
    names, kinds = dict(names or {}), dict(kinds or {})
    features = []
    for p in pm.places:
        if len(p.polygon) < 3:
            continue
        features.append({
            "type": "Feature",
            "geometry": {"type": "Polygon", "coordinates": [_ring(p.polygon)]},
            "properties": {"id": p.id, "name": names.get(p.id), "kind": kinds.get(p.id, p.kind_hint),
                           "kind_hint": p.kind_hint, "area": round(p.area, 3),
                           "centroid": [round(p.centroid[0], 3), round(p.centroid[1], 3)]},
        })
    for d in pm.doors:
        features.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(d.x, 3), round(d.y, 3)]},
            "properties": {"id": d.id, "kind": "door", "width": round(d.width, 3),
                           "between": [d.a, d.b]},
        })
    for pid, (name, (x, y)) in (unentered or {}).items():
        features.append({
            "type": "Feature",
            "geometry": {"type": "Point", "coordinates": [round(x, 3), round(y, 3)]},
            "properties": {"id": pid, "name": name, "kind": kinds.get(pid, "room"),
                           "entered": False},
        })
    return {"type": "FeatureCollection", "name": "places",
            "properties": {"frame": "map", "units": "m", "resolution": pm.resolution},
            "features": features}


def write_places_geojson(path: str | Path, pm: PlaceMap, names: Mapping[str, str] | None = None,
                         kinds: Mapping[str, str] | None = None,
                         unentered: Mapping[str, tuple[str, tuple[float, float]]] | None = None
                         ) -> Path:
    """Write :func:`places_geojson` to ``path`` (atomically); returns the path."""
    path = Path(path)
    atomic_write_text(path, json.dumps(places_geojson(pm, names, kinds, unentered), indent=1)
                      + "\n")
    return path


def _colours(n: int) -> np.ndarray:
    """n distinct pastel RGB colours (deterministic golden-angle hues)."""
    import colorsys

    return np.array([colorsys.hsv_to_rgb((i * 0.618034) % 1.0, 0.45, 0.95) for i in range(n)])


def _label_point(pm: PlaceMap, place: Any) -> tuple[float, float]:
    """The centroid, or (for a ring such as a corridor loop) the place's cell nearest to it."""
    if pm.place_at(*place.centroid) == place.id:
        return place.centroid
    rows, cols = np.nonzero(place.mask)
    xs = pm.origin[0] + (cols + 0.5) * pm.resolution
    ys = pm.origin[1] + (rows + 0.5) * pm.resolution
    j = int(np.argmin((xs - place.centroid[0]) ** 2 + (ys - place.centroid[1]) ** 2))
    return float(xs[j]), float(ys[j])


def draw_place_map(path: str | Path, pm: PlaceMap, m: OccupancyMap,
                   labels: Mapping[str, str] | None = None,
                   signs: Iterable[Mapping[str, Any]] | None = None,
                   title: str | None = None, size_px: int = 1200,
                   objects: Iterable[Mapping[str, Any]] | None = None,
                   unentered: Mapping[str, tuple[str, tuple[float, float]]] | None = None
                   ) -> Path:
    """A PNG of the map coloured by place, with names at centroids and doors marked.

    Parameters
    ----------
    path
        The PNG to write (atomically).
    pm
        The segmentation of ``m``.
    m
        The occupancy map (walls black, unknown grey as in the hybrid map).
    labels
        Place id -> text to print at its centroid (default: the id); corridors
        are printed in italics.
    signs
        Optional sign records (x, y, facing in degrees, text): red squares with
        an arrow along the facing.
    title
        Figure title.
    size_px
        Width of the picture (px).
    objects
        Optional object records (label, x, y): blue diamonds with their label.
    unentered
        Optional id -> (name, (x, y)): rooms known only by their signs, their
        names in a dashed box at their doors.

    Returns
    -------
    Path
    """
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    rgb = map_rgba(m)  # 8-bit: a float picture of a large map costs ~150 MB to draw
    colours = (_colours(len(pm.places) + 1) * 255).astype(np.uint8)  # as matplotlib truncates
    for i, place in enumerate(pm.places):
        rgb[pm.labels == int(place.id[1:]), :3] = colours[i]
    rgb[m.classes()[0], :3] = 0  # walls over the places
    h, w = m.shape
    ox, oy = float(m.origin[0]), float(m.origin[1])
    extent = (ox, ox + w * m.resolution, oy, oy + h * m.resolution)
    width, height = extent[1] - extent[0], extent[3] - extent[2]
    fig_h = max(3.0, size_px / 100 * height / width) + 0.6
    fig, ax = plt.subplots(figsize=(size_px / 100, fig_h), dpi=100)
    try:
        ax.imshow(display_sized(rgb, size_px, 100 * fig_h), origin="lower", extent=extent,
                  interpolation="nearest", zorder=0)
        for place in pm.places:
            if len(place.polygon) >= 3:
                ring = np.vstack([place.polygon, place.polygon[:1]])
                ax.plot(ring[:, 0], ring[:, 1], color="#333333", lw=0.6, zorder=2)
            text = (labels or {}).get(place.id, place.id)
            ax.text(*_label_point(pm, place), text, fontsize=7, ha="center", va="center", zorder=6,
                    style="italic" if place.kind_hint == "corridor" else "normal",
                    bbox={"boxstyle": "round,pad=0.15", "fc": "white", "ec": "none",
                          "alpha": 0.75})
        for k, d in enumerate(pm.doors):
            ax.plot(d.x, d.y, "o", mfc="#ffb000", mec="#7a4f00", ms=5, zorder=5,
                    label="door" if k == 0 else None)
            ax.text(d.x, d.y, f" {d.width:.2f}", fontsize=5, color="#7a4f00", va="bottom",
                    zorder=5)
        arrow = 0.8
        for k, s in enumerate(signs or []):
            x, y = float(s["x"]), float(s["y"])
            ax.plot(x, y, "s", color="#b03a2e", ms=4, zorder=7, label="sign" if k == 0 else None)
            f = math.radians(float(s.get("facing", float("nan"))))
            if math.isfinite(f):
                ax.annotate("", xy=(x + arrow * math.cos(f), y + arrow * math.sin(f)),
                            xytext=(x, y), zorder=7,
                            arrowprops={"arrowstyle": "->", "color": "#b03a2e", "lw": 1.0})
        for k, (name, (x, y)) in enumerate((unentered or {}).values()):
            ax.plot(x, y, "v", color="#6c3483", ms=5, zorder=7,
                    label="room read, not entered" if k == 0 else None)
            ax.text(x, y + 0.2, name, fontsize=6, color="#6c3483", ha="center", va="bottom",
                    zorder=7, bbox={"boxstyle": "round,pad=0.15", "fc": "white",
                                    "ec": "#6c3483", "ls": "--", "alpha": 0.75})
        for k, o in enumerate(objects or []):
            x, y = float(o["x"]), float(o["y"])
            ax.plot(x, y, "D", color="#1f5fa8", ms=4, zorder=7, label="object" if k == 0 else None)
            ax.text(x, y - 0.25, str(o.get("label", "")), fontsize=5, color="#1f5fa8",
                    ha="center", va="top", zorder=7)
        ax.set_xlim(extent[0], extent[1])
        ax.set_ylim(extent[2], extent[3])
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(title if title is not None else
                     f"places: {len(pm.places)} places, {len(pm.doors)} doors")
        if pm.doors or signs or objects or unentered:
            ax.legend(loc="upper right", fontsize=7)
        fig.tight_layout()
        return atomic_write_figure(path, fig)
    finally:
        plt.close(fig)
