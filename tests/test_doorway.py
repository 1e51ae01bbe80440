"""Doorways on a planned way: found between two jambs, at any wall angle, and the
points to line up in front of them and to leave by."""
from __future__ import annotations

import math

import numpy as np
import pytest

from blocks.navigate.doorway import doorway_legs, find_doorway
from blocks.navigate.grid import inflate_occupied

RES = 0.05


def slanted_wall(angle_deg: float, door: float, thickness: float = 0.1
                 ) -> tuple[np.ndarray, tuple[float, float], np.ndarray]:
    """Wall cells of a straight wall through (3, 3) at ``angle_deg``, with a door ``door``
    wide centred there; also the wall's unit normal."""
    n = int(6 / RES)
    y, x = np.mgrid[0:n, 0:n]
    xc, yc = (x + 0.5) * RES, (y + 0.5) * RES
    t = math.radians(angle_deg)
    along = (xc - 3) * math.cos(t) + (yc - 3) * math.sin(t)
    across = -(xc - 3) * math.sin(t) + (yc - 3) * math.cos(t)
    walls = (np.abs(across) <= thickness / 2) & (np.abs(along) > door / 2)
    return walls, (3.0, 3.0), np.array([-math.sin(t), math.cos(t)])


@pytest.mark.parametrize("angle", [0.0, 30.0, 63.0])
@pytest.mark.parametrize("slant", [-35.0, 0.0, 40.0])
def test_the_doorway_is_square_to_its_wall_whatever_the_way_and_the_wall(angle, slant):
    walls, centre, normal = slanted_wall(angle, door=0.9)
    heading = math.atan2(normal[1], normal[0]) + math.radians(slant)
    through = np.array([math.cos(heading), math.sin(heading)])
    way = np.array([np.array(centre) - 2.0 * through, np.array(centre) + 2.0 * through])
    door = find_doorway(walls, RES, (0.0, 0.0), way)
    assert door is not None
    assert np.hypot(*(np.array(door.centre) - centre)) < 0.06
    # within a cell across the door (3 degrees at 0.05 m) either side
    assert np.degrees(math.acos(min(1.0, abs(np.dot(door.axis, normal))))) < 6.5
    assert np.dot(door.axis, through) > 0  # pointing the way the way goes
    assert door.width == pytest.approx(0.9 + RES, abs=2 * RES)  # jamb cell to jamb cell


def test_a_corridor_wider_than_narrow_is_no_doorway_and_one_wall_is_no_doorway():
    walls = np.zeros((120, 120), dtype=bool)
    walls[40, :] = walls[70, :] = True  # a corridor 1.5 m wide along x
    way = np.array([[0.5, 2.8], [5.5, 2.8]])
    assert find_doorway(walls, RES, (0.0, 0.0), way) is None
    walls[70, :] = False  # the way runs 0.35 m from a single wall
    assert find_doorway(walls, RES, (0.0, 0.0), np.array([[0.5, 2.4], [5.5, 2.4]])) is None


@pytest.mark.parametrize("start", [(2.0, 0.4), (3.5, 0.4), (4.2, 0.5)])
def test_a_way_leaving_a_wall_slantwise_past_a_corner_is_no_doorway(start):
    """Near one wall, a way that leaves it at a slant has wall cells on both sides of its
    line (behind on one, ahead on the other) and a room's corner beside it; the robot
    stands in no doorway, and it would wait to line up with a door that is not there."""
    walls = np.zeros((100, 100), dtype=bool)
    y, x = np.mgrid[0:100, 0:100]
    xc, yc = (x + 0.5) * RES, (y + 0.5) * RES
    walls[(yc < 0.1) & (xc < 4.6)] = True  # the room's south wall
    walls[(xc > 4.5) & (xc < 4.6) & (yc < 4.0)] = True  # its east wall: a corner at (4.6, 0)
    way = np.array([start, (4.0, 2.0), (4.0, 4.5)])
    assert find_doorway(walls, RES, (0.0, 0.0), way, narrow=0.45) is None
    if start[0] > 3.0:  # any wall cells on both sides will do: a doorway at the corner
        assert find_doorway(walls, RES, (0.0, 0.0), way, narrow=0.45, straddle=False)


def test_the_points_to_line_up_at_and_to_leave_by_lie_on_the_axis_where_the_robot_fits():
    walls, centre, normal = slanted_wall(30.0, door=0.9)
    way = np.array([np.array(centre) - 2.0 * normal, np.array(centre) + 2.0 * normal])
    door = find_doorway(walls, RES, (0.0, 0.0), way)
    grid = inflate_occupied(walls, RES, (0.0, 0.0), radius=0.2)
    before, after = doorway_legs(grid, door, approach=0.7, leave=0.6)
    axis = np.array(door.axis)
    assert np.dot(np.array(door.centre) - before, axis) == pytest.approx(0.7, abs=1e-6)
    assert np.dot(after - np.array(door.centre), axis) == pytest.approx(0.6, abs=1e-6)
    # with a wall 0.5 m in front of the door there is no room to line up 0.7 m out
    blocked = walls.copy()
    front = np.array(door.centre) - 0.55 * axis
    r, c = int(front[1] / RES), int(front[0] / RES)
    blocked[r - 12:r + 13, c - 12:c + 13] = True
    grid = inflate_occupied(blocked, RES, (0.0, 0.0), radius=0.2)
    short = doorway_legs(grid, door, approach=0.7, leave=0.6)
    assert short is None or np.dot(np.array(door.centre) - short[0], axis) < 0.4
