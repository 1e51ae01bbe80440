"""Timetable files: loading, errors with file and line, and "where is X at T"."""
from __future__ import annotations

import datetime as dt

import pytest

from blocks.core.errors import SemmapError
from semantic.kb import KnowledgeBase
from semantic.timetable import EXAMPLES, load_timetable
from semantic.vocabulary import load_vocabulary
from sim2d.world import load_world
from sim2d.worlds import world_path

MON = dt.datetime(2024, 1, 1)  # a Monday


def write(tmp_path, text):
    path = tmp_path / "tt.yaml"
    path.write_text(text)
    return path


GOOD = """people:
  - {name: "Dr Ada Lovelace", role: Teacher}
slots:
  - {person: "Dr Ada Lovelace", place: "LAB", days: [mon, wed], start: "09:00", end: "11:00",
     subject: "Robotics"}
"""


def test_where_at_time(tmp_path):
    tt = load_timetable(write(tmp_path, GOOD))
    assert tt.people[0].role == "Teacher" and tt.slots[0].subject == "Robotics"
    assert tt.where("Dr Ada Lovelace", MON.replace(hour=9)) == "LAB"
    assert tt.where("dr  ada lovelace", MON.replace(hour=10, minute=59)) == "LAB"
    assert tt.where("Dr Ada Lovelace", MON.replace(hour=11)) is None  # end is exclusive
    assert tt.where("Dr Ada Lovelace", MON.replace(day=2, hour=10)) is None  # Tuesday
    assert tt.where("Nobody", MON.replace(hour=10)) is None


def test_unquoted_times_are_read_as_times(tmp_path):
    tt = load_timetable(write(tmp_path, GOOD.replace('"09:00"', "09:00")))
    assert tt.slots[0].start == dt.time(9, 0)


@pytest.mark.parametrize("old, new, line, field", [
    ('start: "09:00"', 'start: "9 am"', 4, "start"),
    ('end: "11:00"', 'end: "08:00"', 4, "end"),
    ("days: [mon, wed]", "days: [mon, someday]", 4, "days"),
    ('person: "Dr Ada Lovelace"', 'person: "Dr Ada Lovelase"', 4, "person"),
    ("role: Teacher", "role: teacher", 2, "role"),
    ('subject: "Robotics"', 'topic: "Robotics"', 5, "topic"),
    ("people:", "persons:", 1, "persons"),
])
def test_errors_name_file_line_and_field(tmp_path, old, new, line, field):
    path = write(tmp_path, GOOD.replace(old, new))
    with pytest.raises(SemmapError) as exc:
        load_timetable(path)
    err = exc.value
    assert err.file == str(path) and err.line == line and err.field == field, str(err)
    assert str(path) in str(err)


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(SemmapError, match="not found"):
        load_timetable(tmp_path / "none.yaml")
    with pytest.raises(SemmapError) as exc:
        load_timetable(write(tmp_path, "people: [\n  {name: x\n"))
    assert exc.value.line is not None


@pytest.mark.parametrize("world", ["office", "hospital"])
def test_example_timetables_use_the_worlds_sign_texts_and_ontology_roles(world):
    tt = load_timetable(EXAMPLES[world])
    texts = {s.text for s in load_world(world_path(world)).signs}
    voc = load_vocabulary()
    for slot in tt.slots:
        assert slot.place in texts, slot
    for person in tt.people:
        assert person.workplace is None or person.workplace in texts
    assert all(voc.place_class(t) for t in texts)
    kb = KnowledgeBase()
    kb.add_timetable(tt)  # every role is an ontology role (raises otherwise)


def test_kb_answers_from_the_office_timetable():
    w = load_world(world_path("office"))
    kb = KnowledgeBase.from_world(w, timetable=load_timetable(EXAMPLES["office"]))
    lab = next(pid for pid in kb.place_graph().nodes
               if kb.place_graph().nodes[pid]["name"] == "LAB")
    office101 = next(pid for pid, d in kb.place_graph().nodes(data=True)
                     if d["name"] == "OFFICE 101")
    assert kb.where_is_person_at("Dr Ada Lovelace", MON.replace(hour=10)) == lab
    assert kb.where_is_person_at("Dr Ada Lovelace", MON.replace(hour=12)) == office101
    manager_office = kb.works_in("Grace Hopper")
    assert len(manager_office) == 1 and kb.place_kind(manager_office[0]) == "ManagerOffice"
    assert kb.where_is_person_at("manager", MON.replace(hour=12, minute=15)) == next(
        pid for pid, d in kb.place_graph().nodes(data=True) if d["name"] == "KITCHEN")
    rows = kb.query("SELECT ?day WHERE { ?s a indoor:Slot ; indoor:person ?p ; "
                    "indoor:dayOfWeek ?day . ?p indoor:name 'Dr Ada Lovelace' . "
                    "?s indoor:startTime ?t . FILTER (?t = '09:00:00'^^xsd:time) }")
    assert sorted(r["day"] for r in rows) == ["mon", "wed"]
