"""What a run's sonar could have seen: the yardstick for map coverage and recall.

A sonar reports the nearest surface anywhere in its 30-degree cone, so it
sees into a room through a door only when the whole cone fits through the
doorway; a line-of-sight test from the path would count rooms the sonar never
sampled.  Here every reading of the run is replayed on the true floor plan
with an ideal sonar (no noise, no specular loss): the cells inside each cone
up to the true nearest surface, plus the surface cells at that range, are
what the run could see.  A map cannot be blamed for cells outside that set.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from .cones import cone_extents, cone_spans, cone_tables
from .mapio import occupancy_map_from_world
from .sectors import Beams, sum_beams

if TYPE_CHECKING:
    from sim2d.world import World

__all__ = ["sonar_visible"]


def sonar_visible(world: World, sensors: np.ndarray, cone_deg: float = 30.0,
                  max_range: float = 4.0, chunk: int = 256) -> np.ndarray:
    """The cells of the world's grid that an ideal sonar at ``sensors`` would sweep.

    Parameters
    ----------
    world
        The world (its wall capsules give the true ranges).
    sensors
        (M, 3) true sensor poses x, y, heading in the world frame.
    cone_deg, max_range
        The sonar's cone angle (deg) and maximum range (m).
    chunk
        Sensors whose true ranges are found at once, against the wall capsules
        near them (:func:`sim2d.sonar.cone_ranges_near`): the cone geometry
        holds some twenty (sensors, capsules) float64 temporaries at a time,
        at most ~11 MB for 256 sensors against 250 capsules (~175 MB for 4096).

    Returns
    -------
    (H, W) bool array
        On the grid of :func:`blocks.maps.mapio.occupancy_map_from_world`
        (rows y up): True where some cone reached, up to and including the
        surface it would echo from.
    """
    from sim2d.sonar import cone_ranges_near

    truth = occupancy_map_from_world(world)
    res = float(truth.resolution)
    shape = truth.occupancy.shape
    sensors = np.asarray(sensors, dtype=np.float64).reshape(-1, 3)
    ranges = cone_ranges_near(sensors, world.segments, math.radians(cone_deg) / 2, max_range,
                              chunk)
    ranges = np.minimum(ranges, max_range)
    reach = int(math.ceil(max_range / res)) + 2
    pad = reach + 1
    padded = (shape[0] + 2 * pad, shape[1] + 2 * pad)
    ix = np.floor((sensors[:, 0] - truth.origin[0]) / res).astype(np.int64) + pad
    iy = np.floor((sensors[:, 1] - truth.origin[1]) / res).astype(np.int64) + pad
    degrees = np.round(np.degrees(sensors[:, 2])).astype(np.int64) % 360
    limit = np.floor(2 * (ranges / res + 1.0)).astype(np.int64)  # one cell beyond: the surface
    # a sensor whose cone would leave the padded grid is off the floor plan: it sees none of it
    rows, cols = cone_extents(cone_tables(res, cone_deg, reach), degrees, limit // 2 + 1)
    index = np.flatnonzero((iy + rows[0] >= 0) & (ix + cols[0] >= 0)
                           & (iy + rows[1] <= padded[0]) & (ix + cols[1] <= padded[1]))
    # each cone's cells up to its limit, counted as row runs (exact in any order),
    # 16 * chunk cones at a time (some 100 runs each, of 32 bytes)
    spans = cone_spans(res, cone_deg, reach)
    seen = np.zeros(padded, dtype=bool)
    for start in range(0, len(index), 16 * chunk):
        part = index[start:start + 16 * chunk]
        n = len(part)
        cones = Beams(iy[part], ix[part], degrees[part], limit[part] + 1, np.zeros(n, np.int64),
                      np.full(n, -1, np.int64), np.ones(n), np.zeros(n))
        seen |= sum_beams(spans, cones, (0, 0), padded) > 0
    return seen[pad:pad + shape[0], pad:pad + shape[1]]
