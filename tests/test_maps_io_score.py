"""Map files (map_server YAML + PGM/PNG) and scoring maps against a world's floor plan."""
from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
from scipy import ndimage

from blocks.core.errors import SemmapError
from blocks.maps.mapio import (MapError, OccupancyMap, occupancy_map_from_world, read_map,
                               write_map)
from blocks.maps.score import (METRIC_KEYS, VISIBLE_KEYS, TrajectoryError, free_floor,
                               read_path_csv, score_map, visible_from_path)
from blocks.maps.score import _ground_truth as score_ground_truth
from sim2d.world import World, load_world
from sim2d.worlds import world_path


@pytest.fixture(scope="module")
def worlds():
    return {name: load_world(world_path(name)) for name in ("corridor", "office")}


def small_map() -> OccupancyMap:
    """4 rows x 5 columns: a wall on the top row, unknown on the right column."""
    p = np.zeros((4, 5))
    p[3, :] = 1.0          # highest y: a wall
    p[1, 1] = 0.9          # occupied, not certain
    p[:, 4] = np.nan       # unknown
    return OccupancyMap(p, resolution=0.1, origin=(-1.0, 2.0, 0.0))


# ---- files -------------------------------------------------------------------------------
def test_write_read_round_trip(tmp_path):
    m = small_map()
    written = write_map(tmp_path / "m.yaml", m, comment="made by a test\nsecond line")
    assert written == [tmp_path / "m.yaml", tmp_path / "m.pgm", tmp_path / "m.png"]
    text = (tmp_path / "m.yaml").read_text()
    assert text.startswith("# made by a test\n# second line\n")
    assert "image: m.pgm" in text and "mode: trinary" in text and "negate: 0" in text
    assert (tmp_path / "m.pgm").read_bytes().startswith(b"P5\n5 4\n255\n")
    back = read_map(tmp_path / "m.yaml")
    assert back.resolution == pytest.approx(0.1)
    assert back.origin == pytest.approx((-1.0, 2.0, 0.0))
    assert back.occupancy.shape == (4, 5)
    assert np.array_equal(np.isnan(back.occupancy), np.isnan(m.occupancy))
    known = ~np.isnan(m.occupancy)
    assert np.allclose(back.occupancy[known], m.occupancy[known], atol=1 / 255)
    for a, b in zip(back.classes(), m.classes()):
        assert np.array_equal(a, b)
    assert not list(tmp_path.glob(".*.tmp"))  # atomic writes leave no temporaries


def test_pgm_row_order_puts_high_y_at_the_top(tmp_path):
    write_map(tmp_path / "m.yaml", small_map(), preview=False)
    assert not (tmp_path / "m.png").exists()
    pixels = cv2.imread(str(tmp_path / "m.pgm"), cv2.IMREAD_UNCHANGED)
    assert pixels.shape == (4, 5)
    assert (pixels[0, :4] == 0).all()            # the wall (highest y) is the image's top row
    assert (pixels[3, :4] == 255).all()          # the lowest row is free
    assert (pixels[:, 4] == 205).all()           # unknown: map_saver's grey
    assert pixels[2, 1] < 90                     # p = 0.9 at row 1 from the bottom


def test_cell_centres_and_classes():
    m = small_map()
    x, y = m.cell_centres()
    assert x == pytest.approx([-0.95, -0.85, -0.75, -0.65, -0.55])
    assert y == pytest.approx([2.05, 2.15, 2.25, 2.35])
    occupied, free, unknown = m.classes()
    assert occupied.sum() == 5 and unknown.sum() == 4 and free.sum() == 11


def test_probabilities_near_thresholds_keep_their_class(tmp_path):
    p = np.array([[0.651, 0.6499, 0.1961, 0.1959, 0.5]])
    m = OccupancyMap(p, resolution=0.05, origin=(0.0, 0.0, 0.0))
    write_map(tmp_path / "t.yaml", m, preview=False)
    back = read_map(tmp_path / "t.yaml")
    assert back.occupancy[0, 0] > 0.65 and back.occupancy[0, 3] < 0.196
    assert np.isnan(back.occupancy[0, [1, 2, 4]]).all()  # in between: unknown in trinary mode


def test_preview_png_is_readable_and_enlarged(tmp_path):
    write_map(tmp_path / "m.yaml", small_map())
    picture = cv2.imread(str(tmp_path / "m.png"))
    assert picture is not None and picture.shape[1] >= 5 * 16 and picture.shape[0] % 4 == 0
    assert (picture[0, 0] == 0).all() and (picture[-1, 0] == 255).all()


def test_read_png_map_with_negate(tmp_path):
    image = np.zeros((3, 4), dtype=np.uint8)   # negate 1: black is free
    image[0, :] = 255                          # top row white: occupied
    image[1, 2] = 128                          # in between: unknown
    cv2.imwrite(str(tmp_path / "n.png"), image)
    (tmp_path / "n.yaml").write_text("image: n.png\nresolution: 0.5\norigin: [1.0, -2.0, 0.0]\n"
                                     "negate: 1\noccupied_thresh: 0.65\nfree_thresh: 0.196\n")
    m = read_map(tmp_path / "n.yaml")
    occupied, free, unknown = m.classes()
    assert occupied[2].all() and not occupied[:2].any()   # image top -> highest row
    assert free[0].all() and free[1, [0, 1, 3]].all()
    assert unknown[1, 2] and np.isnan(m.occupancy[1, 2]) and unknown.sum() == 1
    assert m.origin == (1.0, -2.0, 0.0) and m.resolution == 0.5
    assert m.cell_centres()[1][2] == pytest.approx(-0.75)


def test_a_world_file_reads_as_its_own_map(worlds):
    m = read_map(world_path("office"))
    own = occupancy_map_from_world(worlds["office"])
    assert np.array_equal(m.classes()[0], own.classes()[0])
    assert m.origin == own.origin == (-0.5, -0.5, 0.0)


@pytest.mark.parametrize("yaml_text, field, words", [
    ("image: gone.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "image", "not found"),
    ("image: m.pgm\nresolutoin: 0.05\norigin: [0, 0, 0]\n", "resolution", "resolutoin"),
    ("image: m.pgm\norigin: [0, 0, 0]\n", "resolution", "no 'resolution'"),
    ("image: m.pgm\nresolution: -1\norigin: [0, 0, 0]\n", "resolution", "> 0"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\n", "origin", "[x, y, yaw]"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", "origin", "yaw"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 2\n", "negate", "0 or 1"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 0.9\n", "free_thresh",
     "above"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: raw\n", "mode", "raw"),
])
def test_bad_map_files_are_clear_errors(tmp_path, yaml_text, field, words):
    write_map(tmp_path / "m.yaml", small_map(), preview=False)  # a valid image to point at
    (tmp_path / "bad.yaml").write_text(yaml_text)
    with pytest.raises(MapError) as info:
        read_map(tmp_path / "bad.yaml")
    err = info.value
    assert isinstance(err, SemmapError) and err.field == field and err.line
    assert err.file == str(tmp_path / "bad.yaml")
    assert words in str(err) and "\n" not in str(err)


def test_unreadable_image_and_missing_yaml(tmp_path):
    (tmp_path / "junk.pgm").write_bytes(b"not an image")
    (tmp_path / "j.yaml").write_text("image: junk.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n")
    with pytest.raises(MapError, match="cannot read image"):
        read_map(tmp_path / "j.yaml")
    with pytest.raises(MapError, match="not found"):
        read_map(tmp_path / "absent.yaml")


def test_write_rejects_invalid_maps(tmp_path):
    with pytest.raises(ValueError, match="0, 1"):
        write_map(tmp_path / "m.yaml", OccupancyMap(np.full((2, 2), 2.0), 0.1, (0, 0, 0)))
    with pytest.raises(ValueError, match=".yaml"):
        write_map(tmp_path / "m.pgm", small_map())


# ---- scoring -----------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["corridor", "office"])
def test_the_worlds_own_map_scores_perfectly(worlds, name):
    world = worlds[name]
    s = score_map(occupancy_map_from_world(world), world)
    assert tuple(s) == METRIC_KEYS
    assert s["precision"] == s["recall"] == s["f1"] == 1.0
    assert s["free_coverage"] == 1.0 and s["false_free"] == 0.0
    assert s["map_occupied_cells"] == int(world.occupied.sum())
    assert 0 < s["facing_wall_cells"] < s["map_occupied_cells"]
    assert 0 < s["reachable_free_cells"] <= s["map_free_cells"]


def test_a_round_tripped_coarser_map_still_scores_well(worlds, tmp_path):
    """Different resolution and origin: sampling goes through world coordinates."""
    world = worlds["office"]
    own = occupancy_map_from_world(world)
    walls = own.occupancy > 0.5
    coarse = walls[: walls.shape[0] // 2 * 2, : walls.shape[1] // 2 * 2]
    coarse = coarse.reshape(coarse.shape[0] // 2, 2, coarse.shape[1] // 2, 2).any(axis=(1, 3))
    m = OccupancyMap(coarse.astype(float), 0.1, own.origin)
    write_map(tmp_path / "coarse.yaml", m, preview=False)
    s = score_map(read_map(tmp_path / "coarse.yaml"), world)
    assert s["precision"] == 1.0 and s["recall"] == 1.0
    assert s["free_coverage"] > 0.9 and s["false_free"] == 0.0
    assert s["map_resolution_m"] == 0.1 and s["world_resolution_m"] == 0.05


def test_free_floor_shows_where_the_coverage_is_lost(worlds):
    """The mask behind ``free_coverage``: a map that never saw the west half of the office
    calls none of it free, and the mask's share is the score's."""
    world = worlds["office"]
    own = occupancy_map_from_world(world)
    half = own.occupancy.copy()
    half[:, : half.shape[1] // 2] = 0.5  # unknown
    m = OccupancyMap(half, own.resolution, own.origin)
    truth, reachable, free = free_floor(m, world)
    assert free.shape == reachable.shape == truth.occupancy.shape and not (free & ~reachable).any()
    columns = np.nonzero(reachable)[1]
    assert free[:, : half.shape[1] // 2 - 1].sum() == 0 and free.sum() > 0
    assert free.sum() / reachable.sum() == pytest.approx(score_map(m, world)["free_coverage"])
    assert 0.2 < free.sum() / reachable.sum() < 0.8 and columns.min() < half.shape[1] // 2


def test_a_shifted_map_loses_precision_and_recall(worlds):
    world = worlds["office"]
    own = occupancy_map_from_world(world)
    shifted = OccupancyMap(own.occupancy, own.resolution,
                           (own.origin[0] + 0.5, own.origin[1] + 0.5, 0.0))
    s = score_map(shifted, world)
    assert s["precision"] < 0.8 and s["recall"] < 0.8 and s["f1"] < 0.8
    assert s["false_free"] > 0.1
    # a shift within the tolerance costs nothing
    nudged = OccupancyMap(own.occupancy, own.resolution,
                          (own.origin[0] + 0.1, own.origin[1], 0.0))
    near = score_map(nudged, world)
    assert near["precision"] == 1.0 and near["recall"] == 1.0
    strict = score_map(nudged, world, tolerance=0.05)
    assert strict["precision"] < 1.0 and strict["recall"] < 1.0


def test_an_unknown_map_has_no_recall_and_no_coverage(worlds):
    world = worlds["corridor"]
    own = occupancy_map_from_world(world)
    s = score_map(OccupancyMap(np.full(own.shape, np.nan), own.resolution, own.origin), world)
    assert s["recall"] == 0.0 and s["free_coverage"] == 0.0
    assert s["precision"] == 0.0 and s["f1"] == 0.0 and s["false_free"] == 0.0
    assert s["map_occupied_cells"] == 0 and s["map_free_cells"] == 0


def test_walls_marked_free_are_all_false_free(worlds):
    world = worlds["corridor"]
    own = occupancy_map_from_world(world)
    s = score_map(OccupancyMap(np.zeros(own.shape), own.resolution, own.origin), world)
    assert s["false_free"] == 1.0 and s["free_coverage"] == 1.0 and s["recall"] == 0.0


def test_a_map_outside_the_world_scores_zero(worlds):
    world = worlds["corridor"]
    far = OccupancyMap(np.ones((10, 10)), 0.05, (500.0, 500.0, 0.0))
    s = score_map(far, world)
    assert s["precision"] == s["recall"] == s["free_coverage"] == 0.0


def test_score_rejects_rotated_maps_and_bad_tolerance(worlds):
    world = worlds["corridor"]
    with pytest.raises(SemmapError, match="yaw"):
        score_map(OccupancyMap(np.zeros((2, 2)), 0.05, (0, 0, 0.3)), world)
    with pytest.raises(ValueError):
        score_map(occupancy_map_from_world(world), world, tolerance=-1)


# ---- the command -------------------------------------------------------------------------
def test_cli_score_prints_a_table(cli, tmp_path, worlds):
    own = occupancy_map_from_world(worlds["corridor"])
    write_map(tmp_path / "c.yaml", own, preview=False)
    result = cli("score", tmp_path / "c.yaml", "--world", "corridor")
    assert result.code == 0, result
    lines = dict(line.strip().rsplit("  ", 1) for line in result.out.splitlines()[2:])
    assert {k.strip(): v for k, v in lines.items()}["wall precision"] == "1.000"
    assert "free coverage" in result.out and "false free" in result.out


def test_cli_score_json(cli):
    result = cli("score", world_path("office"), "--world", world_path("office"),
                 "--tolerance", 0.1, "--json")
    assert result.code == 0, result
    doc = json.loads(result.out)
    assert list(doc)[3:] == list(METRIC_KEYS)
    assert doc["world"] == "office" and doc["tolerance_m"] == 0.1
    assert doc["precision"] == doc["recall"] == 1.0
    assert all(isinstance(v, (int, str)) or math.isfinite(v) for v in doc.values())


def test_cli_score_errors_exit_2_without_traceback(cli, tmp_path):
    result = cli("score", tmp_path / "absent.yaml", "--world", "office")
    assert result.code == 2 and "Traceback" not in result.err + result.out
    assert "absent.yaml" in result.err and "not found" in result.err
    result = cli("score", world_path("corridor"), "--world", "nowhere")
    assert result.code == 2 and "unknown world" in result.err
    result = cli("score", world_path("corridor"), "--world", "office", "--tolerance", -1)
    assert result.code == 2 and "Traceback" not in result.err


# ---- what a run could see ----------------------------------------------------------------
RES = 0.05


def grid_world(width: float, height: float, rects: list[tuple[float, float, float, float]],
               start: tuple[float, float], name: str = "drawn") -> World:
    """A world from wall rectangles (x0, y0, x1, y1) in metres, origin (0, 0), 5 cm cells."""
    up = np.zeros((round(height / RES), round(width / RES)), dtype=bool)  # rows y up
    for x0, y0, x1, y1 in rects:
        up[round(y0 / RES):round(y1 / RES), round(x0 / RES):round(x1 / RES)] = True
    return World(name=name, segments=np.zeros((0, 5)), signs=[], starts=[(*start, 0.0)],
                 resolution=RES, origin=(0.0, 0.0, 0.0), occupied=np.flipud(up))


def box(width: float, height: float, t: float = 0.1) -> list[tuple[float, float, float, float]]:
    return [(0, 0, width, t), (0, height - t, width, height), (0, 0, t, height),
            (width - t, 0, width, height)]


#: Two 6 m rooms side by side: room A x in [0.1, 6.0], a 0.3 m thick wall, room B x in
#: [6.3, 11.9]; the door in the dividing wall is at y in [4.5, 5.5], far from the path.
TWO_ROOMS = box(12.0, 6.0) + [(6.0, 0.0, 6.3, 4.5), (6.0, 5.5, 6.3, 6.0)]
#: A path confined to room A, near its floor: the door is > 4 m away from every pose.
ROOM_A_PATH = np.array([[1.0, 1.0], [2.5, 1.0]])


def centres_x(mask_shape: tuple[int, int]) -> np.ndarray:
    return (np.arange(mask_shape[1]) + 0.5) * RES


@pytest.fixture(scope="module")
def two_rooms():
    world = grid_world(12.0, 6.0, TWO_ROOMS, (1.0, 1.0), "two_rooms")
    return world, visible_from_path(world, ROOM_A_PATH, max_range=4.0)


def facing_walls(world: World) -> np.ndarray:
    """Facing wall cells of a drawn world, whose floor is all connected (no outside margin)."""
    walls = occupancy_map_from_world(world).occupancy > 0.5
    reachable = ~walls
    return walls & ndimage.binary_dilation(reachable, structure=np.ones((3, 3), bool))


def test_visibility_stays_in_the_room_the_path_is_in(two_rooms):
    world, seen = two_rooms
    assert seen.shape == occupancy_map_from_world(world).shape
    x = centres_x(seen.shape)[None, :].repeat(seen.shape[0], axis=0)
    facing = facing_walls(world)
    room_b = facing & (x > 6.3)
    assert room_b.sum() > 300 and not (seen & room_b).any()   # the other room is unseen
    assert not seen[:, x[0] > 6.3].any()                       # nothing of it, not only walls
    room_a = facing & (x < 4.0)
    assert (seen & room_a).sum() > 0.3 * room_a.sum()


def test_visibility_is_y_up_and_stops_at_the_first_wall(two_rooms):
    _, seen = two_rooms
    # the path runs along y = 1 m: the floor wall (rows 0-1) is near, the top wall 4.9 m away
    assert seen[1, 20:50].all()          # the wall's face, row 1 = y in [0.05, 0.1)
    assert not seen[0].any()             # behind the face: never visible
    assert not seen[-2:].any()           # the top wall is out of range
    # the dividing wall, 0.3 m thick at x in [6.0, 6.3): its room-A face only
    rows = slice(round(0.8 / RES), round(1.2 / RES))
    assert seen[rows, 120].all()
    assert not seen[rows, 121:126].any()


def test_a_wall_casts_a_shadow():
    # a free-standing wall between the pose and the floor behind it
    world = grid_world(10.0, 6.0, box(10.0, 6.0) + [(3.0, 2.5, 3.2, 3.5)], (1.0, 3.0))
    seen = visible_from_path(world, np.array([[1.025, 3.025]]), max_range=4.0)

    def cell(x: float, y: float) -> tuple[int, int]:
        return int(y / RES), int(x / RES)

    assert seen[cell(3.02, 3.0)]                # the pillar's near face
    assert not seen[cell(3.17, 3.0)]            # its far face
    assert not seen[cell(4.0, 3.0)]             # floor in its shadow, 3 m away
    assert seen[cell(4.0, 1.0)]                 # floor beside the shadow, as far
    # range, along a free row: 3.85 m is seen, 4.25 m is not
    seen_low = visible_from_path(world, np.array([[1.025, 1.025]]), max_range=4.0)
    assert seen_low[cell(4.875, 1.025)]         # 3.85 m away
    assert not seen_low[cell(5.275, 1.025)]     # 4.25 m away


def test_a_corridor_path_sees_both_walls(worlds):
    world = worlds["corridor"]
    path = np.array([[0.9, 1.1], [19.3, 1.1]])  # down the middle of the 2 m wide corridor
    seen = visible_from_path(world, path)
    truth = occupancy_map_from_world(world)
    _, _, facing = score_ground_truth(world)
    _, y = truth.cell_centres()
    low = facing & (y[:, None] < 0.5)
    high = facing & (y[:, None] > 1.5)
    assert low.sum() > 350 and high.sum() > 350
    assert (seen & low).sum() == low.sum() and (seen & high).sum() == high.sum()
    s = score_map(truth, world, visible=seen)
    assert s["visible_wall_cells"] == s["facing_wall_cells"]
    assert s["visible_free_cells"] == s["reachable_free_cells"]


def test_path_sampling_interpolates_between_waypoints(two_rooms):
    world, _ = two_rooms
    # two waypoints 4.5 m apart: the middle of the segment must be seen from, too
    seen = visible_from_path(world, np.array([[0.8, 3.0], [5.3, 3.0]]), max_range=0.5)
    assert seen[round(3.0 / RES), round(3.05 / RES)]
    ends = visible_from_path(world, np.array([[0.8, 3.0], [5.3, 3.0]]), max_range=0.5,
                             spacing=10.0)
    assert not ends[round(3.0 / RES), round(3.05 / RES)]  # only the two ends


def test_visible_scores_a_perfect_map_of_the_seen_room(two_rooms):
    world, seen = two_rooms
    truth = occupancy_map_from_world(world)
    p = truth.occupancy.copy()
    p[:, centres_x(p.shape) > 6.3] = np.nan         # room B never mapped
    s = score_map(OccupancyMap(p, truth.resolution, truth.origin), world, visible=seen)
    assert tuple(s) == METRIC_KEYS + VISIBLE_KEYS
    assert s["precision"] == 1.0
    assert s["recall_visible"] == pytest.approx(1.0) and s["f1_visible"] == pytest.approx(1.0)
    assert s["free_coverage_visible"] == 1.0 and s["false_free_visible"] == 0.0
    assert s["recall"] < 0.7 and s["free_coverage"] < 0.6   # room B counts against plain scores
    assert 0 < s["visible_wall_cells"] < s["facing_wall_cells"]
    assert 0 < s["visible_free_cells"] < s["reachable_free_cells"]
    # and a map that lost the seen room's floor wall loses visible recall
    p[:round(0.2 / RES), :] = 0.0
    worse = score_map(OccupancyMap(p, truth.resolution, truth.origin), world, visible=seen)
    assert worse["recall_visible"] < 0.9 and worse["false_free_visible"] > 0.1


def test_all_and_nothing_visible(two_rooms):
    world, _ = two_rooms
    truth = occupancy_map_from_world(world)
    shifted = OccupancyMap(truth.occupancy, truth.resolution, (0.3, 0.2, 0.0))
    plain = score_map(shifted, world)
    everything = score_map(shifted, world, visible=np.ones(truth.shape, bool))
    for key in ("recall", "f1", "free_coverage", "false_free"):
        assert everything[f"{key}_visible"] == plain[key] == everything[key]
    assert everything["visible_wall_cells"] == plain["facing_wall_cells"]
    nothing = score_map(shifted, world, visible=np.zeros(truth.shape, bool))
    assert all(nothing[k] == 0 for k in VISIBLE_KEYS)


def test_visible_argument_checks(two_rooms):
    world, seen = two_rooms
    truth = occupancy_map_from_world(world)
    with pytest.raises(ValueError, match="shape"):
        score_map(truth, world, visible=seen[:-1])
    with pytest.raises(ValueError, match="shape"):
        score_map(truth, world, visible=seen.T)
    for bad in (np.zeros((0, 2)), np.zeros((3, 3)), np.array([[np.nan, 1.0]])):
        with pytest.raises(ValueError, match="path_xy"):
            visible_from_path(world, bad)
    with pytest.raises(ValueError, match="max_range"):
        visible_from_path(world, ROOM_A_PATH, max_range=0)
    with pytest.raises(ValueError, match="spacing"):
        visible_from_path(world, ROOM_A_PATH, spacing=1e-9)
    # a pose outside the grid sees nothing, and does not crash
    assert not visible_from_path(world, np.array([[-50.0, -50.0]])).any()


def test_visible_from_path_sees_the_office_corridor_loop(worlds):
    """~800 poses round the office's corridor loop (benchmarks/bench_maps.py times it)."""
    world = worlds["office"]
    loop = np.array([[1.0, 5.8], [29.0, 5.8], [29.0, 14.0], [1.0, 14.0], [1.0, 5.8]])
    seen = visible_from_path(world, loop, spacing=72.0 / 800)
    assert seen.sum() > 50_000


# ---- trajectory files --------------------------------------------------------------------
HEADER = "tick,time,robot,x,y,theta,odom_x,odom_y,odom_theta,v,w\n"


def trajectory(rows: list[tuple[str, float, float]]) -> str:
    """CSV text like sim2d.world writes; the odometry columns are deliberately wrong."""
    return HEADER + "".join(f"{i},{i * 0.1:.6f},{name},{x},{y},0,99,99,0,0,0\n"
                            for i, (name, x, y) in enumerate(rows))


def test_read_path_csv_reads_the_true_pose_of_one_robot(tmp_path):
    f = tmp_path / "trajectory.csv"
    f.write_text(trajectory([("a", 1.0, 2.0), ("b", 5.0, 5.0), ("a", 1.5, 2.0), ("b", 6, 5)]))
    assert read_path_csv(f).tolist() == [[1.0, 2.0], [1.5, 2.0]]          # the first robot
    assert read_path_csv(f, robot="b").tolist() == [[5.0, 5.0], [6.0, 5.0]]
    assert read_path_csv(str(f), "a").dtype == np.float64


@pytest.mark.parametrize("text, robot, words, field", [
    (None, None, "not found", None),
    ("", None, "empty", "x"),
    ("tick,time,robot,odom_x,odom_y\n0,0,a,1,2\n", None, "no column 'x' or 'y'", "x"),
    ("x,y\n1,2\n", "a", "no column 'robot'", "robot"),
    (HEADER, None, "no rows", None),
    (trajectory([("a", 1.0, 2.0)]).replace(",2.0,", ",two,"), None, "'two'", "y"),
    (trajectory([("a", 1.0, 2.0)]).replace(",1.0,", ",nan,"), None, "'nan'", "x"),
    (HEADER + "0,0,a,1\n", None, "nothing", "y"),
    (trajectory([("a", 1.0, 2.0)]), "c", "'a'", "robot"),
])
def test_bad_trajectories_are_clear_errors(tmp_path, text, robot, words, field):
    f = tmp_path / "trajectory.csv"
    if text is not None:
        f.write_text(text)
    with pytest.raises(TrajectoryError) as info:
        read_path_csv(f, robot)
    err = info.value
    assert isinstance(err, SemmapError) and err.file == str(f) and err.field == field
    assert words in str(err) and "\n" not in str(err)


def test_a_bad_row_names_its_line(tmp_path):
    f = tmp_path / "t.csv"
    f.write_text(trajectory([("a", 1.0, 2.0), ("a", 1.0, 2.0), ("a", 1.0, 2.0)])
                 .replace("2,0.200000,a,1.0,2.0", "2,0.200000,a,1.0,"))
    with pytest.raises(TrajectoryError) as info:
        read_path_csv(f)
    assert info.value.line == 4 and "t.csv:4" in str(info.value)


# ---- the command with --path -------------------------------------------------------------
def corridor_run(tmp_path) -> Path:
    f = tmp_path / "trajectory.csv"
    f.write_text(trajectory([("robot", 0.9 + 0.1 * i, 1.1) for i in range(185)]))
    return f


def test_cli_score_with_a_path(cli, tmp_path):
    f = corridor_run(tmp_path)
    result = cli("score", world_path("corridor"), "--world", "corridor", "--path", f)
    assert result.code == 0, result
    assert "visible wall recall" in result.out and "visible free coverage" in result.out
    assert "seen by sonar" in result.out
    sonar = json.loads(cli("score", world_path("corridor"), "--world", "corridor", "--path", f,
                           "--json").out)
    # the sonar ring on a straight path sees both long walls, not every cell of the ends
    assert 0.5 < sonar["visible_wall_cells"] / sonar["facing_wall_cells"] < 1.0
    assert sonar["seen_by"] == "sonar" and sonar["range_m"] == 4.0
    result = cli("score", world_path("corridor"), "--world", "corridor", "--path", f,
                 "--seen-by", "sight", "--range", 1.5, "--json")
    assert result.code == 0, result
    doc = json.loads(result.out)
    assert list(doc)[:7] == ["map", "world", "world_file", "path", "path_points", "seen_by",
                             "range_m"]
    assert list(doc)[7:] == list(METRIC_KEYS + VISIBLE_KEYS)
    assert doc["range_m"] == 1.5 and doc["path_points"] == 185
    assert doc["recall_visible"] == doc["free_coverage_visible"] == 1.0
    # the path runs 1 m from both long walls and < 1 m from both ends: all is seen
    assert doc["visible_wall_cells"] == doc["facing_wall_cells"]
    assert doc["visible_free_cells"] == doc["reachable_free_cells"]
    # with 0.5 m, neither wall is seen: the --range reaches the mask
    result = cli("score", world_path("corridor"), "--world", "corridor", "--path", f,
                 "--seen-by", "sight", "--range", 0.5, "--json")
    doc = json.loads(result.out)
    assert doc["visible_wall_cells"] == 0 and doc["recall_visible"] == 0.0
    assert 0 < doc["visible_free_cells"] < doc["reachable_free_cells"]


def test_cli_score_path_errors_exit_2_without_traceback(cli, tmp_path):
    args = ("score", world_path("corridor"), "--world", "corridor")
    result = cli(*args, "--path", tmp_path / "absent.csv")
    assert result.code == 2 and "Traceback" not in result.err + result.out
    assert "absent.csv" in result.err and "not found" in result.err
    (tmp_path / "bad.csv").write_text("a,b\n1,2\n")
    result = cli(*args, "--path", tmp_path / "bad.csv")
    assert result.code == 2 and "bad.csv:1" in result.err and "'x'" in result.err
    result = cli(*args, "--path", corridor_run(tmp_path), "--robot", "other")
    assert result.code == 2 and "'robot'" in result.err and "--robot" in result.err
    result = cli(*args, "--robot", "robot")
    assert result.code == 2 and "--path" in result.err
    result = cli(*args, "--path", corridor_run(tmp_path), "--range", 0)
    assert result.code == 2 and "Traceback" not in result.err


def test_installed_command_reports_a_malformed_trajectory(tmp_path):
    semmap = Path(sys.executable).with_name("semmap")
    (tmp_path / "t.csv").write_text(HEADER + "0,0,robot,1.0,oops,0,0,0,0,0,0\n")
    proc = subprocess.run([str(semmap), "score", str(world_path("corridor")), "--world",
                           "corridor", "--path", str(tmp_path / "t.csv")],
                          capture_output=True, text=True, timeout=60, check=False)
    assert proc.returncode == 2 and "Traceback" not in proc.stderr + proc.stdout
    assert "t.csv:2" in proc.stderr and "'oops'" in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1


def test_map_pictures_are_drawn_no_larger_than_their_figure():
    """A map picture larger than its figure is sampled down (nearest cell) to fit, aspect
    kept and colours unmixed; one that fits is drawn as it is."""
    from blocks.maps.mapio import display_sized, map_rgba
    occupancy = np.zeros((1100, 1500))
    occupancy[::10] = 1.0  # a wall on every tenth row
    occupancy[:, :300] = np.nan
    picture = map_rgba(OccupancyMap(occupancy, 0.025, (0.0, 0.0, 0.0)))
    small = display_sized(picture, 1200, 900)
    assert small.shape[1] <= 1200 and small.shape[0] <= 900 and small.shape[1] >= 1199
    assert small.shape[0] / small.shape[1] == pytest.approx(1100 / 1500, abs=2e-3)
    assert {tuple(c) for c in small.reshape(-1, 4)} <= {tuple(c) for c in picture.reshape(-1, 4)}
    assert (small[..., :3] == 0).any() and (small[:, 0, :3] == [175, 160, 150]).all()
    fits = display_sized(picture[:500, :800], 1200, 900)
    assert np.shares_memory(fits, picture)  # the picture itself, not a copy
