"""The camera's Gaussian pixel noise, and the same noise drawn a frame ahead on a thread.

A noise field is the costliest single step of a camera frame (about a fifth
of it) and the only one that needs nothing from the scene: one draw from the
camera's RNG fixes the whole field. ``NoiseAhead`` uses that to draw the next
frame's field on a worker thread while the robot's tick goes on, so the
second core does it; the fields are exactly the ones ``gaussian_noise`` gives.
That pays while a core is idle: with every core busy (``semmap sweep`` with
as many jobs as cores) the hand-overs cost more than they save, and
``SEMMAP_THREADS=0`` in the environment draws every field in turn instead.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor
from concurrent.futures import wait as wait_for

import cv2
import numpy as np

_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def gaussian_noise(shape: tuple[int, ...], std: float, rng: np.random.Generator,
                   out: np.ndarray | None = None) -> np.ndarray:
    """Gaussian noise, float32, drawn by OpenCV's (thread-local) RNG seeded from ``rng``
    (into ``out``, a C-contiguous float32 array of that shape, if given).

    Three times faster than numpy's normal sampler; one 31-bit draw from
    ``rng`` fixes the whole noise field, so the result is a deterministic
    function of ``rng``'s state.
    """
    return noise_from_seed(shape, std, draw_seed(rng), out)


def draw_seed(rng: np.random.Generator) -> int:
    """The one draw from ``rng`` that fixes a noise field."""
    return int(rng.integers(1, 2**31 - 1))


def noise_from_seed(shape: tuple[int, ...], std: float, seed: int,
                    out: np.ndarray | None = None) -> np.ndarray:
    """The noise field of one seed (into ``out`` if given).

    The field is drawn as one channel: OpenCV draws the same values in memory
    order for any number of channels with the same mean and deviation, and
    scales one channel twice as fast. OpenCV's RNG is per thread, so fields
    drawn on different threads do not disturb each other.
    """
    noise = np.empty(shape, dtype=np.float32) if out is None else out
    cv2.setRNGSeed(seed)
    cv2.randn(noise.reshape(len(noise), -1), 0.0, float(std))
    return noise


def threads_allowed() -> bool:
    """False when ``SEMMAP_THREADS=0``: no helper threads (every core is busy already)."""
    return os.environ.get("SEMMAP_THREADS", "1").strip() != "0"


def _pool() -> ThreadPoolExecutor:
    """One worker thread shared by every camera in the process (made when first needed)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="semmap-noise")
        return _POOL


def _after_fork_in_child() -> None:
    """A forked child has none of its parent's threads: it makes its own worker (and lock)
    when it needs one; fields its parent was drawing are drawn again (see ``NoiseAhead``)."""
    global _POOL, _POOL_LOCK
    _POOL, _POOL_LOCK = None, threading.Lock()


os.register_at_fork(after_in_child=_after_fork_in_child)


class NoiseAhead:
    """Noise fields from ``rng``, each drawn on a worker thread while the one before is used.

    ``field(shape, std)`` returns what ``gaussian_noise(shape, std, rng)``
    would, call after call: the seeds come from ``rng`` in the same order,
    and a field drawn ahead that cannot be used (another shape or deviation,
    a failed draw, a draw begun by the parent of a forked process) is drawn
    again from its seed, so the sequence never shifts. Nothing else may draw
    from ``rng``: the next seed is taken from it one call early. A returned
    field stays valid until the next call (two buffers take turns). With
    ``SEMMAP_THREADS=0`` the fields are drawn in turn, on the calling thread.

    Parameters
    ----------
    rng
        The camera's own generator.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.threaded = threads_allowed()
        self._buffers: list[np.ndarray] = []
        self._turn = 0
        # the next field's seed, shape and deviation, its draw (None: not begun) and the
        # process that began it
        self._ahead: tuple[int, tuple[int, ...], float, Future | None, int] | None = None

    def field(self, shape: tuple[int, ...], std: float) -> np.ndarray:
        """The next noise field (float32, ``shape``), valid until the next call."""
        shape = tuple(int(n) for n in shape)
        if not self.threaded:
            return gaussian_noise(shape, std, self.rng)
        if len(self._buffers) != 2 or self._buffers[0].shape != shape:
            self.wait()  # the thread may still be writing into an old buffer
            self._buffers = [np.empty(shape, np.float32), np.empty(shape, np.float32)]
        here = self._turn
        try:
            noise = self._due(shape, std, self._buffers[here])
        finally:
            self._ahead = None  # its seed is spent, the field drawn or not (as in turn)
        self._turn = here ^ 1
        # the next seed is kept before its draw begins: an exception (Ctrl-C included) in
        # between leaves it for the next call, which draws it then
        self._ahead = (draw_seed(self.rng), shape, std, None, os.getpid())
        seed = self._ahead[0]
        job = _pool().submit(noise_from_seed, shape, std, seed, self._buffers[here ^ 1])
        self._ahead = (seed, shape, std, job, os.getpid())
        return noise

    def _due(self, shape: tuple[int, ...], std: float, out: np.ndarray) -> np.ndarray:
        """The field due, in ``out``: the one drawn ahead if it is this field and its draw
        went well, else drawn now from its seed (on the worker, like every field, so the
        caller's OpenCV RNG never moves)."""
        if self._ahead is None:
            seed = draw_seed(self.rng)
        else:
            seed, ahead_shape, ahead_std, job, pid = self._ahead
            if job is not None and pid == os.getpid():  # not a draw a parent process began
                wait_for([job])
                if (ahead_shape, ahead_std) == (shape, std) and job.exception() is None:
                    return out
        return _pool().submit(noise_from_seed, shape, std, seed, out).result()

    def wait(self) -> None:
        """Let the field being drawn ahead finish (its seed is kept for the next call)."""
        if self._ahead is not None and self._ahead[3] is not None \
                and self._ahead[4] == os.getpid():
            wait_for([self._ahead[3]])
