"""The camera's Gaussian pixel noise, and the same noise drawn a frame ahead on a thread.

A noise field is the costliest single step of a camera frame (about a quarter
of it) and the only one that needs nothing from the scene: one draw from the
camera's RNG fixes the whole field. ``NoiseAhead`` uses that to draw the next
frame's field on a worker thread while the robot's tick goes on, so the
second core does it; the fields are exactly the ones ``gaussian_noise`` gives.
"""
from __future__ import annotations

import os
import threading
from concurrent.futures import Future, ThreadPoolExecutor

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


def _pool() -> ThreadPoolExecutor:
    """One worker thread shared by every camera in the process (made when first needed)."""
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max_workers=1, thread_name_prefix="semmap-noise")
        return _POOL


def _forget_pool() -> None:
    global _POOL
    _POOL = None


# a forked child has none of its parent's threads: it makes its own worker when it needs one
os.register_at_fork(after_in_child=_forget_pool)


class NoiseAhead:
    """Noise fields from ``rng``, each drawn on a worker thread while the one before is used.

    ``field(shape, std)`` returns what ``gaussian_noise(shape, std, rng)``
    would, call after call: the seeds come from ``rng`` in the same order,
    and a field whose shape or deviation differs from the one drawn ahead is
    drawn again from the same seed. Nothing else may draw from ``rng``: the
    next seed is taken from it one call early. A returned field stays valid
    until the next call (two buffers take turns).

    Parameters
    ----------
    rng
        The camera's own generator.
    """

    def __init__(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self._buffers: list[np.ndarray] = []
        self._turn = 0
        self._ahead: tuple[int, tuple[int, ...], float, Future] | None = None

    def field(self, shape: tuple[int, ...], std: float) -> np.ndarray:
        """The next noise field (float32, ``shape``), valid until the next call."""
        shape = tuple(int(n) for n in shape)
        if len(self._buffers) != 2 or self._buffers[0].shape != shape:
            self.wait()  # the thread may still be writing into an old buffer
            self._buffers = [np.empty(shape, np.float32), np.empty(shape, np.float32)]
        if self._ahead is None or self._ahead[1:3] != (shape, std):
            # nothing drawn ahead, or not this field: draw it now from the seed due
            seed = draw_seed(self.rng) if self._ahead is None else self._ahead[0]
            self.wait()
            self._ahead = (seed, shape, std, self._draw(seed, shape, std))
        noise = self._buffers[self._turn]
        self._ahead[3].result()
        self._turn ^= 1
        seed = draw_seed(self.rng)
        self._ahead = (seed, shape, std, self._draw(seed, shape, std))
        return noise

    def _draw(self, seed: int, shape: tuple[int, ...], std: float) -> Future:
        """Draw a field into the buffer whose turn it is, on the worker (every field is drawn
        there, so the caller's OpenCV RNG is never moved)."""
        return _pool().submit(noise_from_seed, shape, std, seed, self._buffers[self._turn])

    def wait(self) -> None:
        """Let the field being drawn ahead finish (its seed is kept for the next call)."""
        if self._ahead is not None:
            self._ahead[3].result()
