"""The camera noise drawn ahead on a thread is the noise drawn in turn, field for field."""
from __future__ import annotations

import cv2
import numpy as np

from sim2d.camera import CameraRenderer, CameraSpec
from sim2d.noise import NoiseAhead, gaussian_noise
from sim2d.world import make_world


def test_fields_drawn_ahead_are_the_fields_drawn_in_turn():
    """Same seeds, same order, through changes of shape and deviation (a changed field is
    drawn again from the seed drawn ahead, so the sequence never shifts)."""
    calls = [((24, 32, 3), 3.0)] * 3 + [((12, 16, 3), 3.0), ((12, 16, 3), 1.5),
                                         ((12, 16, 3), 1.5), ((24, 32, 3), 3.0)]
    plain, ahead = np.random.default_rng(7), NoiseAhead(np.random.default_rng(7))
    for shape, std in calls:
        want = gaussian_noise(shape, std, plain)
        got = ahead.field(shape, std)
        assert got.shape == shape and got.dtype == np.float32
        assert np.array_equal(got, want)


def test_a_field_stays_valid_until_the_next_call():
    ahead = NoiseAhead(np.random.default_rng(1))
    first = ahead.field((40, 30, 3), 3.0)
    kept = first.copy()
    ahead.wait()  # the next field is drawn meanwhile, into the other buffer
    assert np.array_equal(first, kept)
    assert not np.array_equal(ahead.field((40, 30, 3), 3.0), kept)


def test_the_main_threads_opencv_rng_is_left_alone():
    """OpenCV's RNG is per thread: fields drawn on the worker do not move the caller's."""
    ahead = NoiseAhead(np.random.default_rng(2))
    cv2.setRNGSeed(99)
    want = cv2.randu(np.empty(8, np.float32), 0.0, 1.0).copy()
    cv2.setRNGSeed(99)
    ahead.field((10, 10, 3), 3.0)
    ahead.field((10, 10, 3), 3.0)
    ahead.wait()
    assert np.array_equal(cv2.randu(np.empty(8, np.float32), 0.0, 1.0), want)


def test_camera_frames_with_noise_drawn_ahead_are_the_same_frames():
    box = make_world([[0, -2, 4, -2], [4, -2, 4, 2], [4, 2, 0, 2], [0, 2, 0, -2]])
    plain = CameraRenderer(box, CameraSpec())
    ahead = CameraRenderer(box, CameraSpec())
    rng_plain, noise = np.random.default_rng(3), NoiseAhead(np.random.default_rng(3))
    for step in range(4):
        pose, zoom = (1.0 + 0.2 * step, 0.1 * step, 0.05 * step), 1.0 + step
        want = plain.frame(pose, 0.0, zoom, rng_plain).image
        assert np.array_equal(ahead.frame(pose, 0.0, zoom, noise).image, want)


def test_a_forked_child_draws_noise_on_a_worker_of_its_own():
    """A child forked after the parent started the noise worker has no thread behind the
    parent's pool: it must start its own, not queue fields nobody draws."""
    import multiprocessing
    want = NoiseAhead(np.random.default_rng(5)).field((8, 8, 3), 3.0).copy()
    with multiprocessing.get_context("fork").Pool(1) as pool:
        got = pool.apply_async(_field_in_child).get(timeout=30)
    assert np.array_equal(got, want)


def _field_in_child() -> np.ndarray:
    return NoiseAhead(np.random.default_rng(5)).field((8, 8, 3), 3.0).copy()


def test_a_failed_draw_spends_its_seed_as_in_turn_and_the_sequence_goes_on():
    """A field that cannot be drawn raises, as drawing it in turn does, and spends its seed
    as that does; the next call gets the field drawing in turn gives next."""
    import pytest
    plain, ahead = np.random.default_rng(9), NoiseAhead(np.random.default_rng(9))
    assert np.array_equal(ahead.field((6, 6, 3), 3.0), gaussian_noise((6, 6, 3), 3.0, plain))
    with pytest.raises(ValueError):
        gaussian_noise((6, 6, 3), "loud", plain)
    with pytest.raises(ValueError):
        ahead.field((6, 6, 3), "loud")
    for _ in range(2):
        assert np.array_equal(ahead.field((6, 6, 3), 3.0),
                              gaussian_noise((6, 6, 3), 3.0, plain))


_FORKED: NoiseAhead | None = None


def _field_after_fork(queue) -> None:
    queue.put(_FORKED.field((500, 500, 3), 3.0).copy())


def test_a_child_forked_mid_draw_draws_that_field_again():
    """The parent's draw of the next field never finishes in a forked child (its thread is
    not there): the child draws that field again from the seed it kept."""
    import multiprocessing
    global _FORKED
    _FORKED = ahead = NoiseAhead(np.random.default_rng(11))
    ahead.field((500, 500, 3), 3.0)  # the next field is being drawn as the process forks
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=_field_after_fork, args=(queue,))
    child.start()
    got = queue.get(timeout=30)
    child.join(timeout=30)
    assert np.array_equal(got, ahead.field((500, 500, 3), 3.0))


def test_without_threads_the_fields_are_drawn_in_turn(monkeypatch):
    monkeypatch.setenv("SEMMAP_THREADS", "0")
    plain, ahead = np.random.default_rng(4), NoiseAhead(np.random.default_rng(4))
    assert not ahead.threaded
    for _ in range(3):
        assert np.array_equal(ahead.field((5, 7, 3), 3.0), gaussian_noise((5, 7, 3), 3.0, plain))


def test_a_sweep_worker_with_every_core_busy_runs_without_helper_threads(monkeypatch):
    from blocks.sweep.worker import init_pool_worker
    monkeypatch.delenv("SEMMAP_THREADS", raising=False)
    init_pool_worker(None, helper_threads=True)
    assert NoiseAhead(np.random.default_rng(0)).threaded
    init_pool_worker(None, helper_threads=False)
    assert not NoiseAhead(np.random.default_rng(0)).threaded
