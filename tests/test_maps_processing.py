"""The processed online map: smoothing, edge detection and border tracing into walls."""
from __future__ import annotations

import json

import numpy as np
import pytest
from matplotlib.path import Path as PolygonPath

from blocks.maps.mapio import OccupancyMap
from blocks.maps.processing import (
    ProcessedMap,
    polyline_length,
    process_occupancy_map,
    walls_to_geojson,
    write_walls_geojson,
)

RES = 0.05
ORIGIN = (-1.3, 2.1, 0.0)


def paper_like(p: np.ndarray, origin=ORIGIN) -> OccupancyMap:
    """A map with the paper map's thresholds (free levels 0, 1/3, 2/3; borders 1)."""
    return OccupancyMap(p, RES, origin, occupied_thresh=0.9, free_thresh=0.7)


def cell(x: float, y: float, origin=ORIGIN) -> tuple[int, int]:
    """[iy, ix] of the cell containing world point (x, y)."""
    return int(np.floor((y - origin[1]) / RES)), int(np.floor((x - origin[0]) / RES))


def dist_to_outline(points: np.ndarray, x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    """Distance from each point to the outline of the axis-aligned rectangle."""
    x, y = points[:, 0], points[:, 1]
    inside = (x > x0) & (x < x1) & (y > y0) & (y < y1)
    d_in = np.minimum.reduce([x - x0, x1 - x, y - y0, y1 - y])
    d_out = np.hypot(x - np.clip(x, x0, x1), y - np.clip(y, y0, y1))
    return np.where(inside, d_in, d_out)


def dist_to_polyline(q: np.ndarray, line: np.ndarray) -> float:
    """Shortest distance from point q to a polyline's segments."""
    a, b = line[:-1], line[1:]
    ab = b - a
    t = np.clip(((q - a) * ab).sum(1) / np.maximum((ab * ab).sum(1), 1e-12), 0, 1)
    return float(np.hypot(*(a + t[:, None] * ab - q).T).min())


def signed_area(line: np.ndarray) -> float:
    x, y = line[:, 0], line[:, 1]
    return 0.5 * float(np.dot(x[:-1], y[1:]) - np.dot(y[:-1], x[1:]))


# ---- a noisy 4 m x 3 m room ----------------------------------------------------------------
# free cells ix 20..99, iy 20..79 of a 100 x 120 grid: x in [-0.3, 3.7], y in [3.1, 6.1]
X0, Y0 = ORIGIN[0] + 20 * RES, ORIGIN[1] + 20 * RES
X1, Y1 = X0 + 4.0, Y0 + 3.0
SPECKLE = (slice(5, 13), slice(3, 11))         # 0.4 x 0.4 m of free space outside the room
HOLE = (slice(50, 54), slice(60, 64))           # 0.2 x 0.2 m unknown hole inside it


def noisy_room(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    p = np.full((100, 120), np.nan)
    p[20:80, 20:100] = rng.choice([0.0, 1 / 3, 2 / 3], size=(60, 80))
    # ragged edges: cells either side of the true edge flipped free <-> unknown
    band = np.zeros(p.shape, bool)
    band[19:81, 19:101] = True
    band[21:79, 21:99] = False
    flip = band & (rng.random(p.shape) < 0.2)
    p[flip] = np.where(np.isnan(p[flip]), 1 / 3, np.nan)
    inside = np.zeros(p.shape, bool)
    inside[23:77, 23:97] = True
    p[inside & (rng.random(p.shape) < 0.03)] = np.nan    # unknown specks in the room
    outside = np.ones(p.shape, bool)
    outside[17:83, 17:103] = False
    p[outside & (rng.random(p.shape) < 0.03)] = 0.0      # free specks outside it
    p[SPECKLE] = 0.0
    p[HOLE] = np.nan
    # the paper's borders: unknown cells next to free ones (processing must ignore them)
    free = np.nan_to_num(p, nan=1.0) < 0.7
    grown = np.zeros_like(free)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            grown |= np.roll(np.roll(free, dy, 0), dx, 1)
    p[grown & np.isnan(p)] = 1.0
    return p


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_noisy_room_is_traced_as_one_wall_around_the_true_rectangle(seed):
    m = paper_like(noisy_room(seed))
    pm = process_occupancy_map(m)
    assert isinstance(pm, ProcessedMap)
    assert pm.kinds == ["outer"]                 # speckles gone, small hole filled
    wall = pm.walls[0]
    assert wall.shape[1] == 2 and np.array_equal(wall[0], wall[-1])
    # Walls run through the centres of the cells just outside the free space, i.e. on the
    # true rectangle grown by half a cell; noise may leave a vertex one cell off that line.
    h = RES / 2
    assert dist_to_outline(wall, X0 - h, Y0 - h, X1 + h, Y1 + h).max() <= RES + 1e-9
    # Convex corners are rounded by the opening (radius smooth_m = 3 cells): < 2 cells.
    for corner in [(X0 - h, Y0 - h), (X1 + h, Y0 - h), (X1 + h, Y1 + h), (X0 - h, Y1 + h)]:
        assert dist_to_polyline(np.array(corner), wall) < 2 * RES
    assert polyline_length(wall) == pytest.approx(14.0, rel=0.05)
    assert signed_area(wall) > 0                 # counter-clockwise: free space on the left

    occupied, free, unknown = pm.map.classes()
    assert pm.map.origin == ORIGIN and pm.map.shape == m.shape
    assert (pm.map.occupied_thresh, pm.map.free_thresh) == (0.65, 0.196)
    assert unknown[SPECKLE].all()                # speckle removed
    assert free[HOLE].all()                      # hole filled
    assert free[25:75, 25:95].all()
    for x, y in wall:                            # the wall is drawn into the map
        assert occupied[cell(x, y)]
    # nothing free or occupied far from the room
    far = np.ones(m.shape, bool)
    far[16:84, 16:104] = False
    assert unknown[far].all()


def test_a_clean_rectangle_at_one_metre_cells_is_traced_exactly():
    p = np.full((10, 12), np.nan)
    p[2:8, 2:10] = 0.0
    pm = process_occupancy_map(OccupancyMap(p, 1.0, (10.0, -5.0, 0.0)), smooth_m=0,
                               fill_gap_m=0, min_region_m2=0, min_wall_m=0)
    # free x in [12, 20], y in [-3, 3]; wall cells' centres half a cell outside
    assert pm.walls[0].tolist() == [[11.5, -3.5], [20.5, -3.5], [20.5, 3.5], [11.5, 3.5],
                                    [11.5, -3.5]]
    occupied, free, _ = pm.map.classes()
    assert free.sum() == 48 and occupied.sum() == 2 * (10 + 8) - 4
    assert occupied[1, 1:11].all() and occupied[8, 1:11].all()


# ---- obstacles, shapes, walls ---------------------------------------------------------------
@pytest.mark.parametrize("value", [np.nan, 1.0])
def test_an_obstacle_inside_free_space_gets_its_own_clockwise_wall(value):
    p = np.full((80, 80), np.nan)
    p[10:70, 10:70] = 0.0                        # 3 m x 3 m free
    p[30:50, 30:50] = value                      # 1 m x 1 m obstacle, unknown or occupied
    origin = (2.0, -1.0, 0.0)
    pm = process_occupancy_map(OccupancyMap(p, RES, origin))
    assert sorted(pm.kinds) == ["inner", "outer"]
    inner = pm.walls[pm.kinds.index("inner")]
    # obstacle x in [3.5, 4.5], y in [0.5, 1.5]; its wall runs through its edge cells' centres
    h = RES / 2
    assert dist_to_outline(inner, 3.5 + h, 0.5 + h, 4.5 - h, 1.5 - h).max() <= RES + 1e-9
    # 4 x 19 cells between edge-cell centres, less the corners the smoothing rounds off
    assert polyline_length(inner) == pytest.approx(3.8, rel=0.1)
    assert signed_area(inner) < 0                # clockwise: free space still on the left
    assert signed_area(pm.walls[pm.kinds.index("outer")]) > 0
    _, free, unknown = pm.map.classes()
    assert unknown[33:47, 33:47].all()           # the obstacle's inside stays unknown
    assert free[12:28, 12:68].all()


def test_small_holes_are_filled_unless_occupied_cells_are_trusted():
    p = np.full((60, 60), np.nan)
    p[10:50, 10:50] = 0.0
    p[20:24, 20:24] = np.nan                     # 0.2 m unknown patch: filled
    p[35:39, 35:39] = 1.0                        # 0.2 m pillar seen occupied
    m = OccupancyMap(p, RES, (0.0, 0.0, 0.0))
    assert process_occupancy_map(m).kinds == ["outer"]
    kept = process_occupancy_map(m, keep_occupied=True)
    assert sorted(kept.kinds) == ["inner", "outer"]
    _, free, _ = kept.map.classes()
    assert free[20:24, 20:24].all() and not free[35:39, 35:39].any()


def test_a_wall_between_two_rooms_survives_smoothing():
    p = np.full((60, 100), np.nan)
    p[10:50, 10:48] = 0.0
    p[10:50, 52:90] = 0.0                        # a 0.2 m (4 cell) unknown wall between
    pm = process_occupancy_map(paper_like(p, (0.0, 0.0, 0.0)))
    assert pm.kinds == ["outer", "outer"]
    _, free, _ = pm.map.classes()
    assert not free[:, 48:52].any()


def test_an_l_shape_is_not_flipped_or_transposed():
    # free: a bar along x (x 0..4, y 0..1) and a bar along y (x 0..1, y 0..2.5), in a map
    # that is wider than tall and has an offset origin
    origin = (-0.5, 1.0, 0.0)
    p = np.full((70, 100), np.nan)
    p[10:30, 10:90] = 0.0                        # rows are y: y 1.5..2.5, x 0..4
    p[10:60, 10:30] = 0.0                        # y 1.5..4.0, x 0..1
    pm = process_occupancy_map(OccupancyMap(p, RES, origin))
    assert pm.kinds == ["outer"]
    region = PolygonPath(pm.walls[0])
    inside = [(3.5, 2.0), (0.5, 3.5), (0.5, 2.0)]
    outside = [(3.5, 3.5), (2.0, 3.0), (-0.3, 1.2), (4.2, 2.0)]
    assert region.contains_points(inside).all()
    assert not region.contains_points(outside).any()
    xs, ys = pm.walls[0][:, 0], pm.walls[0][:, 1]
    assert xs.min() == pytest.approx(-0.025) and xs.max() == pytest.approx(4.025)
    assert ys.min() == pytest.approx(1.475) and ys.max() == pytest.approx(4.025)
    _, free, _ = pm.map.classes()
    assert free[cell(3.5, 2.0, origin)] and not free[cell(3.5, 3.5, origin)]


def test_short_walls_are_dropped():
    p = np.full((60, 60), np.nan)
    p[10:50, 10:50] = 0.0
    m = OccupancyMap(p, RES, (0.0, 0.0, 0.0))
    assert len(process_occupancy_map(m).walls) == 1
    assert process_occupancy_map(m, min_wall_m=9.0).walls == []


@pytest.mark.parametrize("value", [np.nan, 1.0])
def test_a_map_without_free_space_has_no_walls(value):
    m = OccupancyMap(np.full((30, 40), value), RES, ORIGIN)
    pm = process_occupancy_map(m)
    assert pm.walls == [] and pm.kinds == []
    assert np.isnan(pm.map.occupancy).all() and pm.map.shape == (30, 40)
    assert walls_to_geojson(pm.walls)["features"] == []


def test_free_space_at_the_edge_of_the_grid_is_walled_just_outside_it():
    p = np.zeros((20, 30))
    pm = process_occupancy_map(OccupancyMap(p, RES, (0.0, 0.0, 0.0)))
    xs, ys = pm.walls[0][:, 0], pm.walls[0][:, 1]
    assert xs.min() == pytest.approx(-0.025) and xs.max() == pytest.approx(1.525)
    assert ys.min() == pytest.approx(-0.025) and ys.max() == pytest.approx(1.025)


def test_bad_input_is_refused():
    m = OccupancyMap(np.zeros((5, 5)), RES, (0.0, 0.0, 0.3))
    with pytest.raises(ValueError, match="yaw"):
        process_occupancy_map(m)
    with pytest.raises(ValueError, match="smooth_m"):
        process_occupancy_map(OccupancyMap(np.zeros((5, 5)), RES, (0, 0, 0)), smooth_m=-1)


# ---- lengths and GeoJSON -------------------------------------------------------------------
def test_polyline_length():
    assert polyline_length([[0, 0], [3, 4], [3, 0]]) == pytest.approx(9.0)
    assert polyline_length(np.array([[0.0, 0.0], [1, 0], [1, 1], [0, 1], [0, 0]])) == 4.0
    assert polyline_length([[1, 1]]) == 0.0 and polyline_length(np.empty((0, 2))) == 0.0


def test_geojson_round_trip_is_atomic_and_in_metres(tmp_path):
    pm = process_occupancy_map(paper_like(noisy_room(0)))
    walls = pm.walls + [np.array([[0.1234567, -2.0], [1.0, -2.0004]])]   # an open polyline
    path = write_walls_geojson(tmp_path / "sub" / "walls.geojson", walls,
                               properties={"source": "test"},
                               feature_properties=[{"kind": k} for k in pm.kinds] + [{}])
    assert path == tmp_path / "sub" / "walls.geojson"
    assert [p.name for p in path.parent.iterdir()] == ["walls.geojson"]  # no temporaries
    doc = json.loads(path.read_text())
    assert doc["type"] == "FeatureCollection" and "crs" not in doc
    assert doc["properties"] == {"frame": "map", "units": "m", "source": "test"}
    assert len(doc["features"]) == len(walls)
    for feature, wall in zip(doc["features"], walls):
        assert feature["type"] == "Feature"
        assert feature["geometry"]["type"] == "LineString"
        coords = np.array(feature["geometry"]["coordinates"])
        assert coords.shape == wall.shape
        assert np.abs(coords - wall).max() <= 0.0005 + 1e-12
        assert feature["properties"]["length_m"] == pytest.approx(polyline_length(wall),
                                                                 abs=0.001)
    assert doc["features"][0]["properties"]["closed"] is True
    assert doc["features"][0]["properties"]["kind"] == "outer"
    last = doc["features"][-1]
    assert last["properties"] == {"length_m": 0.877, "closed": False}
    assert last["geometry"]["coordinates"] == [[0.123, -2.0], [1.0, -2.0]]
    # the in-memory document is unrounded and the same as ProcessedMap.to_geojson's shape
    assert pm.to_geojson()["features"][0]["properties"]["kind"] == "outer"
    assert walls_to_geojson(walls)["features"][-1]["geometry"]["coordinates"][0][0] == 0.1234567


def test_geojson_rejects_mismatched_properties_and_degenerate_walls():
    with pytest.raises(ValueError, match="feature_properties"):
        walls_to_geojson([np.zeros((3, 2))], feature_properties=[])
    with pytest.raises(ValueError, match="vertex"):
        walls_to_geojson([np.zeros((1, 2))])
