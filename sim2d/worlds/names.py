"""Room names and classes for generated buildings, drawn from the place vocabulary.

Each domain has a programme: the rooms it repeats (offices, classrooms,
wards: numbered on their signs) and the rooms it has at most once (a
kitchen, a pharmacy). Every sign text is a phrase or a filled pattern of
``semantic/vocabulary.yaml``, so the reader and the knowledge base know it,
and no two rooms of a floor share a name.
"""
from __future__ import annotations

import numpy as np

__all__ = ["PROGRAMMES", "RoomNamer"]

#: Per domain: (repeated classes with the pattern their signs use, singular classes).
PROGRAMMES: dict[str, tuple[dict[str, str], list[str]]] = {
    "office": ({"Office": "OFFICE {n}", "MeetingRoom": "MEETING ROOM {n}",
                "Laboratory": "LAB {n}", "Storage": "STORE {n}"},
               ["ManagerOffice", "Administration", "Reception", "Library", "ComputerRoom",
                "ServerRoom", "CopyRoom", "MailRoom", "Kitchen", "BreakRoom", "Toilet",
                "Maintenance", "PlantRoom", "Elevator", "Stairs"]),
    "hospital": ({"Ward": "WARD {n}", "PatientRoom": "PATIENT ROOM {n}",
                  "ConsultingRoom": "CONSULTING ROOM {n}", "Office": "OFFICE {n}"},
                 ["Pharmacy", "Radiology", "OperatingRoom", "IntensiveCare", "Emergency",
                  "WaitingRoom", "Maternity", "Physiotherapy", "Sterilisation", "Laboratory",
                  "Kitchen", "Toilet", "Elevator", "Stairs", "Administration", "Reception",
                  "Storage"]),
    "school": ({"Classroom": "CLASSROOM {n}", "Office": "OFFICE {n}",
                "Laboratory": "LAB {n}"},
               ["StaffRoom", "PrincipalOffice", "Library", "Gymnasium", "MusicRoom", "ArtRoom",
                "ComputerRoom", "LectureHall", "Administration", "Cafeteria", "Storage",
                "Maintenance", "Toilet", "Stairs", "MailRoom"]),
}
_MIN_LETTERS = 4  # a sign never says only "WC" or "MEN": too short to be read for sure


class RoomNamer:
    """Hands out (name, class) pairs for one floor: numbered repeats, singular rooms once.

    Parameters
    ----------
    domain : str
        A key of :data:`PROGRAMMES`.
    rng : numpy.random.Generator
        Picks the first room number and the order of singular rooms.
    """

    def __init__(self, domain: str, rng: np.random.Generator) -> None:
        from semantic.vocabulary import load_vocabulary
        self.vocabulary = load_vocabulary()
        self.repeated, singular = PROGRAMMES[domain]
        self.singular = [singular[i] for i in rng.permutation(len(singular))]
        self.number = int(rng.integers(1, 4)) * 100 + 1
        self.counts: dict[str, int] = {}
        self.unsigned = 0
        self.used: set[str] = set()

    def next(self, rng: np.random.Generator, kind: str | None = None) -> tuple[str, str]:
        """A fresh (sign text, class); ``kind`` asks for a class (repeated or singular)."""
        if kind is None:
            if self.singular and rng.random() < 0.45:
                kind = self.singular[0]
            else:
                kind = list(self.repeated)[int(rng.integers(len(self.repeated)))]
        if kind in self.singular:
            self.singular.remove(kind)
            name = self._phrase(rng, kind)
            if name not in self.used:
                self.used.add(name)
                return name, kind
        if kind not in self.repeated:
            kind = list(self.repeated)[0]
        n = self.counts.get(kind, 0) + 1
        self.counts[kind] = n
        number = self.number + self.counts.get("_all", 0)
        self.counts["_all"] = self.counts.get("_all", 0) + 1
        name = self.repeated[kind].format(n=number if kind in ("Office", "PatientRoom") else n)
        self.used.add(name)
        return name, kind

    def unsigned_name(self) -> str:
        """A name for a room without a sign (not a sign text: nothing on the floor says it)."""
        self.unsigned += 1
        return f"unsigned room {self.unsigned}"

    def _phrase(self, rng: np.random.Generator, kind: str) -> str:
        phrases = [p for p in self.vocabulary.entry(kind).phrases
                   if len(p.replace(" ", "")) >= _MIN_LETTERS]
        if not phrases or rng.random() < 0.7:
            return self.vocabulary.entry(kind).phrases[0]
        return phrases[int(rng.integers(len(phrases)))]
