"""Generated commands with their right answers: the generator reads them off the ground truth,
the planner on the surveyed floor gets every one right, the scorer can tell a wrong answer,
the file round-trips and says what is wrong with it, and a semantic mapping run reports
the planner's score on its own map."""
from __future__ import annotations

import re
from pathlib import Path
from types import SimpleNamespace

import cv2
import numpy as np
import pytest
import yaml

from blocks.core.block import RunContext
from blocks.maps.mapio import occupancy_map_from_world, write_map
from blocks.maps.pathio import write_path_csv
from semantic.query import load_map
from semantic.query.exam import (CATEGORIES, CommandCase, CommandsError, generate_commands,
                                 load_commands, score_commands, write_commands)
from semantic.query.truth import TIGHT_DOOR
from sim2d.world import load_world
from sim2d.worlds import world_path

NOW = "monday 10:00"


@pytest.fixture(scope="module", params=["office", "hospital"])
def floor(request):
    name = request.param
    return SimpleNamespace(name=name, world=load_world(world_path(name)), qm=load_map(name))


@pytest.fixture(scope="module")
def office():
    return SimpleNamespace(world=load_world(world_path("office")), qm=load_map("office"))


def _wrong(score: dict) -> list[dict]:
    return [row for row in score["cases"] if not row["right"]]


# ---- the generator ------------------------------------------------------------------------------
def test_the_same_seed_gives_the_same_commands_and_another_seed_others(office):
    first = generate_commands(office.world, seed=3)
    assert generate_commands(office.world, seed=3) == first
    assert len(first) == 20
    other = generate_commands(office.world, seed=4)
    assert [c.command for c in other] != [c.command for c in first]


@pytest.mark.parametrize("seed", [0, 1])
def test_the_planner_on_the_surveyed_floor_gets_every_generated_command_right(floor, seed,
                                                                              tmp_path):
    path = write_commands(tmp_path / f"{floor.name}.commands.yaml",
                          generate_commands(floor.world, seed=seed, count=40), NOW)
    cases, now = load_commands(path)
    score = score_commands(floor.qm, cases, now)
    assert score["total"] == 40
    assert _wrong(score) == []
    assert score["right_fraction"] == 1.0


def test_every_category_appears_where_the_floor_allows_it(floor):
    cases = generate_commands(floor.world, seed=0, count=len(CATEGORIES))
    found = {c.category for c in cases}
    # the hospital's repeated rooms are lettered (WARD A), and the planner reads numbers only
    expected = set(CATEGORIES) - ({"go_named"} if floor.name == "hospital" else set())
    assert found == expected


def test_each_kind_of_command_says_what_the_ground_truth_says(office):
    cases = generate_commands(office.world, seed=0, count=200)
    printer = next(c for c in cases if c.category == "where_object" and "printer" in c.command)
    assert printer.answer == ("ADMIN",)
    ada = [c for c in cases if c.category == "where_person" and "Ada" in c.command]
    assert ada and all(c.answer[0] in ("LAB", "MEETING ROOM", "OFFICE 101") for c in ada)
    kinds = [c for c in cases if c.category == "refuse_kind"]
    assert kinds and all(c.refused == (f"this map has no {c.command.rsplit('the ', 1)[1]}",)
                         for c in kinds)
    on_this_floor = {"office", "kitchen", "library", "laboratory", "mail room", "server room"}
    assert not {c.command.rsplit("the ", 1)[1] for c in kinds} & on_this_floor
    numbers = [c for c in cases if c.category == "refuse_number"]
    assert numbers and all(re.search(r"\d{3}$", c.refused[0]) for c in numbers)


def test_refusals_are_a_tenth_of_the_commands_at_most_per_kind(office):
    cases = generate_commands(office.world, seed=0, count=20)
    assert sum(c.category == "refuse_kind" for c in cases) == 2
    assert sum(c.category == "refuse_number" for c in cases) == 2


# ---- a floor with closed doors, tight doors and unsigned rooms ----------------------------------
#: (name, kind, x0, y0 of the room, door width or None when shut, signed)
ROOMS = [
    ("OFFICE 201", "Office", 0, 0, 1.0, True),
    ("OFFICE 202", "Office", 4, 0, None, True),
    ("unsigned room 1", "Office", 8, 0, 1.0, False),
    ("KITCHEN", "Kitchen", 12, 0, TIGHT_DOOR + 0.08, True),
    ("LAB 1", "Laboratory", 0, 6, 1.0, True),
    ("MEETING ROOM 1", "MeetingRoom", 4, 6, 1.0, True),
    ("COPY ROOM", "CopyRoom", 8, 6, 1.1, True),
    ("LIBRARY", "Library", 12, 6, 1.0, True),
]
OBJECTS = [("Printer", 10, 8), ("Shredder", 2, 2), ("Shredder", 6, 8), ("Microscope", 14, 2),
           ("Toolbox", 10, 2), ("Bookshelf", 14, 8)]
TIMETABLE = {"version": 1,
             "people": [{"name": "Ann Smith", "role": "Researcher", "workplace": "OFFICE 201"},
                        {"name": "Bob Jones", "role": "Researcher", "workplace": "OFFICE 202"},
                        {"name": "Carl Moss", "role": "Librarian"}],
             "slots": [{"person": "Ann Smith", "place": "LAB 1", "days": ["mon"],
                        "start": "09:00", "end": "11:00"}]}
RES = 0.05


def _floor_image(path: Path) -> None:
    """16 x 10 m: a corridor (y 4-6) between four rooms south and four north (4 x 4 m)."""
    img = np.full((int(10 / RES), int(16 / RES)), 254, np.uint8)

    def wall(x0: float, y0: float, x1: float, y1: float) -> None:
        rows = slice(int(round((10 - y1) / RES)), int(round((10 - y0) / RES)))
        img[rows, int(round(x0 / RES)):int(round(x1 / RES))] = 0

    for x0, y0, x1, y1 in [(0, 0, 16, 0.1), (0, 9.9, 16, 10), (0, 0, 0.1, 10), (15.9, 0, 16, 10),
                           (0, 3.95, 16, 4.05), (0, 5.95, 16, 6.05)]:
        wall(x0, y0, x1, y1)
    for x in (4, 8, 12):
        wall(x - 0.05, 0, x + 0.05, 4)
        wall(x - 0.05, 6, x + 0.05, 10)
    for _, _, x0, y0, width, _ in ROOMS:
        if width is not None:  # the doorway: floor through the wall
            y = 4.0 if y0 == 0 else 6.0
            rows = slice(int(round((10 - y - 0.1) / RES)), int(round((10 - y + 0.1) / RES)))
            img[rows, int(round((x0 + 2 - width / 2) / RES)):
                int(round((x0 + 2 + width / 2) / RES))] = 254
    cv2.imwrite(str(path), img)


def _write_floor(folder: Path, commands: str | None = None) -> Path:
    _floor_image(folder / "floor.png")
    (folder / "floor.timetable.yaml").write_text(yaml.safe_dump(TIMETABLE, sort_keys=False))
    places = [{"name": "CORRIDOR", "kind": "Corridor",
               "polygon": [[0.1, 4.05], [15.9, 4.05], [15.9, 5.95], [0.1, 5.95]]}]
    doors, signs = [], []
    for name, kind, x0, y0, width, signed in ROOMS:
        places.append({"name": name, "kind": kind, "polygon": [
            [x0 + 0.1, y0 + 0.1], [x0 + 3.95, y0 + 0.1], [x0 + 3.95, y0 + 3.9],
            [x0 + 0.1, y0 + 3.9]]})
        y, facing = (4.0, 90.0) if y0 == 0 else (6.0, -90.0)
        doors.append({"x": x0 + 2, "y": y, "width": width or 1.0, "between": [name, "CORRIDOR"],
                      **({"closed": True} if width is None else {})})
        if signed:
            signs.append({"text": name, "x": x0 + 3.2, "y": y + (0.05 if y0 == 0 else -0.05),
                          "facing": facing})
    doc = {"name": "exam_floor", "image": "floor.png", "resolution": RES,
           "origin": [0.0, 0.0, 0.0], "negate": 0, "occupied_thresh": 0.65,
           "free_thresh": 0.196, "start": [1.0, 5.0, 0.0], "timetable": "floor.timetable.yaml",
           "signs": signs, "places": places, "doors": doors,
           "objects": [{"label": label, "x": x, "y": y} for label, x, y in OBJECTS]}
    if commands is not None:
        doc["commands"] = commands
    path = folder / "floor.yaml"
    path.write_text(yaml.safe_dump(doc, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def tricky(tmp_path_factory):
    path = _write_floor(tmp_path_factory.mktemp("floor"))
    cases = [c for seed in range(3) for c in generate_commands(load_world(path), seed=seed,
                                                                count=200)]
    return SimpleNamespace(path=path, cases=cases)


def test_no_command_sends_the_robot_behind_a_shut_or_tight_door_or_to_an_unsigned_room(tricky):
    places = {place for c in tricky.cases for _, place in c.objectives}
    assert places and not places & {"OFFICE 202", "KITCHEN", "unsigned room 1"}
    # an office is unsigned, so "the office" has no clear answer; shredders stand in two rooms
    assert not any(re.search(r"\bthe office\b|shredder|toolbox", c.command) for c in tricky.cases)
    # asked about, not sent to: the microscope in the kitchen, Bob in the shut office
    assert any(c.answer == ("KITCHEN",) for c in tricky.cases)
    assert any(c.answer[:1] == ("OFFICE 202",) for c in tricky.cases)


def test_rooms_sharing_a_number_are_named_by_their_whole_sign(tricky):
    named = {c.objectives[0][1] for c in tricky.cases if c.category == "go_named"}
    assert named == {"OFFICE 201", "LAB 1", "MEETING ROOM 1"}
    refused = " ".join(c.refused[0] for c in tricky.cases if c.category == "refuse_number")
    assert not re.search(r" (1|201|202)$", refused)


def test_the_planner_on_the_surveyed_tricky_floor_gets_every_command_right(tricky):
    score = score_commands(load_map(tricky.path), tricky.cases, NOW)
    assert _wrong(score) == []


# ---- the scorer ---------------------------------------------------------------------------------
WRONG = [
    CommandCase("go to the kitchen", "go_kind", objectives=(("go to", "LAB"),)),
    CommandCase("where is the printer?", "where_object", answer=("KITCHEN",)),
    CommandCase("who works in office 101", "where_person", answer=("OFFICE 10",)),
    CommandCase("go to the kitchen", "refuse_kind", refused=("this map has no kitchen",)),
    CommandCase("go to the pharmacy", "refuse_kind", refused=("this map has no library",)),
    CommandCase("go to the pharmacy", "go_kind", objectives=(("go to", "PHARMACY"),)),
    CommandCase("fetch the wizard's scroll", "refuse_kind", refused=("wizard",)),
]


def test_a_wrong_expectation_is_scored_wrong_and_says_what_came_instead(office):
    right = CommandCase("go to the kitchen", "go_kind", objectives=(("go to", "KITCHEN"),))
    score = score_commands(office.qm, [right, *WRONG], NOW)
    assert (score["total"], score["right"]) == (8, 1)
    assert score["right_fraction"] == pytest.approx(1 / 8)
    assert score["categories"]["go_kind"] == {"total": 3, "right": 1,
                                              "right_fraction": pytest.approx(1 / 3)}
    got = [row["got"] for row in score["cases"][1:]]
    assert got[0] == "go to at KITCHEN"
    assert "ADMIN" in got[1]
    assert got[3].startswith("not refused: go to at KITCHEN")
    assert got[5].startswith('error: cannot do "go to the pharmacy": this map has no pharmacy')
    assert got[6].startswith('error: could not understand "fetch the wizard\'s scroll"')


def test_names_compare_as_the_sign_scorer_compares_them(office):
    """A plate reads MAIL ROOM on the robot's map; the truth may spell it MAILROOM. The sign
    scorer counts that read exactly, so the command scorer counts the plan to it right: case
    and spacing say nothing, letters do."""
    spaced = [CommandCase("go to the mail room", "go_named", objectives=(("go to", "MAILROOM"),)),
              CommandCase("where is the kitchen?", "where_object", answer=("KIT CHEN",))]
    assert score_commands(office.qm, spaced, NOW)["right"] == 2
    other = CommandCase("go to the mail room", "go_named", objectives=(("go to", "MAIL ROOMS"),))
    assert score_commands(office.qm, [other], NOW)["right"] == 0


# ---- the file -----------------------------------------------------------------------------------
def test_the_commands_file_round_trips(office, tmp_path):
    cases = generate_commands(office.world, seed=5, count=30)
    path = write_commands(tmp_path / "office.commands.yaml", cases, "friday 14:05")
    assert load_commands(path) == (cases, "friday 14:05")
    assert load_commands(write_commands(tmp_path / "none.yaml", [], NOW)) == ([], NOW)


BAD = [
    ("comands: []\n", "comands", "unknown top-level field"),
    ("now: someday\ncommands: []\n", "now", "not a moment"),
    ("commands:\n  - {category: go_kind, objectives: [[go to, LAB]]}\n", "command",
     "must be a non-empty text"),
    ("commands:\n  - {command: go to the lab, category: go_kind, objectives: [[go to, LAB]],\n"
     "     answer: [LAB]}\n", "answer", "exactly one of"),
    ("commands:\n  - {command: go to the lab, category: go_kind, objectives: [[walk to, LAB]]}\n",
     "objectives", "the action 'walk to'"),
    ("commands:\n  - {command: go to the lab, category: go_kind, objectives: [LAB]}\n",
     "objectives", "[action, place] pairs"),
    ("commands:\n  - {command: where is the lab, category: x, answer: []}\n", "answer",
     "non-empty list"),
    ("commands:\n  - {command: go to the lab, category: x, refused: [no], expect: 1}\n", "expect",
     "unknown field"),
]


@pytest.mark.parametrize("text,field,message", BAD, ids=[b[1] + ": " + b[2] for b in BAD])
def test_a_malformed_commands_file_is_one_paragraph_naming_the_field(tmp_path, text, field,
                                                                     message):
    path = tmp_path / "bad.commands.yaml"
    path.write_text("version: 1\n" + text)
    with pytest.raises(CommandsError) as err:
        load_commands(path)
    assert err.value.field == field and err.value.line is not None
    text = str(err.value)
    assert message in text and str(path) in text and "\n" not in text


def test_a_case_needs_exactly_one_expectation():
    with pytest.raises(ValueError, match="exactly one"):
        CommandCase("go to the lab", "go_kind")


# ---- in a run -----------------------------------------------------------------------------------
class _Handle:
    def __init__(self, items: list[dict], occupancy=None) -> None:
        self.items, self.occupancy, self.version = items, occupancy, 1

    def current(self) -> list[dict]:
        return self.items

    def snapshot(self):
        return self.occupancy


def _run_knowledge(tmp_path: Path, *, commands: bool) -> dict:
    """The knowledge node's run.json metrics at the end of a run on the tricky floor, its
    map the true floor plan, with or without a commands file."""
    from blocks.semantic.blocks import Knowledge
    folder = tmp_path / "world"
    folder.mkdir()
    world = load_world(_write_floor(folder))
    if commands:
        write_commands(folder / "floor.commands.yaml", generate_commands(world, seed=0), NOW)
    world_file = _write_floor(folder, commands="floor.commands.yaml" if commands else None)
    # what the offline map node leaves in the run folder before the knowledge node finishes
    out = tmp_path / "run"
    occupancy = occupancy_map_from_world(world)
    write_map(out / "maps" / "offline.yaml", occupancy)
    write_path_csv(out / "maps" / "offline_path.csv", [0, 1], np.array([[1.0, 5.0, 0.0],
                                                                        [3.0, 5.0, 0.0]]))
    ctx = RunContext(dt=0.1, seed=0, out_dir=out)
    values = {name: p.default for name, p in Knowledge.params.items()}
    block = Knowledge({**values, "world": str(world_file), "live": False}, name="knowledge",
                      ctx=ctx)
    block.setup()
    block.reset()
    signs = [{"text": s.text, "x": s.x, "y": s.y, "facing": float(np.degrees(s.facing))}
             for s in world.signs]
    block.step(_Handle(signs), map=_Handle([], occupancy),
               objects=_Handle([{"label": o.label, "x": o.x, "y": o.y} for o in world.objects]))
    block.finish()
    return ctx.metrics["knowledge"]


def test_the_knowledge_block_reports_the_planner_score_on_its_own_map(tmp_path):
    metrics = _run_knowledge(tmp_path, commands=True)
    rows = metrics["commands_cases"]
    assert metrics["commands_total"] == len(rows) == 20
    assert metrics["commands_right"] == sum(r["right"] for r in rows)
    assert metrics["commands_right_fraction"] >= 0.8, _wrong({"cases": rows})
    assert metrics["commands_refuse_kind_right_fraction"] == 1.0
    assert "rooms_mean_iou" in metrics


def test_a_world_without_commands_reports_no_commands_score(tmp_path):
    metrics = _run_knowledge(tmp_path, commands=False)
    assert "rooms_mean_iou" in metrics
    assert not [key for key in metrics if key.startswith("commands")]


# ---- where plans stop ---------------------------------------------------------------------------
def _mapped_run(folder: Path, world_file: Path, signs: list[dict], unknown: str | None = None):
    """A run folder as the semantic mapping leaves it, the map the true floor plan (with the
    room ``unknown`` never seen), and the planner's map of it (its world not recorded)."""
    from blocks.maps.mapio import OccupancyMap
    from semantic.place_score import polygon_mask_on_grid
    from semantic.query import load_run_map
    from semantic.semantic_map import build_semantic_map, write_semantic_map
    world = load_world(world_file)
    occupancy = occupancy_map_from_world(world)
    if unknown is not None:
        inside = polygon_mask_on_grid(np.asarray(world.place(unknown).polygon), occupancy.shape,
                                      occupancy.resolution, occupancy.origin)
        occupancy = OccupancyMap(np.where(inside, np.nan, occupancy.occupancy),
                                 occupancy.resolution, occupancy.origin)
    write_map(folder / "maps" / "offline.yaml", occupancy)
    write_path_csv(folder / "maps" / "offline_path.csv", [0], np.array([[1.0, 5.0, 0.0]]))
    write_semantic_map(folder, build_semantic_map(occupancy, signs), occupancy, signs=signs)
    return load_run_map(folder)


def _signs(world) -> list[dict]:
    return [{"text": s.text, "x": s.x, "y": s.y, "facing": float(np.degrees(s.facing))}
            for s in world.signs]


@pytest.fixture(scope="module")
def exam_floor(tmp_path_factory):
    return _write_floor(tmp_path_factory.mktemp("stops"))


def test_a_stop_is_at_a_room_inside_it_or_in_front_of_it_not_behind_its_wall(exam_floor):
    from semantic.query.exam import AT_ROOM, stops_at
    world = load_world(exam_floor)
    assert stops_at(world, "LAB 1", 2.0, 8.0)  # inside
    assert stops_at(world, "LAB 1", 3.2, 5.0)  # the corridor in front of its door and plate
    assert not stops_at(world, "LAB 1", 3.2, 6.1 - AT_ROOM - 0.2)  # too far out (a wall away)
    assert not stops_at(world, "LAB 1", 5.0, 8.0)  # in the meeting room next door
    assert not stops_at(world, "LAB 1", 11.0, 5.0)  # down the corridor
    assert stops_at(world, "lab  1", 2.0, 8.0)  # names compare as signs do
    assert stops_at(world, "NO SUCH ROOM", 50.0, 50.0)  # nothing to check against


def test_a_plan_to_a_room_only_read_stops_at_its_door_and_counts(exam_floor, tmp_path):
    qm = _mapped_run(tmp_path, exam_floor, _signs(load_world(exam_floor)), unknown="LAB 1")
    case = CommandCase("go to lab 1", "go_named", objectives=(("go to", "LAB 1"),))
    (row,) = score_commands(qm, [case], NOW, world=load_world(exam_floor))["cases"]
    assert row["right"], row
    from semantic.query import ask
    plan = ask("go to lab 1", qm, now=NOW)
    (objective,) = plan.grounding.objectives
    assert 4.05 < objective.target.y < 6.0  # in the corridor, not in the unmapped room
    assert "has not been inside" in plan.grounding.answer


def test_a_plan_named_right_that_stops_in_the_wrong_room_is_wrong(exam_floor, tmp_path):
    """A plate misplaced on the meeting room's door names that room LAB 1 on the map: the
    plan says LAB 1 and drives into the meeting room."""
    world = load_world(exam_floor)
    signs = [s for s in _signs(world) if s["text"] not in ("LAB 1", "MEETING ROOM 1")]
    signs.append({"text": "LAB 1", "x": 7.2, "y": 5.95, "facing": -90.0})
    qm = _mapped_run(tmp_path, exam_floor, signs)
    case = CommandCase("go to lab 1", "go_named", objectives=(("go to", "LAB 1"),))
    (row,) = score_commands(qm, [case], NOW, world=world)["cases"]
    assert not row["right"] and "not at LAB 1" in row["got"], row
    (by_name,) = score_commands(qm, [case], NOW)["cases"]  # no world known: names alone
    assert by_name["right"]
