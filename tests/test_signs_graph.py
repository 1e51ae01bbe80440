"""graphs/semantic_mapping.yaml end to end on the office: signs found, read, placed, drawn."""
from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from conftest import ROOT

# the main pipeline end to end (`make test` runs each file on one worker, --dist
# loadfile, so the office run, the suite's longest setup, is not run on both)
pytestmark = pytest.mark.slow

GRAPH = ROOT / "graphs/semantic_mapping.yaml"


@pytest.fixture(scope="module")
def office_run(tmp_path_factory):
    from blocks.cli import main
    out = tmp_path_factory.mktemp("semantic") / "office"
    # 1,250 s, not the default 1,500: past the loop's close (1,072 s) and the mail room's
    # visit after it (from 1,089 s), which is all these tests look at; the suite's
    # longest setup, so its last four minutes of exploring are left to `make demo`
    code = main(["run", str(GRAPH), "--world", "office", "--out", str(out), "-q",
                 "--steps", "12500"])
    assert code == 0
    return out, json.loads((out / "run.json").read_text())["metrics"]


def test_the_signs_along_the_path_are_read_and_placed_without_false_signs(office_run):
    out, metrics = office_run
    signs = metrics["signs"]
    assert signs["signs_along_path"] >= 12  # the loop passes (nearly) every office sign
    # room visits change the path; a sign passed while a visit drives can be missed
    assert signs["read_exactly_along_path"] >= 0.85 * signs["signs_along_path"]
    assert signs["false_signs"] == 0
    assert signs["position_error_max"] < 0.4  # what the drift correction leaves (odometry: 0.8)
    assert signs["position_error_max_true_pose"] < 0.3  # the correlation's own error
    # white panels (the coffee machine's "BARISTA", ...) can pass for a plate in some
    # frames, the more so now that the camera looks round inside the rooms; they never
    # become a sign (false_signs above)
    detector = metrics["detector"]
    assert detector["false_positives"] <= 0.05 * detector["frames"]
    seek = metrics["seek"]
    assert seek["captures"] == seek["stops"] - seek["rejected_not_sign"] - seek["timeouts"]
    assert metrics["reader"]["captures_read"] == seek["captures"]
    # every reading placed is listed, with the plate it went to
    import csv
    rows = list(csv.DictReader((out / "signs/sightings.csv").open()))
    assert len(rows) <= seek["captures"]
    assert sum(r["published"] == "True" for r in rows) == signs["sightings"]


def test_the_stops_add_little_to_the_exploration(office_run):
    _, metrics = office_run
    loop = metrics["follower.loop"]
    assert loop["loop_closed"]
    # the stops themselves take no more than a tenth of the exploration
    assert metrics["seek"]["stopped_time_s"] <= 0.1 * loop["loop_time_s"]


def test_signs_json_and_the_hybrid_map_are_written(office_run):
    out, _ = office_run
    signs = json.loads((out / "signs.json").read_text())
    assert isinstance(signs, list) and signs
    for s in signs:
        assert set(s) >= {"text", "raw_text", "confidence", "x", "y", "facing", "sightings"}
        assert 0.5 <= s["confidence"] <= 1.0 and s["sightings"] >= 1
    assert len({s["text"] for s in signs}) == len(signs)  # repeated sightings merged
    image = cv2.imread(str(out / "maps/hybrid.png"))
    assert image is not None and image.shape[0] > 200 and image.std() > 10
    assert (out / "maps/offline.yaml").exists()
    assert list((out / "signs/captures").glob("*.png"))
    assert (out / "signs/seek_log.csv").read_text().startswith("time,event")


def test_the_semantic_map_is_written_and_its_rooms_are_the_signed_ones(office_run):
    out, metrics = office_run
    knowledge = metrics["knowledge"]
    assert knowledge["live_updates"] >= 10  # re-reasoned as the signs came in
    assert knowledge["signed_places"] >= 10
    assert knowledge["rooms_one_place_rooms"] >= 10  # each glimpsed room is one place
    assert knowledge["rooms_mean_iou_observed"] >= 0.6  # of what the sonar saw of them
    geo = json.loads((out / "places.geojson").read_text())
    names = {f["properties"].get("name") for f in geo["features"]}
    # the mail room, read last after ~15 min of odometry drift, is not always named yet
    # (issue 7 stays open for it)
    assert {"MANAGER", "KITCHEN"} <= names
    import rdflib
    graph = rdflib.Graph().parse(out / "semantic_map.ttl", format="turtle")
    rows = list(graph.query(
        "PREFIX indoor: <https://w3id.org/semmap/indoor#> "
        "SELECT ?name WHERE { ?p indoor:hasDefaultEquipment indoor:Fridge ; indoor:name ?name }"))
    assert [str(r[0]) for r in rows] == ["KITCHEN"]
    assert cv2.imread(str(out / "maps/semantic.png")) is not None
    objects = metrics["objects"]
    assert objects["false_positives"] == 0


def test_the_rooms_behind_the_signs_are_visited_and_mapped(office_run):
    """Issue 7's target: a mean IoU >= 0.7 over the rooms the run explored (>= half seen).
    The default office run measures 0.76 over 13: 0.79-0.89 each but the elevator's 0.60
    (62 % seen) and the stairs', mapped but its sign not read, 0; the bounds leave room
    for small changes to the path, not for the odometry's bent walls (0.69)."""
    _, metrics = office_run
    rooms = metrics["rooms"]
    assert rooms["visited"] >= 9 and rooms["failed"] == 0
    assert metrics["world"]["collisions"] == 0  # neither the visits nor the explorer
    knowledge = metrics["knowledge"]
    assert knowledge["rooms_explored_rooms"] >= 9
    assert knowledge["rooms_mean_iou_explored"] >= 0.75
    explored = [r for r in knowledge["rooms"] if r["coverage"] >= 0.5]
    assert len(explored) == knowledge["rooms_explored_rooms"]
    # what was seen of each is mapped well; a room seen only in part (the elevator,
    # 62 % from the frontier explorer's passes) cannot match the whole room better.
    # A room whose sign was not read has no named place to score (the office's one
    # missed sign, STAIRS, passed while a room visit turned the robot)
    named = [r for r in explored if r["place"]]
    assert len(explored) - len(named) <= 1
    assert min(r["iou_observed"] for r in named) >= 0.8
    assert min(r["iou"] for r in named if r["coverage"] >= 0.8) >= 0.65
    assert metrics["follower.loop"]["loop_closed"]


def test_the_shredder_seen_in_the_kitchen_overrides_the_default(office_run):
    out, _ = office_run
    import rdflib
    graph = rdflib.Graph().parse(out / "semantic_map.ttl", format="turtle")
    prefix = "PREFIX indoor: <https://w3id.org/semmap/indoor#> "
    observed = {str(r[0]) for r in graph.query(
        prefix + "SELECT ?name WHERE { ?o a indoor:Shredder ; indoor:source \"observed\" ; "
                 "indoor:locatedIn ?p . ?p indoor:name ?name }")}
    assert observed == {"KITCHEN"}
    # ...so the mail room's default shredder is withdrawn
    defaults = list(graph.query(
        prefix + "SELECT ?p WHERE { ?p indoor:hasDefaultEquipment indoor:Shredder }"))
    assert defaults == []


def test_the_query_planner_plans_on_the_run_and_names_what_its_map_lacks(office_run, cli):
    """`semmap ask` on a real mapping run: the drift-corrected path is written, the kitchen
    (signed, visited) is planned to through its door, and a place the run did not name is
    reported as missing with the places it did name, not guessed."""
    from blocks.maps.pathio import read_path_csv
    out, _ = office_run
    ticks, poses = read_path_csv(out / "maps" / "offline_path.csv")
    assert len(ticks) > 1000 and np.allclose(poses[0], [1.0, 5.8, 0.0], atol=1e-3)
    result = cli("ask", "go to the kitchen", "--map", out, "--json")
    assert result.code == 0, result.err
    data = json.loads(result.out)
    assert [(s["action"], s["place"]) for s in data["steps"]] == [("go to", "KITCHEN")]
    assert 25 < data["path_length_m"] < 35  # along the south corridor, into the room
    result = cli("ask", "go to the pharmacy", "--map", out)
    assert result.code == 3
    assert "this map has no pharmacy" in result.err and "KITCHEN" in result.err


def test_a_plan_on_the_mapped_run_is_driven_in_the_true_world_without_collisions(office_run,
                                                                                  cli, tmp_path):
    out, _ = office_run
    result = cli("ask", "go to the kitchen", "--map", out, "--execute", "--out", tmp_path / "x")
    assert result.code == 0, result.err
    metrics = json.loads((tmp_path / "x" / "run.json").read_text())["metrics"]
    assert [(g["name"], g["status"]) for g in metrics["goto"]["goals"]] == [("KITCHEN",
                                                                             "reached")]
    assert metrics["world"]["collisions"] == 0
