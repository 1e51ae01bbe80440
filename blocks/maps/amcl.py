"""Monte Carlo localisation on a known map with the sonar ring (ROS ``amcl``'s method).

Driving a plan on a map needs the robot's pose *in that map*. Odometry starts
in the map's frame but drifts (a few centimetres per metre, and heading
errors that grow sideways error with every metre after them). A particle
filter corrects it with what the sonar hears, as ``amcl`` does with a laser
(Thrun, Burgard and Fox, *Probabilistic Robotics*, ch. 8; Fox et al. 1999):

- **Motion**: each particle moves by the odometry's step since the last
  update, as a first turn, a straight move and a second turn, each with
  Gaussian noise that grows with the step (the odometry motion model,
  table 5.6; ``amcl``'s ``diff`` model with its ``odom_alpha1..4``).
- **Sensing**: each particle's 16 sonars are placed on the map and the range
  each should read is computed with the simulator's own ranger model
  (:func:`sim2d.sonar.cone_ranges`: the nearest wall inside the 30-degree
  cone, and its incidence) on the map's walls traced the way the
  simulator traces a world image (:func:`sim2d.world.segments_from_occupancy`).
  A reading is scored against the expected range with the beam model's
  mixture (a Gaussian hit, short readings from things the map lacks, random
  readings); a silent sonar is scored by whether the map says it should have
  heard a wall (square enough to echo) there. The sum of the beams'
  log-likelihoods is tempered (multiplied by ``temper`` < 1), because the
  beams of one ring are far from independent and the raw product makes the
  cloud collapse onto a wrong pose.
- **Resampling**: low-variance resampling, whenever the effective sample
  size falls below half the particles, or fewer particles would do.
- **How many particles** (KLD sampling, Fox 2003, as ``amcl`` does): the
  cloud is binned (0.5 m, 0.5 m, 10 degrees) and a resampled cloud that
  falls in ``k`` bins gets the particles that bound the error of its
  histogram (Kullback-Leibler divergence ``kld_err`` with quantile
  ``kld_z``), between ``min_particles`` and ``particles``. A converged cloud
  needs far fewer than a spread one, and an update costs in proportion.

Updates happen only after the robot has moved ``update_min_d`` or turned
``update_min_a`` (``amcl`` defaults: 0.2 m, pi/6); in between, the estimate
follows the odometry, so the output is smooth.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from blocks.signs.geometry import compose, relative
from sim2d.sonar import cone_ranges, nearest_in_cone
from sim2d.world import segments_from_occupancy

from .features import sensor_poses_along
from .mapio import OccupancyMap

__all__ = ["AMCLParams", "MonteCarloLocaliser", "kld_resample", "kld_sample_limit",
           "low_variance_resample", "map_walls", "occupied_bins", "sample_odometry_motion",
           "walls_in_reach"]


@dataclass(frozen=True)
class AMCLParams:
    """Parameters of :class:`MonteCarloLocaliser` (``amcl``'s names where it has them).

    Attributes
    ----------
    particles
        Number of particles at the start, and the most there may be
        (``amcl``'s ``max_particles``).
    min_particles
        The fewest there may be (set it to ``particles`` for a fixed number).
    kld_err, kld_z
        KLD sampling's bound on the error of the cloud's histogram, and the
        standard normal quantile of its confidence (``amcl``'s names and
        defaults; ``amcl`` uses ``kld_z`` as the quantile itself).
    kld_bin
        Bin size (m, m, rad) of that histogram (``amcl``'s kd-tree cells).
    odom_alpha
        Motion noise (``odom_alpha1..4``): rotation from rotation, rotation
        from translation (rad per m), translation from translation,
        translation from rotation (m per rad).
    update_min_d, update_min_a
        Update the filter only after this much translation (m) or rotation (rad).
    initial_std
        Spread (m, m, rad) of the particles round the initial pose.
    sigma_hit
        Standard deviation (m) of a reading about the expected range: the
        sonar's noise plus the map's own error.
    z_hit, z_short, z_rand
        Mixture weights of a hit, a short reading (something the map lacks)
        and a random reading.
    lambda_short
        Rate (1/m) of the short readings' exponential.
    p_silent_wall
        Chance that a sonar facing a wall it should hear (square enough to
        echo, within range) reads nothing: missed echoes, walls the map has
        wrong.
    temper
        Each update's log-likelihood is multiplied by this: the sixteen beams
        of a ring are correlated (a wrong map edge fools several), and the raw
        product would trust them as sixteen independent witnesses.
    """

    particles: int = 300
    min_particles: int = 100
    kld_err: float = 0.01
    kld_z: float = 0.99
    kld_bin: tuple[float, float, float] = (0.5, 0.5, math.radians(10.0))
    odom_alpha: tuple[float, float, float, float] = (0.2, 0.05, 0.1, 0.05)
    update_min_d: float = 0.2
    update_min_a: float = math.pi / 6
    initial_std: tuple[float, float, float] = (0.1, 0.1, 0.05)
    sigma_hit: float = 0.15
    z_hit: float = 0.8
    z_short: float = 0.1
    z_rand: float = 0.1
    lambda_short: float = 1.0
    p_silent_wall: float = 0.2
    temper: float = 0.3


def map_walls(m: OccupancyMap) -> np.ndarray:
    """The map's occupied cells as wall capsules (S, 5), as the simulator traces a world image.

    ``m`` is indexed ``[iy, ix]`` with row 0 at the lowest y; the tracer
    takes image order (row 0 at the top), hence the flip.
    """
    occupied, _, _ = m.classes()
    return segments_from_occupancy(occupied[::-1], m.resolution, m.origin)


def walls_in_reach(sensors: np.ndarray, walls: np.ndarray, half_cone: float,
                   max_range: float) -> list[np.ndarray]:
    """For each sonar k of ``sensors`` (P, K, 3), the walls one of its P cones could meet.

    All P cones of one sonar lie inside one wider cone: half-angle
    ``half_cone`` plus the largest heading deviation from their mean, its apex
    moved back until every sensor's position is inside it, its range
    lengthened by as much. A wall outside that cone is outside every one of
    the P cones, so dropping it changes no range. Headings spread too far for
    such a cone keep every wall.
    """
    heading = np.arctan2(np.sin(sensors[..., 2]).mean(axis=0),
                         np.cos(sensors[..., 2]).mean(axis=0))  # (K,)
    deviation = np.abs(_wrap(sensors[..., 2] - heading)).max(axis=0)
    half = half_cone + float(deviation.max())  # one angle for all K: one numpy call
    if half >= math.radians(80) or not len(walls):
        return [walls] * len(heading)
    centre = sensors[..., :2].mean(axis=0)  # (K, 2)
    radius = np.hypot(*np.moveaxis(sensors[..., :2] - centre, -1, 0)).max(axis=0)
    back = radius / math.sin(half) + 1e-6
    c, s = np.cos(heading)[:, None], np.sin(heading)[:, None]
    dist = nearest_in_cone(centre[:, 0:1] - back[:, None] * c, centre[:, 1:2] - back[:, None] * s,
                           c, s, walls[None, :, :], half)[0]  # (K, S)
    keep = dist <= (max_range + back + radius)[:, None]
    return [walls[row] for row in keep]


_UNREACHABLE = np.array([1e9, 1e9, 1e9, 1e9, 0.0])  # a capsule beyond every sonar's range


def _wrap(angle: np.ndarray | float) -> np.ndarray | float:
    return (np.asarray(angle) + np.pi) % (2 * np.pi) - np.pi


def sample_odometry_motion(particles: np.ndarray, before: np.ndarray, after: np.ndarray,
                           alpha: tuple[float, float, float, float],
                           rng: np.random.Generator) -> np.ndarray:
    """Move every particle by the odometry's step ``before -> after``, with noise.

    Probabilistic Robotics, table 5.6: the step is a turn, a straight move and
    a turn; each gets Gaussian noise whose standard deviation is
    ``alpha1 |rot| + alpha2 trans`` (the turns) or ``alpha3 trans + alpha4
    (|rot1| + |rot2|)`` (the move). A step shorter than 1 cm has no direction
    of its own, so its first turn is taken as zero (as ``amcl`` does).

    Parameters
    ----------
    particles
        (P, 3) poses ``x, y, theta`` in the map frame.
    before, after
        Odometry poses (3,) at the last update and now.
    alpha
        ``(alpha1, alpha2, alpha3, alpha4)``.
    rng
        The noise's generator.

    Returns
    -------
    (P, 3) array
        The moved particles.
    """
    dx, dy = float(after[0] - before[0]), float(after[1] - before[1])
    trans = math.hypot(dx, dy)
    rot1 = float(_wrap(math.atan2(dy, dx) - before[2])) if trans >= 0.01 else 0.0
    if abs(rot1) > math.pi / 2 and trans >= 0.01:  # driving backwards: a back step, not a U-turn
        rot1 = float(_wrap(rot1 + math.pi))
        trans = -trans
    rot2 = float(_wrap(after[2] - before[2] - rot1))
    a1, a2, a3, a4 = alpha
    n = len(particles)
    r1 = rot1 + rng.normal(0.0, a1 * abs(rot1) + a2 * abs(trans) + 1e-9, n)
    t = trans + rng.normal(0.0, a3 * abs(trans) + a4 * (abs(rot1) + abs(rot2)) + 1e-9, n)
    r2 = rot2 + rng.normal(0.0, a1 * abs(rot2) + a2 * abs(trans) + 1e-9, n)
    heading = particles[:, 2] + r1
    out = np.empty_like(particles)
    out[:, 0] = particles[:, 0] + t * np.cos(heading)
    out[:, 1] = particles[:, 1] + t * np.sin(heading)
    out[:, 2] = _wrap(heading + r2)
    return out


def low_variance_resample(weights: np.ndarray, rng: np.random.Generator,
                          count: int | None = None) -> np.ndarray:
    """``count`` (default: as many as weights) indices drawn in proportion to ``weights``
    with one random offset (table 4.4).

    One draw instead of P keeps the particles' variety when the weights are
    even, and costs O(P).
    """
    n = len(weights) if count is None else int(count)
    cumulative = np.cumsum(weights / weights.sum())
    cumulative[-1] = 1.0
    points = (rng.uniform(0.0, 1.0 / n) + np.arange(n) / n)
    return np.searchsorted(cumulative, points, side="left")


def kld_sample_limit(bins: int, err: float, z: float, low: int, high: int) -> int:
    """Particles needed for a cloud in ``bins`` histogram bins (Fox 2003, eq. 13).

    The Wilson-Hilferty approximation of the chi-square quantile bounds, with
    quantile ``z``, the Kullback-Leibler divergence ``err`` between the
    cloud's histogram and the true one. One bin needs no more than ``low``
    (where ``amcl`` takes ``high``: a cloud inside one bin is already as
    exact as the histogram can tell). Clipped to ``[low, high]``.
    """
    if bins <= 1:
        return low
    b = 2.0 / (9.0 * (bins - 1))
    n = math.ceil((bins - 1) / (2.0 * err) * (1.0 - b + math.sqrt(b) * z) ** 3)
    return int(min(max(n, low), high))


def occupied_bins(particles: np.ndarray, size: tuple[float, float, float]) -> np.ndarray:
    """The histogram bin key of each particle (P,): equal keys share a bin."""
    cells = np.floor(particles / np.asarray(size)).astype(np.int64)
    cells[:, 2] = np.floor(_wrap(particles[:, 2]) / size[2]).astype(np.int64)
    cells -= cells.min(axis=0)
    flat = np.ravel_multi_index(cells.T, tuple(cells.max(axis=0) + 1))
    return np.unique(flat, return_inverse=True)[1].ravel()


def kld_resample(particles: np.ndarray, weights: np.ndarray, params: AMCLParams,
                 rng: np.random.Generator) -> np.ndarray:
    """Indices of a resampled cloud whose size KLD sampling chooses.

    Up to ``params.particles`` are drawn (low variance, then shuffled so that
    every prefix is a fair sample) and kept until their number reaches the
    limit for the bins they fill so far (``amcl``'s ``pf_update_resample``).
    """
    p = params
    draws = rng.permutation(low_variance_resample(weights, rng, p.particles))
    keys = occupied_bins(particles[draws], p.kld_bin)
    first = np.zeros(len(keys), dtype=bool)
    first[np.unique(keys, return_index=True)[1]] = True
    bins = np.cumsum(first)  # bins filled by the first m + 1 draws
    limits = np.array([kld_sample_limit(k, p.kld_err, p.kld_z, p.min_particles, p.particles)
                       for k in range(int(bins[-1]) + 1)])
    needed = limits[bins]
    enough = np.flatnonzero(np.arange(1, len(draws) + 1) >= needed)
    return draws[:int(enough[0]) + 1] if len(enough) else draws


class MonteCarloLocaliser:
    """A particle filter localising the sonar robot on ``walls`` (see the module docstring).

    Parameters
    ----------
    walls
        (S, 5) wall capsules of the map (:func:`map_walls`).
    mounts
        (16, 3) sonar mounts ``x, y, theta`` in the robot frame.
    cone_deg, max_range, specular_deg
        The sonar's cone, range and the incidence above which an echo is lost
        (the robot file's ``sonar`` section: its calibration).
    start
        The pose (map frame) the robot starts at.
    params
        :class:`AMCLParams`.
    rng
        The filter's random generator, or a seed for one (runs are deterministic per seed).
    """

    def __init__(self, walls: np.ndarray, mounts: np.ndarray, *, cone_deg: float,
                 max_range: float, specular_deg: float | None, start: np.ndarray,
                 params: AMCLParams = AMCLParams(),
                 rng: np.random.Generator | int = 0) -> None:
        self.walls = np.asarray(walls, dtype=np.float64).reshape(-1, 5)
        self.mounts = np.asarray(mounts, dtype=np.float64)
        self.half_cone = math.radians(cone_deg) / 2
        self.max_range = float(max_range)
        self.specular = math.radians(specular_deg) if specular_deg is not None else math.inf
        self.params = params
        self.rng = rng if isinstance(rng, np.random.Generator) else np.random.default_rng(rng)
        start = np.asarray(start, dtype=np.float64)[:3]
        self.particles = start + self.rng.normal(0.0, 1.0, (params.particles, 3)) \
            * np.asarray(params.initial_std)
        self.particles[:, 2] = _wrap(self.particles[:, 2])
        self.weights = np.full(params.particles, 1.0 / params.particles)
        self._odom_at_update: np.ndarray | None = None
        self._estimate = start.copy()
        self._correction = np.zeros(3)  # map pose = correction (+) odometry pose
        self.updates = 0
        self.resamples = 0
        self.particle_counts: list[int] = []  # the cloud's size after each update
        self.spread_m = self.spread()  # kept with the cloud: it changes only on updates

    # ---- the filter ---------------------------------------------------------------------
    def step(self, odometry: np.ndarray, ranges: np.ndarray, echo: np.ndarray) -> np.ndarray:
        """Take the odometry pose and one sonar reading; return the pose in the map frame."""
        odometry = np.asarray(odometry, dtype=np.float64)[:3]
        if self._odom_at_update is None:
            self._odom_at_update = odometry.copy()
            self._correction = _between(odometry, self._estimate)
        before = self._odom_at_update
        moved = math.hypot(*(odometry[:2] - before[:2]))
        turned = abs(float(_wrap(odometry[2] - before[2])))
        p = self.params
        if moved >= p.update_min_d or turned >= p.update_min_a:
            self.particles = sample_odometry_motion(self.particles, before, odometry,
                                                    p.odom_alpha, self.rng)
            self._weigh(np.asarray(ranges, dtype=np.float64), np.asarray(echo, dtype=bool))
            self._odom_at_update = odometry.copy()
            self._estimate = self.mean()
            self._correction = _between(odometry, self._estimate)
            self.updates += 1
            self.particle_counts.append(len(self.particles))
            self.spread_m = self.spread()
        return np.array(compose(self._correction, odometry))

    def expected_ranges(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """What each pose's sonars should read on the map: ranges and incidence, (P, 16) each.

        One sonar across all the particles points about one way from about one
        place, so the walls none of its cones can reach are dropped first
        (:func:`walls_in_reach`): the same ranges, at a third of the cost.
        """
        sensors = sensor_poses_along(poses, self.mounts)  # (P, 16, 3)
        reach = walls_in_reach(sensors, self.walls, self.half_cone, self.max_range)
        # one numpy pass for all sixteen: each sonar's walls, padded with capsules too far
        # to reach, which no cone can choose over a wall in range
        stacked = np.empty((len(reach), max(1, max(len(w) for w in reach)), 5))
        stacked[:] = _UNREACHABLE
        for k, walls in enumerate(reach):
            stacked[k, :len(walls)] = walls
        ranges, incidence = cone_ranges(np.swapaxes(sensors, 0, 1), stacked, self.half_cone,
                                        self.max_range)
        return ranges.T, incidence.T

    def log_likelihood(self, poses: np.ndarray, ranges: np.ndarray,
                       echo: np.ndarray) -> np.ndarray:
        """The beam model's log-likelihood (P,) of one reading at each pose (untempered)."""
        p = self.params
        expected, incidence = self.expected_ranges(poses)
        heard = np.isfinite(expected) & ~(incidence > self.specular)  # the map says: an echo
        z = ranges[None, :]
        gauss = np.exp(-0.5 * ((z - expected) / p.sigma_hit) ** 2) \
            / (p.sigma_hit * math.sqrt(2 * math.pi))
        short = np.where(np.isfinite(expected) & (z <= expected),
                         p.lambda_short * np.exp(-p.lambda_short * z), 0.0)
        rand = 1.0 / self.max_range
        on_echo = np.where(heard, p.z_hit * gauss + p.z_short * short + p.z_rand * rand,
                           p.z_short * short + p.z_rand * rand)
        on_silence = np.where(heard, p.p_silent_wall, 1.0 - p.p_silent_wall)
        likelihood = np.where(echo[None, :], on_echo, on_silence)
        return np.log(np.maximum(likelihood, 1e-12)).sum(axis=1)

    def _weigh(self, ranges: np.ndarray, echo: np.ndarray) -> None:
        p = self.params
        log_w = np.log(self.weights) + p.temper * self.log_likelihood(self.particles, ranges,
                                                                      echo)
        log_w -= log_w.max()
        w = np.exp(log_w)
        self.weights = w / w.sum()
        n = len(self.weights)
        if 1.0 / float(np.sum(self.weights ** 2)) < n / 2 or self._fewer_would_do():
            keep = kld_resample(self.particles, self.weights, p, self.rng)
            self.particles = self.particles[keep]
            self.weights = np.full(len(keep), 1.0 / len(keep))
            self.resamples += 1

    def _fewer_would_do(self) -> bool:
        """Whether KLD sampling asks for fewer particles than the cloud has."""
        p = self.params
        if p.min_particles >= len(self.particles):
            return False
        bins = int(occupied_bins(self.particles, p.kld_bin).max()) + 1
        return kld_sample_limit(bins, p.kld_err, p.kld_z, p.min_particles,
                                p.particles) < len(self.particles)

    # ---- the estimate -------------------------------------------------------------------
    def mean(self) -> np.ndarray:
        """The weighted mean pose (circular mean for the heading)."""
        w = self.weights
        theta = math.atan2(float(w @ np.sin(self.particles[:, 2])),
                           float(w @ np.cos(self.particles[:, 2])))
        return np.array([float(w @ self.particles[:, 0]), float(w @ self.particles[:, 1]), theta])

    def spread(self) -> float:
        """The cloud's position standard deviation (m): the root of the covariance's trace."""
        d = self.particles[:, :2] - self.mean()[:2]
        return float(math.sqrt(float(self.weights @ (d ** 2).sum(axis=1))))


def _between(odometry: np.ndarray, estimate: np.ndarray) -> np.ndarray:
    """The correction ``T`` with ``T (+) odometry = estimate`` (``amcl``'s map -> odom)."""
    return np.array(compose(estimate, relative(odometry, (0.0, 0.0, 0.0))))
