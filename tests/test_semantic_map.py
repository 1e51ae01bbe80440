"""The semantic map assembled from a map, signs and objects; the `semmap sparql` command."""
from __future__ import annotations

import json
import math

import pytest

from blocks.maps.mapio import occupancy_map_from_world
from semantic.semantic_map import build_semantic_map, live_kb, write_semantic_map
from sim2d.worlds import world_path
from sim2d.world import load_world


@pytest.fixture(scope="module")
def office():
    world = load_world(world_path("office"))
    signs = [{"text": s.text, "x": s.x, "y": s.y, "facing": math.degrees(s.facing)} for s in world.signs]
    return world, occupancy_map_from_world(world), signs


@pytest.fixture(scope="module")
def office_map(office):
    world, occupancy, signs = office
    objects = [{"label": "Shredder", "x": 27.5, "y": 3.2}]  # in the kitchen, not the mail room
    return build_semantic_map(occupancy, signs, objects)


def _place_named(sm, text):
    ids = [pid for pid, name in sm.names.items() if name == text]
    assert len(ids) == 1, f"{text}: {ids}"
    return ids[0]


def test_every_signed_room_becomes_a_place_of_its_kind(office, office_map):
    _, _, signs = office
    assert sorted(office_map.names.values()) == sorted(s["text"] for s in signs)
    assert office_map.kinds[_place_named(office_map, "MAIL ROOM")] == "MailRoom"
    assert office_map.kinds[_place_named(office_map, "OFFICE 101")] == "Office"
    corridors = [pid for pid, kind in office_map.kinds.items() if kind == "Corridor"]
    assert len(corridors) == 1


def test_the_semantic_map_answers_from_signs_defaults_and_observations(office_map):
    kb = office_map.kb
    manager = _place_named(office_map, "MANAGER")
    assert kb.works_in("Manager") == [manager]
    mail_room = _place_named(office_map, "MAIL ROOM")
    kitchen = _place_named(office_map, "KITCHEN")
    assert ("Fridge", "default") in kb.equipment_in(kitchen)  # the kitchen's function implies it
    # the mail room's default shredder gives way to the one seen in the kitchen
    assert ("Shredder", "default") not in kb.equipment_in(mail_room)
    assert kb.where_is("Shredder") == [(kitchen, "observed")]
    assert kb.connected(mail_room, _place_named(office_map, "LAB"))


def test_the_outputs_are_written(tmp_path, office, office_map):
    _, occupancy, signs = office
    written = write_semantic_map(tmp_path, office_map, occupancy, signs=signs)
    assert all(p.exists() and p.stat().st_size > 0 for p in written)
    geo = json.loads((tmp_path / "places.geojson").read_text())
    names = {f["properties"].get("name") for f in geo["features"]}
    assert "MAIL ROOM" in names
    import rdflib
    g = rdflib.Graph().parse(tmp_path / "semantic_map.ttl", format="turtle")
    assert len(g) > 100


def test_the_live_knowledge_base_knows_a_room_as_soon_as_its_sign_is_read():
    kb = live_kb([{"text": "MANAGER", "x": 8.35, "y": 5.1, "facing": 90.0}])
    kb.reason()
    assert len(kb.works_in("Manager")) == 1


def test_sparql_command_answers_and_reports_bad_queries(tmp_path, office, office_map, capsys):
    from blocks.cli import main
    _, occupancy, signs = office
    write_semantic_map(tmp_path, office_map, occupancy, signs=signs)
    query = "SELECT ?name WHERE { ?p indoor:name ?name } ORDER BY ?name"
    assert main(["sparql", str(tmp_path), query, "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)["rows"]
    assert ["MAIL ROOM"] in rows
    assert main(["sparql", str(tmp_path), "SELECT ?x WHERE { ?x"]) != 0
    err = capsys.readouterr().err
    assert "SPARQL" in err and "Traceback" not in err
    assert main(["sparql", str(tmp_path / "nowhere"), query]) != 0
    assert "semantic map" in capsys.readouterr().err


def _live_updates():
    """Live inputs as the knowledge block sees them: a sign read, an object seen and moved
    (its running mean), a sign inserted before the others (ids shift: a retraction), a
    second object, and an object given to a sign's place once that sign is read."""
    manager = {"text": "MANAGER", "x": 8.35, "y": 5.1, "facing": 90.0}
    kitchen = {"text": "KITCHEN", "x": 27.0, "y": 5.1, "facing": 90.0}
    mail = {"text": "MAIL ROOM", "x": 3.0, "y": 5.1, "facing": 90.0}
    shredder = {"label": "Shredder", "x": 8.0, "y": 3.0}
    moved = {"label": "Shredder", "x": 8.2, "y": 3.1}
    printer = {"label": "Printer", "x": 27.5, "y": 3.0}
    return [([manager], []), ([manager], [shredder]), ([manager], [moved]),
            ([manager], [moved, printer]), ([manager, kitchen], [moved, printer]),
            ([mail, manager, kitchen], [moved, printer]),
            ([mail, manager, kitchen], [moved, printer])]


def test_a_live_base_handed_the_previous_owl_pass_equals_one_reasoned_from_scratch():
    """Reusing or extending the previous update's OWL closure gives what a fresh base
    gives, update by update, whether the OWL input stayed, grew or shrank."""
    owl, how = None, []
    for signs, objects in _live_updates():
        kb = live_kb(signs, objects, owl=owl)
        stats = kb.reason()
        owl = kb.owl
        how.append(stats.incremental)
        fresh = live_kb(signs, objects)
        fresh_stats = fresh.reason()
        assert not fresh_stats.incremental
        assert kb.facts.triples == fresh.facts.triples
        assert set(kb.graph) == set(fresh.graph)
        assert stats.triples_after == fresh_stats.triples_after
        assert kb.works_in("Manager") == fresh.works_in("Manager")
    # first from scratch; an object moved: the same OWL input; a retraction: from scratch
    assert how[0] is False and how[2] is True and how[5] is False and how[6] is True


def test_an_owl_pass_reuses_extends_or_restarts_its_closure():
    from semantic.kb import OwlPass
    from rdflib import RDF
    kb = live_kb([{"text": "MANAGER", "x": 8.35, "y": 5.1, "facing": 90.0}])
    owl = OwlPass()
    axioms = kb._owl_tbox
    a = (kb._iri("S1"), RDF.type, kb._class("Office", {"place"}, "kind"))
    b = (kb._iri("S2"), RDF.type, kb._class("Kitchen", {"place"}, "kind"))
    first, inc = owl.close(axioms, {a})
    assert not inc
    again, inc = owl.close(axioms, {a})
    assert inc and again is first  # the same input: the same closure, no reasoning
    grown, inc = owl.close(axioms, {a, b})
    assert inc and (b[0], RDF.type, kb._class("Room", {"place"}, "kind")) in grown.on_map
    shrunk, inc = owl.close(axioms, {b})
    assert not inc and all(t[0] != a[0] for t in shrunk.on_map)
    fresh, _ = OwlPass().close(axioms, {a, b})
    assert set(grown.on_map) == set(fresh.on_map) and set(grown.off_map) == set(fresh.off_map)


def test_an_owl_pass_that_failed_does_not_give_its_last_closure_again(monkeypatch):
    import reasonable
    from rdflib import RDF

    from semantic.kb import OwlPass
    kb = live_kb([{"text": "MANAGER", "x": 8.35, "y": 5.1, "facing": 90.0}])
    owl, axioms = OwlPass(), kb._owl_tbox
    a = (kb._iri("S1"), RDF.type, kb._class("Office", {"place"}, "kind"))
    b = (kb._iri("S2"), RDF.type, kb._class("Kitchen", {"place"}, "kind"))
    first, _ = owl.close(axioms, {a})

    def broken(self):
        raise RuntimeError("reasoner crashed")
    with monkeypatch.context() as m:
        m.setattr(reasonable.PyReasoner, "reason", broken)
        with pytest.raises(RuntimeError):
            owl.close(axioms, {a, b})
    again, incremental = owl.close(axioms, {a, b})
    assert not incremental and again is not first  # a new reasoner, from scratch
    assert (b[0], RDF.type, kb._class("Room", {"place"}, "kind")) in again.on_map


@pytest.fixture(scope="module")
def manager_unentered(office):
    """The office mapped everywhere but inside the MANAGER's room, as when the robot read
    the plate beside its door and never went in; the plate read twice."""
    import numpy as np

    from blocks.maps.mapio import OccupancyMap
    from semantic.place_score import polygon_mask_on_grid
    world, occupancy, signs = office
    inside = polygon_mask_on_grid(np.asarray(world.place("MANAGER").polygon), occupancy.shape,
                                  occupancy.resolution, occupancy.origin)
    unknown = np.where(inside, np.nan, occupancy.occupancy)
    blank = OccupancyMap(unknown, occupancy.resolution, occupancy.origin)
    manager = next(s for s in signs if s["text"] == "MANAGER")
    again = dict(manager, x=manager["x"] + 0.3)
    return signs + [again], build_semantic_map(blank, signs + [again])


def test_a_room_read_but_not_entered_is_a_place_at_its_door(manager_unentered):
    """Why: the robot learnt that the manager's room is behind that door; dropping the
    room with the map's missing outline would lose it for every command."""
    signs, sm = manager_unentered
    k = next(i for i, s in enumerate(signs) if s["text"] == "MANAGER")
    assert "MANAGER" not in sm.names.values() and sm.sign_places[k] is None
    (pid, (name, (x, y))), = sm.unentered.items()  # one place for both readings
    facing = math.radians(signs[k]["facing"])
    assert name == "MANAGER"
    assert (x, y) == pytest.approx((signs[k]["x"] + 0.5 * math.cos(facing),
                                    signs[k]["y"] + 0.5 * math.sin(facing)))
    assert sm.kb.place_kind(pid) == "ManagerOffice"
    assert sm.kb.works_in("Manager") == [pid]  # the sign's meaning is kept
    assert sm.kb.polygon(pid) is None
    mapped = {p.id for p in sm.places.places}
    assert pid not in mapped and len(sm.names) == len(signs) - 2  # the rest as before


def test_only_place_names_not_yet_on_the_map_make_unentered_rooms(office):
    _, occupancy, signs = office
    extra = [dict(signs[0], x=signs[0]["x"] + 9.0),  # a name already on the map
             {"text": "PUSH", "x": 20.0, "y": 5.05, "facing": 90.0}]  # names no place
    sm = build_semantic_map(occupancy, signs + extra)
    assert sm.unentered == {}


def test_an_unentered_room_is_on_the_picture_and_in_the_geojson(tmp_path, office,
                                                                 manager_unentered):
    _, occupancy, _ = office
    signs, sm = manager_unentered
    write_semantic_map(tmp_path, sm, occupancy, signs=signs)
    geo = json.loads((tmp_path / "places.geojson").read_text())
    (room,) = [f for f in geo["features"] if f["properties"].get("entered") is False]
    assert room["geometry"]["type"] == "Point"
    assert room["properties"]["name"] == "MANAGER"
    assert room["properties"]["kind"] == "ManagerOffice"
