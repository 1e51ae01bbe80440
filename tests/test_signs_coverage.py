"""Which signs a run passed close enough to read: the denominator of the sign scores."""
from __future__ import annotations

import math

import numpy as np

from blocks.signs.coverage import signs_along_path
from sim2d.world import Sign, make_world


def world():
    walls = [[-1.0, 0.0, 20.0, 0.0], [-1.0, 2.0, 20.0, 2.0],   # a corridor
             [-1.0, 4.0, 20.0, 4.0]]                            # a second one beyond a wall
    signs = [Sign("NEAR", 5.0, 0.05, math.pi / 2),              # faces the corridor
             Sign("BEHIND WALL", 5.0, 2.05, math.pi / 2),       # faces the other corridor
             Sign("FAR AHEAD", 18.0, 0.05, math.pi / 2)]        # beyond the path's end
    return make_world(walls, start=(0.0, 1.0, 0.0), signs=signs)


def test_a_passed_sign_counts_and_hidden_or_unreached_ones_do_not():
    path = np.column_stack([np.linspace(0.0, 10.0, 200), np.full(200, 1.0), np.zeros(200)])
    found = [s.text for s in signs_along_path(world(), path)]
    assert found == ["NEAR"]


def test_a_sign_only_seen_edge_on_does_not_count():
    # the path stays 6+ m along the wall from the plate: never within 3 m
    path = np.column_stack([np.linspace(10.0, 12.0, 50), np.full(50, 1.0), np.zeros(50)])
    assert signs_along_path(world(), path) == []
    # within range, but only at a grazing angle (> 60 degrees off the normal)
    path = np.column_stack([np.linspace(7.0, 7.5, 20), np.full(20, 0.6), np.zeros(20)])
    assert signs_along_path(world(), path, max_view_deg=60.0) == []
    assert [s.text for s in signs_along_path(world(), path, max_view_deg=80.0)] == ["NEAR"]
