"""The world library in sim2d/worlds and the world-file errors of sim2d.world.

The library's worlds must load, be compact (traced contours, not one body per
pixel), start the robot in free space beside a wall on its right, put every
sign on a wall facing reachable free space (door signs beside their door),
and be exactly what ``python -m sim2d.worlds.generate`` writes. Malformed
world files must raise a one-line WorldError naming the file and the field.
"""
from __future__ import annotations

import math
import textwrap

import cv2
import numpy as np
import pytest

from blocks.core.errors import SemmapError
from sim2d.world import World, WorldError, distance_to_segments, load_world
from sim2d.worlds import WORLDS_DIR, available_worlds, world_path
from sim2d.worlds import generate as gen

EXPECTED_WORLDS = {"corridor", "complex", "office", "hospital"}
MIN_SEGMENTS = {"corridor": 8, "complex": 40, "office": 150, "hospital": 150}
WORLD_FILES = sorted(WORLDS_DIR.glob("*.yaml"))
_CACHE: dict[str, World] = {}


def world(name: str) -> World:
    """A library world, loaded once per test session."""
    if name not in _CACHE:
        _CACHE[name] = load_world(WORLDS_DIR / f"{name}.yaml")
    return _CACHE[name]


def pixel(w: World, x: float, y: float) -> tuple[int, int]:
    """(row, col) of the grid cell holding world point (x, y) (origin yaw 0)."""
    h = w.occupied.shape[0]
    col = math.floor((x - w.origin[0]) / w.resolution)
    row = h - 1 - math.floor((y - w.origin[1]) / w.resolution)
    return row, col


def free_components(w: World) -> np.ndarray:
    """Labels of the 4-connected free regions of the occupancy grid."""
    _, labels = cv2.connectedComponents((~w.occupied).astype(np.uint8), connectivity=4)
    return labels


def all_signs():
    return [pytest.param(path.stem, i, id=f"{path.stem}:{s.text}")
            for path in WORLD_FILES for i, s in enumerate(world(path.stem).signs)]


# ---- the library ----------------------------------------------------------------------------
def test_library_has_the_worlds():
    assert EXPECTED_WORLDS <= set(available_worlds())
    for name in EXPECTED_WORLDS:
        assert world_path(name) == WORLDS_DIR / f"{name}.yaml"
        assert (WORLDS_DIR / f"{name}.png").is_file()


def test_unknown_world_lists_the_available_ones():
    with pytest.raises(WorldError) as info:
        world_path("ofice")
    text = str(info.value)
    assert "'ofice'" in text and "Did you mean 'office'" in text
    for name in EXPECTED_WORLDS:
        assert name in text
    assert "\n" not in text


@pytest.mark.parametrize("path", WORLD_FILES, ids=lambda p: p.stem)
def test_world_loads_and_is_compact(path):
    w = world(path.stem)
    assert w.name == path.stem
    assert w.occupied is not None and w.resolution == 0.05
    wall_pixels = int(w.occupied.sum())
    assert len(w.segments) >= MIN_SEGMENTS.get(path.stem, 4)
    assert len(w.segments) < wall_pixels / 20, (len(w.segments), wall_pixels)
    text = path.read_text()
    doc_lines = [line for line in text.splitlines() if line.startswith("doc: ")]
    assert len(doc_lines) == 1 and len(doc_lines[0]) > 20


@pytest.mark.parametrize("path", WORLD_FILES, ids=lambda p: p.stem)
def test_start_is_free_closed_in_and_has_a_wall_on_its_right(path):
    w = world(path.stem)
    labels = free_components(w)
    border = set(np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]]).tolist())
    for x, y, theta in w.starts:
        assert distance_to_segments(np.array([x, y]), w.segments).min() >= 0.5
        row, col = pixel(w, x, y)
        assert not w.occupied[row, col]
        assert labels[row, col] not in border, "the start's free space leaks out of the map"
        right = np.array([math.sin(theta), -math.cos(theta)])
        hits = [d for d in np.arange(0.5, 1.0, 0.01)
                if distance_to_segments(np.array([x, y]) + d * right, w.segments).min() <= 0]
        assert hits, "no wall within 1 m on the start's right"


@pytest.mark.parametrize("name, index", all_signs())
def test_sign_is_on_a_wall_and_faces_reachable_free_space(name, index):
    w = world(name)
    sign = w.signs[index]
    on_wall = distance_to_segments(np.array([sign.x, sign.y]), w.segments).min()
    assert abs(on_wall) <= 0.05, f"{sign.text} is {on_wall:.3f} m off the wall"
    normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
    front = np.array([sign.x, sign.y]) + 0.5 * normal
    assert distance_to_segments(front, w.segments).min() > 0.2, f"{sign.text} faces a wall"
    behind = np.array([sign.x, sign.y]) - 0.05 * normal
    assert w.occupied[pixel(w, *behind)], f"{sign.text} has no wall behind it"
    labels = free_components(w)
    assert labels[pixel(w, *front)] == labels[pixel(w, *w.start[:2])], \
        f"{sign.text} faces space the robot cannot reach"


@pytest.mark.parametrize("name, index", [
    p for p in all_signs() if p.values[0] in ("office", "hospital")
    and world(p.values[0]).signs[p.values[1]].text != "NURSES STATION"])  # on an island counter
def test_door_sign_is_beside_its_door(name, index):
    w = world(name)
    sign = w.signs[index]
    normal = np.array([math.cos(sign.facing), math.sin(sign.facing)])
    tangent = np.array([-normal[1], normal[0]])
    inside = np.array([sign.x, sign.y]) - 0.1 * normal  # the wall's centre line
    gaps = [abs(s) for s in np.arange(-1.5, 1.5001, 0.01)
            if not w.occupied[pixel(w, *(inside + s * tangent))]]
    assert gaps, f"no door within 1.5 m of {sign.text}"
    assert 0.3 <= min(gaps) <= 0.8, f"{sign.text}: door edge {min(gaps):.2f} m from the sign"


def test_office_and_hospital_signs():
    office = {s.text for s in world("office").signs}
    assert {"MAIL ROOM", "MANAGER", "ADMIN", "MAINTENANCE"} <= office
    assert {"KITCHEN", "LAB", "MEETING ROOM", "OFFICE 101"} <= office
    hospital = {s.text for s in world("hospital").signs}
    assert {"WARD A", "WARD B", "PHARMACY", "RADIOLOGY", "NURSES STATION", "ELEVATOR",
            "STAIRS", "OPERATING ROOM"} <= hospital


def test_office_rooms_are_furnished():
    """Some rooms hold furniture: free-standing blocks (contours not touching the outer ring)."""
    w = world("office")
    count, _ = cv2.connectedComponents(w.occupied.astype(np.uint8), connectivity=8)
    assert count - 1 >= 6  # the building plus at least five free-standing pieces


# ---- the generator --------------------------------------------------------------------------
def test_generator_is_deterministic_and_committed_files_are_current(tmp_path):
    first, second = tmp_path / "a", tmp_path / "b"
    assert gen.main(["--out", str(first)]) == 0
    gen.generate(second)
    written = sorted(p.name for p in first.iterdir())
    assert written == sorted(p.name for p in second.iterdir())
    assert written == sorted(f"{n}.{ext}" for n in gen.BUILDERS for ext in ("png", "yaml"))
    for name in written:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name
    committed = sorted(p.name for p in WORLDS_DIR.iterdir() if p.suffix in (".png", ".yaml"))
    assert committed == written, "stale or missing world files in sim2d/worlds"
    for name in written:
        if name.endswith(".yaml"):
            assert (WORLDS_DIR / name).read_bytes() == (first / name).read_bytes(), \
                f"{name} is out of date: run python -m sim2d.worlds.generate"
        else:  # compare pixels: PNG bytes may differ between zlib builds
            ours = cv2.imread(str(first / name), cv2.IMREAD_UNCHANGED)
            theirs = cv2.imread(str(WORLDS_DIR / name), cv2.IMREAD_UNCHANGED)
            assert theirs.dtype == ours.dtype and np.array_equal(theirs, ours), \
                f"{name} is out of date: run python -m sim2d.worlds.generate"


def test_generator_check_catches_a_sign_off_the_wall(tmp_path, monkeypatch):
    def bad_corridor():
        plan = gen.build_corridor()
        plan.signs.append({"text": "EXIT", "x": 5.0, "y": 1.0, "facing": 90.0})
        return plan

    monkeypatch.setitem(gen.BUILDERS, "corridor", bad_corridor)
    with pytest.raises(ValueError, match="EXIT"):
        gen.generate(tmp_path, ["corridor"])


def test_drawing_puts_wall_faces_on_pixel_edges():
    plan = gen.new_plan("t", "t", -0.5, -0.5, 2.5, 2.5)
    gen.box_walls(plan, 0.0, 0.0, 2.0, 2.0)
    w = World(name="t", segments=np.zeros((0, 5)), signs=[], starts=[(1.0, 1.0, 0.0)],
              origin=(-0.5, -0.5, 0.0), occupied=plan.image == gen.OCCUPIED)
    assert w.occupied[pixel(w, 0.09, 1.0)] and not w.occupied[pixel(w, 0.11, 1.0)]
    assert w.occupied[pixel(w, -0.09, 1.0)] and not w.occupied[pixel(w, -0.11, 1.0)]
    assert w.occupied[pixel(w, 1.0, 2.09)] and not w.occupied[pixel(w, 1.0, 2.11)]


# ---- malformed world files ------------------------------------------------------------------
GOOD = """\
    image: m.png
    resolution: 0.05
    origin: [0.0, 0.0, 0.0]
    negate: 0
    occupied_thresh: 0.65
    free_thresh: 0.196
    start: [1.0, 1.0, 0.0]
    signs:
      - {text: EXIT, x: 0.3, y: 1.0, facing: 0}
"""

def write_world(tmp_path, text):
    """A 2 m x 2 m room (4-pixel walls at x, y in 0.1..0.3 and 1.7..1.9) and its YAML."""
    img = np.full((40, 40), 254, np.uint8)
    img[2:38, 2:6] = img[2:38, 34:38] = img[2:6, 2:38] = img[34:38, 2:38] = 0
    cv2.imwrite(str(tmp_path / "m.png"), img)
    path = tmp_path / "w.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def test_good_world_loads(tmp_path):
    w = load_world(write_world(tmp_path, GOOD))
    assert w.start == (1.0, 1.0, 0.0) and w.signs[0].text == "EXIT"
    on_face = distance_to_segments(np.array([0.3, 1.0]), w.segments).min()
    assert on_face == pytest.approx(0, abs=1e-9)


@pytest.mark.parametrize("old, new, field", [
    pytest.param("    start: [1.0, 1.0, 0.0]\n", "", "start", id="missing start"),
    pytest.param("[1.0, 1.0, 0.0]", "[0.29, 1.0, 0.0]", "start", id="start on a wall face"),
    # the middle of a wall over 2 pixels thick is outside every capsule: the grid decides
    pytest.param("[1.0, 1.0, 0.0]", "[0.2, 1.0, 0.0]", "start", id="start inside a thick wall"),
    pytest.param("[1.0, 1.0, 0.0]", "[1.0, 1.0]", "start", id="start of wrong length"),
    pytest.param("m.png", "missing.png", "image", id="image missing"),
    pytest.param("m.png", "w.yaml", "image", id="image not a picture"),
    pytest.param("text: EXIT, ", "", "signs[0].text", id="sign without text"),
    pytest.param("text: EXIT", "text: '  '", "signs[0].text", id="sign with blank text"),
    pytest.param("facing: 0", "facing: north", "signs[0].facing", id="sign facing a string"),
    pytest.param("facing: 0}", "facing: 0, colour: red}", "signs[0]", id="sign unknown field"),
    pytest.param("negate: 0", "negate: 2", "negate", id="bad negate"),
    pytest.param("negate: 0", "negate: 0\n    colour: red", "colour", id="unknown key"),
    pytest.param("negate: 0", "negate: 0\n    walls: [[0, 0, 1]]", "walls[0]",
                 id="walls entry of wrong length"),
    pytest.param("negate: 0", "negate: 0\n    walls: {a: 1}", "walls", id="walls not a list"),
    pytest.param("free_thresh: 0.196", "free_thresh: 0.9", "free_thresh",
                 id="free_thresh above occupied_thresh"),
    pytest.param("occupied_thresh: 0.65", "occupied_thresh: 1.5", "occupied_thresh",
                 id="occupied_thresh out of range"),
    pytest.param("resolution: 0.05", "resolution: -0.05", "resolution", id="negative resolution"),
    pytest.param("resolution: 0.05", "resolution: fine", "resolution", id="resolution a string"),
    pytest.param("[0.0, 0.0, 0.0]", "[0.0, 0.0]", "origin", id="origin of wrong length"),
])
def test_malformed_world_names_the_field(tmp_path, old, new, field):
    assert old in GOOD
    path = write_world(tmp_path, GOOD.replace(old, new, 1))
    with pytest.raises(WorldError) as info:
        load_world(path)
    err = info.value
    assert isinstance(err, SemmapError)
    assert err.field is not None and field in err.field, (err.field, str(err))
    text = str(err)
    assert "\n" not in text and str(path) in text
    assert err.file == str(path)


@pytest.mark.parametrize("text", [
    pytest.param(GOOD + "    negate: 1\n", id="duplicate key"),
    pytest.param(GOOD + "    start: [1.0, 1.0\n", id="YAML syntax error"),
])
def test_unreadable_world_yaml_is_a_world_error(tmp_path, text):
    with pytest.raises(WorldError):
        load_world(write_world(tmp_path, text))


def test_unreadable_world_yaml_is_still_a_one_line_user_error(tmp_path):
    path = write_world(tmp_path, GOOD + "    negate: 1\n")
    with pytest.raises(SemmapError) as info:
        load_world(path)
    assert "\n" not in str(info.value) and str(path) in str(info.value)
