"""Map files (map_server YAML + PGM/PNG) and scoring maps against a world's floor plan."""
from __future__ import annotations

import json
import math

import cv2
import numpy as np
import pytest

from blocks.core.errors import SemmapError
from blocks.maps.mapio import (MapError, OccupancyMap, occupancy_map_from_world, read_map,
                               write_map)
from blocks.maps.score import METRIC_KEYS, score_map
from sim2d.world import load_world
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
