"""Place segmentation, the place graph, sign attachment, GeoJSON/PNG output and scoring.

The office world's own floor plan is the reference: every signed room must
come out as one place (IoU >= 0.9) with its door found at the right width,
the corridor loop must be one place, and each door sign must name its room,
not the corridor it hangs in.
"""
from __future__ import annotations

import json
import math

import numpy as np
import pytest

from blocks.maps.mapio import OccupancyMap
from semantic.place_io import draw_place_map, places_geojson, write_places_geojson
from semantic.place_score import score_places, true_map
from semantic.places import attach_signs, place_names, segment_places
from sim2d.worlds import WORLDS_DIR
from sim2d.world import load_world

_CACHE: dict = {}


def office():
    """(world, true map, segmentation, sign dicts, attachment) of the office, computed once."""
    if not _CACHE:
        w = load_world(WORLDS_DIR / "office.yaml")
        m = true_map(w)
        pm = segment_places(m)
        signs = [{"text": s.text, "x": s.x, "y": s.y, "facing": math.degrees(s.facing)}
                 for s in w.signs]
        _CACHE.update(world=w, map=m, pm=pm, signs=signs, attached=attach_signs(pm, signs))
    return _CACHE


def test_office_rooms_are_one_place_each_with_their_doors():
    c = office()
    names = place_names(c["signs"], c["attached"])
    score = score_places(c["pm"], c["world"], names=names)
    assert score["room_count"] == 14
    for room in score["rooms"]:
        assert room["one_place"], room
        assert room["iou"] >= 0.9, room
        assert room["door_found"] and abs(room["door_width_error"]) <= 0.2, room
    assert [r["one_place"] for r in score["corridors"]] == [True]
    assert score["mean_iou"] >= 0.95


def test_office_signs_name_their_rooms_not_the_corridor():
    c = office()
    pm, w = c["pm"], c["world"]
    corridor = pm.place_at(1.0, 10.0)
    assert corridor is not None
    assert pm.place(corridor).kind_hint == "corridor"
    for i, sign in enumerate(c["signs"]):
        pid = c["attached"][i]
        assert pid is not None and pid != corridor, sign["text"]
        room = w.place(sign["text"])
        (x0, y0), (x1, y1) = room.polygon.min(axis=0), room.polygon.max(axis=0)
        hits = [pm.place_at(x, y) for x in np.linspace(x0 + 0.2, x1 - 0.2, 7)
                for y in np.linspace(y0 + 0.2, y1 - 0.2, 7)]
        hits = [h for h in hits if h is not None]  # points on furniture are in no place
        assert max(set(hits), key=hits.count) == pid, sign["text"]


def test_place_graph_is_a_star_around_the_corridor():
    pm = office()["pm"]
    corridor = pm.place_at(15.0, 6.0)
    assert pm.place_at(15.0, 14.0) == corridor and pm.place_at(29.0, 10.0) == corridor
    g = pm.graph
    assert g.number_of_nodes() == 15 and g.degree[corridor] == 14
    for node, data in g.nodes(data=True):
        assert data["polygon"].shape[1] == 2 and data["area"] > 0
        if node != corridor:
            assert data["kind_hint"] == "room" and g.degree[node] == 1
            edge = g.edges[node, corridor]
            assert edge["width"] == pytest.approx(1.0, abs=0.1)
            assert pm.place_at(edge["x"], edge["y"] + 0.3) in (node, corridor)
    assert pm.place_at(15.0, 10.0) is not None  # the core: elevator / stairs, not the corridor
    assert pm.place_at(-0.3, 10.0) is None  # outside the building
    assert pm.seconds < 5


def two_rooms_and_corridor(res: float = 0.05) -> OccupancyMap:
    """A 10 m x 2 m corridor (y 4..6) with two 4 m x 4 m rooms south of it, 1 m doors."""
    h, w = int(round(8 / res)), int(round(12 / res))
    occ = np.ones((h, w))

    def clear(x0, y0, x1, y1):
        occ[int(round(y0 / res)):int(round(y1 / res)), int(round(x0 / res)):int(round(x1 / res))] = 0

    clear(1, 4, 11, 6)        # corridor
    clear(1, 0.2, 5, 3.9)     # room A (wall 3.9..4)
    clear(6, 0.2, 10, 3.9)    # room B
    clear(2.5, 3.9, 3.5, 4)   # door A, x 2.5..3.5
    clear(7.5, 3.9, 8.5, 4)   # door B
    return OccupancyMap(occupancy=occ, resolution=res, origin=(0.0, 0.0, 0.0))


def test_synthetic_two_rooms_and_a_corridor():
    m = two_rooms_and_corridor()
    pm = segment_places(m)
    a, b, corr = pm.place_at(3, 2), pm.place_at(8, 2), pm.place_at(6, 5)
    assert len({a, b, corr}) == 3 and None not in {a, b, corr}
    assert len(pm.places) == 3 and len(pm.doors) == 2
    for room, cx in ((a, 3.0), (b, 8.0)):
        (door,) = pm.doors_of(room)
        assert door.other(room) == corr
        assert door.x == pytest.approx(cx, abs=0.1) and door.y == pytest.approx(3.95, abs=0.2)
        assert door.width == pytest.approx(1.0, abs=0.1)
        assert pm.place(room).area == pytest.approx(4 * 3.7, rel=0.05)
    labels = pm.labels
    assert labels.dtype == np.int32 and labels.shape == m.shape
    assert labels[int(2 / 0.05), int(3 / 0.05)] == int(a[1:])  # row 0 = lowest y
    # a sign beside door A on the corridor face, facing north: room A, not the corridor
    signs = [{"x": 2.0, "y": 4.0, "facing": 90.0, "text": "A"},
             {"x": 6.0, "y": 6.0, "facing": -90.0, "text": "NOWHERE"}]  # no door: wall behind
    assert attach_signs(pm, signs) == {0: a, 1: None}


def test_a_sign_beside_its_door_beats_one_that_looks_through_the_wall():
    """The office's ELEVATOR plate, its own door unmapped, once named the STAIRS room
    next door through the wall, and the STAIRS sign, beside its door, lost its room."""
    pm = segment_places(two_rooms_and_corridor())
    a = pm.place_at(3, 2)
    beside_door = {"x": 3.8, "y": 4.0, "facing": 90.0, "text": "A"}  # door A 0.8 m away
    through_wall = {"x": 4.8, "y": 4.0, "facing": 90.0, "text": "OTHER"}  # door A 1.8 m away
    for signs in ([through_wall, beside_door], [beside_door, through_wall]):
        k = signs.index(beside_door)
        assert attach_signs(pm, signs, max_door_distance=1.5) == {k: a, 1 - k: None}
        assert attach_signs(pm, signs) == {k: a, 1 - k: None}  # both by the door: the nearer
    # two plates of one room (its two sightings, or a sign on each door) both name it
    twin = dict(through_wall, text="a")
    assert attach_signs(pm, [beside_door, twin], max_door_distance=1.5) == {0: a, 1: a}


def test_a_wide_opening_does_not_split():
    m = two_rooms_and_corridor()
    occ = m.occupancy
    occ[int(3.9 / 0.05):int(4 / 0.05), int(1 / 0.05):int(5 / 0.05)] = 0  # room A wide open
    pm = segment_places(m)
    assert pm.place_at(3, 2) == pm.place_at(6, 5)
    assert pm.place_at(8, 2) != pm.place_at(6, 5)


def test_unknown_cells_are_in_no_place():
    m = two_rooms_and_corridor()
    m.occupancy[: int(2 / 0.05), : int(5.5 / 0.05)] = np.nan  # half of room A unknown
    pm = segment_places(m)
    assert pm.place_at(3, 1) is None and pm.place_at(3, 3) is not None
    assert pm.place_at(3, 3) != pm.place_at(6, 5)


def test_geojson_round_trips_with_closed_rings(tmp_path):
    c = office()
    names = place_names(c["signs"], c["attached"])
    path = write_places_geojson(tmp_path / "places.geojson", c["pm"], names)
    doc = json.loads(path.read_text())
    assert doc == json.loads(json.dumps(places_geojson(c["pm"], names)))
    assert doc["type"] == "FeatureCollection"
    polys = [f for f in doc["features"] if f["geometry"]["type"] == "Polygon"]
    points = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    assert len(polys) == 15 and len(points) == 14
    for f in polys:
        ring = f["geometry"]["coordinates"][0]
        assert len(ring) >= 4 and ring[0] == ring[-1]
        x, y = np.array(ring).T
        assert 0.5 * np.sum(x[:-1] * y[1:] - x[1:] * y[:-1]) > 0  # counter-clockwise
    assert {f["properties"]["name"] for f in polys} >= {"MAIL ROOM", "KITCHEN", "LIBRARY"}
    for f in points:
        assert f["properties"]["kind"] == "door" and len(f["properties"]["between"]) == 2


def test_place_png_is_written(tmp_path):
    c = office()
    path = draw_place_map(tmp_path / "places.png", c["pm"], c["map"],
                          labels=place_names(c["signs"], c["attached"]), signs=c["signs"])
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_score_penalises_a_wrong_name():
    c = office()
    names = place_names(c["signs"], c["attached"])
    kitchen = next(pid for pid, t in names.items() if t == "KITCHEN")
    mail = next(pid for pid, t in names.items() if t == "MAIL ROOM")
    names[kitchen], names[mail] = "MAIL ROOM", "KITCHEN"
    score = score_places(c["pm"], c["world"], names=names)
    rows = {r["name"]: r for r in score["rooms"]}
    assert rows["KITCHEN"]["iou"] < 0.1 and not rows["KITCHEN"]["one_place"]
    assert rows["ADMIN"]["iou"] > 0.9


def test_polygon_mask_is_the_even_odd_rule_at_cell_centres():
    """Row-by-row crossings give the cells a whole-grid even-odd test gives, also for
    self-crossing polygons, horizontal edges and vertices on cell centres."""
    from semantic.place_score import polygon_mask_on_grid

    def reference(poly, shape, res, origin):
        h, w = shape
        px, py = np.meshgrid(origin[0] + (np.arange(w) + 0.5) * res,
                             origin[1] + (np.arange(h) + 0.5) * res)
        inside = np.zeros(shape, bool)
        for (x1, y1), (x2, y2) in zip(poly, np.roll(poly, -1, axis=0)):
            if y1 != y2:
                inside ^= ((y1 > py) != (y2 > py)) & (px < x1 + (py - y1) * (x2 - x1) / (y2 - y1))
        return inside

    rng = np.random.default_rng(6)
    shapes = [np.array([[1, 1], [8, 1], [8, 6], [1, 6], [1, 4], [6, 4], [6, 3], [1, 3]], float),
              np.array([[0.625, 0.625], [9.125, 0.625], [9.125, 0.625], [5.125, 8.875]])]
    shapes += [rng.uniform(0, 10, (rng.integers(3, 12), 2)) for _ in range(60)]
    shapes += [np.round(rng.uniform(0, 10, (6, 2)) * 4) / 4 + 0.125 for _ in range(30)]
    for poly in shapes:
        for res, shape, origin in [(0.25, (48, 44), (-0.5, -0.5, 0.0)),
                                   (0.1, (90, 120), (0.05, -0.3, 0.0))]:
            expected = reference(poly, shape, res, origin)
            assert np.array_equal(polygon_mask_on_grid(poly, shape, res, origin), expected)
    assert reference(shapes[0], (48, 44), 0.25, (-0.5, -0.5, 0.0)).sum() > 100


def test_a_room_without_a_sign_is_scored_against_its_own_unnamed_place():
    """With the ADMIN plate taken down, ADMIN is an unsigned room: its place must exist
    and carry no name.  Naming that place after another room's sign, or shutting the
    room's door, changes what is scored."""
    import dataclasses
    c = office()
    w = dataclasses.replace(c["world"], signs=[s for s in c["world"].signs if s.text != "ADMIN"])
    signs = [s for s in c["signs"] if s["text"] != "ADMIN"]
    names = place_names(signs, attach_signs(c["pm"], signs))
    score = score_places(c["pm"], w, names=names)
    assert score["room_count"] == 13 and score["unsigned_count"] == 1
    (admin,) = score["unsigned"]
    assert admin["name"] == "ADMIN" and admin["named_as"] is None and admin["iou"] >= 0.9
    assert score["unsigned_places"] == 1 and score["open_count"] == 14
    assert score["open_mean_iou"] >= 0.95

    wrong = dict(names, **{admin["place"]: "KITCHEN"})
    (misnamed,) = score_places(c["pm"], w, names=wrong)["unsigned"]
    assert misnamed["named_as"] == "KITCHEN" and misnamed["iou"] == 0.0

    shut = [dataclasses.replace(d, closed=True) if "ADMIN" in d.between else d for d in w.doors]
    closed = score_places(c["pm"], dataclasses.replace(w, doors=shut), names=names)
    assert closed["unsigned_count"] == 0 and closed["open_count"] == 13
