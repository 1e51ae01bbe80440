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
    written = sorted(p.name for p in first.iterdir() if p.is_file())
    assert written == sorted(p.name for p in second.iterdir() if p.is_file())
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


# ---- ground truth: places, doors, objects, timetable ----------------------------------------
TRUTH = GOOD + """\
    places:
      - {name: ROOM, kind: Office, polygon: [[0.3, 0.3], [1.0, 0.3], [1.0, 1.7], [0.3, 1.7]]}
      - {name: NOOK, kind: Storage, polygon: [[1.0, 0.3], [1.7, 0.3], [1.7, 1.7], [1.0, 1.7]]}
    doors:
      - {x: 1.0, y: 1.0, width: 0.8, between: [ROOM, NOOK]}
    objects:
      - {label: Shredder, x: 1.2, y: 1.2}
"""


def test_world_ground_truth_loads(tmp_path):
    w = load_world(write_world(tmp_path, TRUTH))
    assert [p.name for p in w.places] == ["ROOM", "NOOK"]
    assert w.places[0].kind == "Office" and w.places[0].polygon.shape == (4, 2)
    assert w.doors[0].between == ("ROOM", "NOOK") and w.doors[0].width == 0.8
    assert w.objects[0].label == "Shredder" and (w.objects[0].x, w.objects[0].y) == (1.2, 1.2)
    assert w.place("NOOK") is w.places[1] and w.place("HALL") is None
    assert w.timetable is None


def test_world_timetable_resolves_relative_to_the_world_file(tmp_path):
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "t.yaml").write_text("events: []\n")
    w = load_world(write_world(tmp_path, GOOD + "    timetable: sub/t.yaml\n"))
    assert w.timetable == (tmp_path / "sub" / "t.yaml").resolve()


def test_worlds_without_ground_truth_still_load(tmp_path):
    w = load_world(write_world(tmp_path, GOOD))
    assert w.places == [] and w.doors == [] and w.objects == [] and w.timetable is None


@pytest.mark.parametrize("old, new, field, line", [
    pytest.param("kind: Office, ", "", "places[0].kind", 11, id="place without kind"),
    pytest.param("name: ROOM, ", "name: 3, ", "places[0].name", 11, id="place name a number"),
    pytest.param("[[0.3, 0.3], [1.0, 0.3], [1.0, 1.7], [0.3, 1.7]]", "[[0.3, 0.3], [1.0, 0.3]]",
                 "places[0].polygon", 11, id="polygon of two corners"),
    pytest.param("[[0.3, 0.3], [1.0, 0.3], [1.0, 1.7], [0.3, 1.7]]", "[[0.3, 0.3], [1.0], "
                 "[1.0, 1.7]]", "places[0].polygon", 11, id="polygon corner of one number"),
    pytest.param("[[0.3, 0.3], [1.0, 0.3], [1.0, 1.7], [0.3, 1.7]]", "[[0, 0], [1, 1], [2, 2]]",
                 "places[0].polygon", 11, id="polygon of zero area"),
    pytest.param("name: NOOK", "name: ROOM", "places[1].name", 12, id="duplicate place name"),
    pytest.param("kind: Storage, ", "kind: Storage, colour: red, ", "places[1]", 12,
                 id="place unknown field"),
    pytest.param("between: [ROOM, NOOK]", "between: [ROOM, NOK]", "doors[0].between", 14,
                 id="door joins an unknown place"),
    pytest.param("between: [ROOM, NOOK]", "between: [ROOM]", "doors[0].between", 14,
                 id="door between one place"),
    pytest.param("width: 0.8", "width: -1", "doors[0].width", 14, id="negative door width"),
    pytest.param("y: 1.0, width", "width", "doors[0]", 14, id="door without y"),
    pytest.param("label: Shredder, ", "", "objects[0].label", 16, id="object without label"),
    pytest.param("x: 1.2, y: 1.2}", "x: 1.2, y: high}", "objects[0].y", 16,
                 id="object y a string"),
    pytest.param("x: 1.2, y: 1.2}", "x: 0.2, y: 1.2}", "objects[0]", 16, id="object in a wall"),
    pytest.param("objects:\n      - {label: Shredder, x: 1.2, y: 1.2}",
                 "objects: {label: Shredder}", "objects", 15, id="objects not a list"),
    pytest.param("objects:\n", "timetable: nowhere.yaml\n    objects:\n", "timetable", 15,
                 id="timetable missing"),
])
def test_malformed_ground_truth_names_file_line_and_field(tmp_path, old, new, field, line):
    assert old in TRUTH
    path = write_world(tmp_path, TRUTH.replace(old, new, 1))
    with pytest.raises(WorldError) as info:
        load_world(path)
    err = info.value
    assert err.field is not None and field in err.field, (err.field, str(err))
    assert err.file == str(path) and err.line == line, (err.line, str(err))
    assert "\n" not in str(err) and str(path) in str(err)


def test_office_ground_truth_matches_the_plan():
    w = world("office")
    signed = {s.text for s in w.signs}
    rooms = {p.name for p in w.places if p.kind != "Corridor"}
    assert rooms == signed and w.place("CORRIDOR").kind == "Corridor"
    assert w.place("MAIL ROOM").kind == "MailRoom" and w.place("ADMIN").kind == "Administration"
    assert len(w.doors) == 14 and all(d.width == 1.0 for d in w.doors)
    labels = {o.label for o in w.objects}
    assert {"Shredder", "Printer", "Microscope", "Projector", "Toolbox", "CoffeeMachine",
            "Bookshelf"} <= labels
    for obj in w.objects:  # in free space, inside one place, near (<= 2.5 m) that place's door
        owners = [p for p in w.places if gen.point_in_polygon(obj.x, obj.y, p.polygon)]
        assert len(owners) == 1, obj
        doors = [d for d in w.doors if owners[0].name in d.between]
        assert min(math.hypot(obj.x - d.x, obj.y - d.y) for d in doors) <= 2.5, obj
    shredder = next(o for o in w.objects if o.label == "Shredder")
    assert gen.point_in_polygon(shredder.x, shredder.y, w.place("KITCHEN").polygon)


def test_corridor_ring_polygon_covers_the_loop_but_not_the_core():
    ring = world("office").place("CORRIDOR").polygon
    for x, y in ((1.0, 10.0), (15.0, 6.0), (15.0, 14.0), (29.0, 10.0), (1.0, 12.0)):
        assert gen.point_in_polygon(x, y, ring), (x, y)
    for x, y in ((15.0, 10.0), (5.0, 10.0), (15.0, 3.0), (15.0, 17.0)):
        assert not gen.point_in_polygon(x, y, ring), (x, y)


def test_hospital_ground_truth_doors_join_known_places():
    w = world("hospital")
    names = {p.name for p in w.places}
    assert {"HALL", "CORRIDOR WEST", "CORRIDOR EAST", "PHARMACY", "ICU"} <= names
    assert all(set(d.between) <= names for d in w.doors)
    assert any(o.label == "Medicine" for o in w.objects)
