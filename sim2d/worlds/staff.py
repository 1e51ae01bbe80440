"""Who works on a generated floor, and when they are where: a timetable from its rooms.

Each signed room whose class is some role's workplace gets a person of that
role (a manager for the MANAGER office, a pharmacist for the PHARMACY);
numbered offices get researchers, teachers or doctors with the office as their
own workplace; meeting rooms, classrooms, labs and halls get weekly slots.
The file is ``semantic/timetable.py``'s format, so the knowledge base and the
planner read it as they read the shipped worlds' timetables.
"""
from __future__ import annotations

import numpy as np

from .floorplan import FloorPlan

__all__ = ["ROLE_OF_KIND", "timetable_document"]

#: Place class -> the role whose workplace it is (the ontology's ``workplaceKind``).
ROLE_OF_KIND = {
    "ManagerOffice": "Manager", "Administration": "Administrator", "Reception": "Receptionist",
    "Classroom": "Teacher", "Maintenance": "Technician", "Library": "Librarian",
    "ConsultingRoom": "Doctor", "OperatingRoom": "Surgeon", "Pharmacy": "Pharmacist",
    "Radiology": "Radiographer", "Kitchen": "Cook", "Laboratory": "Researcher",
    "PrincipalOffice": "Principal", "MailRoom": "MailClerk", "ServerRoom": "SystemAdministrator",
}
#: Who sits in a numbered office, by the building's domain.
OFFICE_ROLE = {"office": "Researcher", "school": "Teacher", "hospital": "Doctor"}
#: Where slots happen: a person of these roles meets in rooms of these classes.
SLOT_KINDS = ("MeetingRoom", "Classroom", "Laboratory", "LectureHall", "Library", "StaffRoom")
FIRST = ("Ada", "Alan", "Grace", "Katherine", "Edsger", "Barbara", "Claude", "Hedy", "John",
         "Margaret", "Donald", "Frances", "Dennis", "Radia", "Tim", "Sophie", "Niklaus",
         "Shafi", "Leslie", "Karen", "Tony", "Annie", "Vint", "Jean", "Marvin", "Lynn")
LAST = ("Lovelace", "Turing", "Hopper", "Johnson", "Dijkstra", "Liskov", "Shannon", "Lamarr",
        "Backus", "Hamilton", "Knuth", "Allen", "Ritchie", "Perlman", "Berners-Lee", "Wilson",
        "Wirth", "Goldwasser", "Lamport", "Sparck Jones", "Hoare", "Easley", "Cerf",
        "Bartik", "Minsky", "Conway")
DAY_SETS = (["mon", "wed"], ["tue", "thu"], ["fri"], ["mon", "tue", "wed", "thu", "fri"],
            ["wed"], ["thu", "fri"])


def _names(rng: np.random.Generator, count: int) -> list[str]:
    pairs = [(f, s) for f in FIRST for s in LAST]
    picks = rng.choice(len(pairs), size=min(count, len(pairs)), replace=False)
    return [f"{pairs[i][0]} {pairs[i][1]}" for i in picks]


def timetable_document(plan: FloorPlan, rng: np.random.Generator) -> dict:
    """The timetable of a floor: people (name, role, workplace) and weekly slots."""
    signed = [s for s in plan.rooms() if s.signed and not _closed(plan, s.name)]
    staff: list[dict] = []
    for room in signed:
        if room.kind in ROLE_OF_KIND and not any(p["role"] == ROLE_OF_KIND[room.kind]
                                                 for p in staff):
            staff.append({"role": ROLE_OF_KIND[room.kind]})
    offices = [r for r in signed if r.kind == "Office"]
    for room in offices[:4]:
        staff.append({"role": OFFICE_ROLE[plan.domain], "workplace": room.name})
    names = _names(rng, len(staff))
    people = [{"name": n, **p} for n, p in zip(names, staff)]
    venues = [r.name for r in signed if r.kind in SLOT_KINDS]
    slots = []
    for person in people:
        if not venues or rng.random() < 0.3:
            continue
        hour = int(rng.integers(8, 16))
        minutes = int(rng.choice([0, 30]))
        length = int(rng.choice([60, 90, 120]))
        end = hour * 60 + minutes + length
        slots.append({"person": person["name"], "place": venues[int(rng.integers(len(venues)))],
                      "days": DAY_SETS[int(rng.integers(len(DAY_SETS)))],
                      "start": f"{hour:02d}:{minutes:02d}", "end": f"{end // 60:02d}:{end % 60:02d}",
                      "subject": "Weekly meeting"})
    return {"version": 1, "people": people, "slots": slots}


def _closed(plan: FloorPlan, room: str) -> bool:
    return any(d.closed and room in d.between for d in plan.doors)
