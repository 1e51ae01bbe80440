"""Knowledge base reasoning time: can it re-run whenever the robot reads a new sign?

Two knowledge bases are built: the office world's ground truth (14 signed rooms
and the corridor, their doors and signs, the world's objects and the example
timetable) and a synthetic 50-place floor (two corridors joined by a hall, 47
rooms of kinds cycling through the vocabulary, each with a door and a sign, an
object in every third room, a timetable of 10 people). Each is reasoned over
once from scratch (*full*: the OWL 2 RL pass by ``reasonable`` from nothing,
then the domain rules), then a new sign is added and it is reasoned over again
(*per sign*: the pass a running robot makes; incremental OWL). Times are
medians over ``--repeats``.

The reference, measured in the same run on the 50-place floor, is ``owlrl``
(pure-Python OWL 2 RL, run once: it is slow) on exactly the triples
``reasonable`` is given; the ratio says how many times faster the OWL pass is.
Target: per-sign re-reasoning of the 50-place floor <= 100 ms (median).
"""
from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from semantic.kb import KnowledgeBase  # noqa: E402
from semantic.timetable import EXAMPLES, Person, Slot, Timetable, load_timetable  # noqa: E402
from semantic.vocabulary import load_vocabulary  # noqa: E402
from sim2d.world import load_world  # noqa: E402
from sim2d.worlds import world_path  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))
from results_io import write_results  # noqa: E402

RESULTS_JSON = Path(__file__).resolve().parent / "results" / "reasoner.json"
PER_SIGN_TARGET_MS = 100.0
OBJECTS = ("Shredder", "Printer", "Laptop", "Book", "Mail", "Microscope", "Projector")


def office_kb() -> KnowledgeBase:
    """The office world's ground truth with the example office timetable."""
    return KnowledgeBase.from_world(load_world(world_path("office")),
                                    timetable=load_timetable(EXAMPLES["office"]))


def synthetic_kb(places: int = 50) -> KnowledgeBase:
    """A floor of ``places`` places: corridors W and E joined by a hall, rooms on both.

    Rooms are 5 m x 4 m, kinds cycle through the vocabulary's classes (circulation
    kinds aside), each signed with the kind's first phrase plus a number when the
    kind has a pattern, so several rooms share kinds as on a real floor.
    """
    voc = load_vocabulary()
    kinds = [e for e in voc.entries if e.is_a != "Circulation" and e.phrases]
    kb = KnowledgeBase()
    kb.add_place("W", "Corridor", name="WEST CORRIDOR", polygon=_box(0, 4, 60, 6))
    kb.add_place("E", "Corridor", name="EAST CORRIDOR", polygon=_box(65, 4, 125, 6))
    kb.add_place("H", "Hall", name="HALL", polygon=_box(60, 0, 65, 10))
    kb.add_door("dWH", "W", "H", x=60.0, y=5.0, width=2.0)
    kb.add_door("dHE", "H", "E", x=65.0, y=5.0, width=2.0)
    people, slots = [], []
    for i in range(places - 3):
        entry = kinds[i % len(kinds)]
        corridor, x0 = ("W", 5.0 * (i // 2 % 12)) if i < 24 else ("E", 65 + 5.0 * (i // 2 % 12))
        y0 = 0.0 if i % 2 == 0 else 6.0
        pid = f"R{i}"
        kb.add_place(pid, None, polygon=_box(x0, y0, x0 + 5.0, y0 + 4.0))
        kb.add_door(f"d{i}", pid, corridor, x=x0 + 2.5, y=4.0 if y0 == 0 else 6.0, width=1.0)
        text = entry.patterns[0].fill(str(100 + i)) if entry.patterns else entry.phrases[0]
        if not entry.patterns and i >= len(kinds):
            text = entry.phrases[min(1, len(entry.phrases) - 1)]
        kb.add_sign(f"s{i}", text, x=x0 + 2.0, y=4.1 if y0 == 0 else 5.9,
                    facing_deg=90.0 if y0 == 0 else -90.0, place_id=pid)
        if i % 3 == 0:
            kb.add_object(f"o{i}", OBJECTS[i // 3 % len(OBJECTS)], x=x0 + 1.0, y=y0 + 1.0)
        if i % 5 == 0 and len(people) < 10:
            name = f"Person {len(people)}"
            people.append(Person(name, ["Teacher", "Manager", "Nurse", "Researcher",
                                        "Technician"][len(people) % 5], None))
            slots.append(Slot(name, text, ("mon", "wed"), _t(9), _t(11)))
    kb.add_timetable(Timetable(people, slots))
    return kb


def _box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
    return np.array([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], float)


def _t(hour: int):
    import datetime as dt
    return dt.time(hour)


def time_kb(make, repeats: int) -> tuple[dict, KnowledgeBase]:
    """Median full and per-sign reasoning times (total, OWL, rules) of the KB ``make()``
    builds, and the last KB built."""
    full, sign = [], []
    for r in range(repeats):
        kb = make()
        full.append(kb.reason())
        kb.add_sign(f"new_sign_{r}", "KITCHEN", x=0.0, y=0.0, facing_deg=0.0,
                    place_id=next(iter(sorted(kb.place_graph().nodes))))
        sign.append(kb.reason())

    def med(stats, attr):
        return round(statistics.median(getattr(s, attr) for s in stats), 2)
    return {"places": len(kb.place_graph().nodes),
            "triples_before": full[-1].triples_before, "triples_after": full[-1].triples_after,
            "full_ms": med(full, "ms_total"), "full_owl_ms": med(full, "ms_owl"),
            "full_rules_ms": med(full, "ms_rules"),
            "per_sign_ms": med(sign, "ms_total"), "per_sign_owl_ms": med(sign, "ms_owl"),
            "per_sign_rules_ms": med(sign, "ms_rules"),
            "per_sign_incremental": all(s.incremental for s in sign)}, kb


def owlrl_ms(kb: KnowledgeBase) -> tuple[float, int]:
    """Wall time of owlrl's OWL 2 RL closure of what ``reasonable`` was given (run once)."""
    import owlrl
    import rdflib
    g = rdflib.Graph()
    for t in kb._reasoner_input:
        g.add(t)
    t0 = time.perf_counter()
    owlrl.DeductiveClosure(owlrl.OWLRL_Semantics).expand(g)
    return (time.perf_counter() - t0) * 1e3, len(g)


def reasonable_owl_ms(kb: KnowledgeBase, repeats: int) -> float:
    """Median wall time of ``reasonable`` from scratch on the same input (load + reason)."""
    import reasonable
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        r = reasonable.PyReasoner()
        r.from_graph(list(kb._reasoner_input))
        r.reason()
        times.append((time.perf_counter() - t0) * 1e3)
    return statistics.median(times)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="1 repeat, no owlrl (a smoke test)")
    parser.add_argument("--repeats", type=int, default=None, help="default 7 (1 with --quick)")
    parser.add_argument("--places", type=int, default=50)
    parser.add_argument("--no-owlrl", action="store_true", help="skip the owlrl reference")
    parser.add_argument("--json", type=Path, default=RESULTS_JSON)
    args = parser.parse_args(argv)
    repeats = args.repeats if args.repeats is not None else (1 if args.quick else 7)
    office, _ = time_kb(office_kb, repeats)
    floor, kb = time_kb(lambda: synthetic_kb(args.places), repeats)
    print(f"semmap knowledge base reasoning (reasonable OWL 2 RL + domain rules), "
          f"median of {repeats}")
    results = {"repeats": repeats, "office": office, "floor": floor,
               "per_sign_target_ms": PER_SIGN_TARGET_MS}
    if not (args.quick or args.no_owlrl):
        ref_ms, ref_triples = owlrl_ms(kb)
        ours_ms = reasonable_owl_ms(kb, repeats)
        results.update(owlrl_ms=round(ref_ms, 1), owlrl_triples=ref_triples,
                       reasonable_ms=round(ours_ms, 2),
                       owlrl_x_reasonable=round(ref_ms / ours_ms, 1))
        print(f"reference: owlrl OWL 2 RL closure of the {floor['places']}-place floor: "
              f"{ref_ms:.0f} ms (once), reasonable on the same triples {ours_ms:.1f} ms "
              f"-> {ref_ms / ours_ms:.0f}x faster\n")
    else:
        print("reference: owlrl skipped\n")
    print("(medians of the total, the OWL pass and the rules, each taken separately)")
    print(f"{'knowledge base':>22} {'places':>6} {'triples':>15} {'full ms':>8} "
          f"{'(owl+rules)':>13} {'per sign ms':>11} {'(owl+rules)':>13}")
    for name, r in (("office world", office), (f"synthetic {args.places}-place", floor)):
        print(f"{name:>22} {r['places']:6d} {r['triples_before']:6d}->{r['triples_after']:<7d} "
              f"{r['full_ms']:8.1f} {r['full_owl_ms']:6.1f}+{r['full_rules_ms']:<6.1f} "
              f"{r['per_sign_ms']:11.1f} {r['per_sign_owl_ms']:6.1f}+{r['per_sign_rules_ms']:<6.1f}")
    ok = floor["per_sign_ms"] <= PER_SIGN_TARGET_MS
    print(f"\n{'PASS' if ok else 'MISS'} re-reasoning per new sign, {floor['places']}-place floor: "
          f"{floor['per_sign_ms']:.1f} ms (target <= {PER_SIGN_TARGET_MS:.0f} ms)")
    write_results(args.json, results)
    return 0 if (ok or args.quick) else 1


if __name__ == "__main__":
    sys.exit(main())
