"""A room without a sign, in closed loop: the main pipeline visits it and its semantic map
holds it as an unnamed place of its own (issue 20: every open room, signed or not)."""
from __future__ import annotations

import json

import numpy as np
import pytest

from conftest import ROOT, floor_plan, write_world

ROOM = (2.45, 9.55, 2.45, 6.55)  # x0, x1, y0, y1 of the room's floor


def ring_round_an_unsigned_room(tmp_path):
    """A ring corridor 2.3 m wide (12 x 9 m outside) round a 7.1 x 4.1 m room whose only
    door (1 m) opens on the inner side of the south corridor.  No sign anywhere.  The
    follower keeps the outer wall on its right, so its loop never looks into the room."""
    xc, yc = floor_plan(12.0, 9.0)
    outer = (xc < 0) | (xc > 12) | (yc < 0) | (yc > 9)
    block = (xc > 2.3) & (xc < 9.7) & (yc > 2.3) & (yc < 6.7)
    x0, x1, y0, y1 = ROOM
    hollow = (xc > x0) & (xc < x1) & (yc > y0) & (yc < y1)
    door = (xc > 5.5) & (xc < 6.5) & (yc > 2.2) & (yc < 2.6)
    return write_world(tmp_path, "ring_room", outer | (block & ~hollow & ~door),
                       start=(1.2, 1.0, 0.0), doc="A ring corridor round a room with no sign.",
                       extra=f"""\
        signs: []
        places:
          - {{name: CORRIDOR, kind: Corridor, polygon: [[0, 0], [12, 0], [12, 9], [0, 9], [0, 0],
             [2.3, 2.3], [2.3, 6.7], [9.7, 6.7], [9.7, 2.3], [2.3, 2.3]]}}
          - {{name: room 1, kind: Office, polygon: [[{x0}, {y0}], [{x1}, {y0}], [{x1}, {y1}],
             [{x0}, {y1}]]}}
        doors:
          - {{x: 6.0, y: 2.375, width: 1.0, between: [CORRIDOR, room 1]}}
    """)


@pytest.mark.slow
@pytest.mark.parametrize("explore", [True, False])
def test_an_unsigned_room_is_visited_and_becomes_an_unnamed_place(cli, tmp_path, explore):
    """With frontier exploration the robot goes in once its loop has closed, and the room
    is a place of its own with no name (IoU against the true room at least 0.75).  The
    perimeter follower alone (the case that shows this test can fail) never enters it."""
    world = ring_round_an_unsigned_room(tmp_path)
    out = tmp_path / "run"
    steps = 3500 if explore else 1500
    result = cli("run", ROOT / "graphs" / "semantic_mapping.yaml", "--world", world,
                 "--out", out, "--quiet", "--steps", steps,
                 "--set", f"explore_frontiers={str(explore).lower()}")
    assert result.code == 0, result.err
    metrics = json.loads((out / "run.json").read_text())["metrics"]
    (room,) = metrics["knowledge"]["rooms_unsigned"]
    path = np.genfromtxt(out / "trajectory.csv", delimiter=",", names=True)
    x0, x1, y0, y1 = ROOM
    entered = bool(np.any((path["x"] > x0 + 0.5) & (path["x"] < x1 - 0.5)
                          & (path["y"] > y0 + 0.5) & (path["y"] < y1 - 0.5)))
    if explore:
        assert entered, metrics["explorer"]["log"]
        assert room["named_as"] is None and room["iou"] >= 0.75, room
        assert metrics["knowledge"]["rooms_unsigned_places"] == 1
        assert metrics["world"]["collisions"] == 0
    else:
        assert not entered
        assert room["iou"] < 0.1, room
