"""Building layouts, one kind per module: each ``draw(plan, rng, namer)`` fills a floor plan.

office
    A straight or L-shaped corridor with rooms on both sides.
ring
    A ring corridor round a central block of rooms or a closed courtyard,
    rooms outside it, sometimes a pinch down to 0.9 m.
hospital
    A long double-loaded corridor broken by wide halls, wards and theatres.
school
    A main corridor with one branch (a T) or two (a comb), dead ends, classrooms.
hall
    An open hall, sometimes with cut (45-degree) corners and pillars, rooms off
    it and a corridor leading away.
"""
from __future__ import annotations

from . import hall, hospital, office, ring, school

#: Layout kind -> (its draw function, the vocabulary domain of its rooms).
LAYOUTS = {
    "office": (office.draw, "office"),
    "ring": (ring.draw, "office"),
    "hospital": (hospital.draw, "hospital"),
    "school": (school.draw, "school"),
    "hall": (hall.draw, "office"),
}
