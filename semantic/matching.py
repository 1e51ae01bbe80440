"""Lowe's ratio test of query descriptors against a fixed set, as arrays rather than ``DMatch`` lists.

``cv2.BFMatcher(norm).knnMatch(query, train, k=2)`` finds each query
descriptor's two nearest train descriptors with ``cv2.batchDistance`` and then
builds two ``DMatch`` objects per query, which the caller loops over in
Python. :func:`ratio_matches` calls ``cv2.batchDistance`` itself and applies
the ratio test to the whole array: the same matches in the same order.

A matrix product (``|q|^2 + |t|^2 - 2 q.t``) would be about three times faster
for SIFT's 128 dimensions, but numpy's BLAS then runs on all cores, and on a
busy two-core machine it measured five to ten times slower than
``cv2.batchDistance``; see ``benchmarks/object_gate.py``.
"""
from __future__ import annotations

import cv2
import numpy as np

__all__ = ["ratio_matches"]


def ratio_matches(query: np.ndarray, train: np.ndarray, ratio: float,
                  norm: int = cv2.NORM_L2) -> tuple[np.ndarray, np.ndarray]:
    """The query descriptors whose best train match is under ``ratio`` times the second best.

    The same matches, in the same order, as ``cv2.BFMatcher(norm).knnMatch(query,
    train, k=2)`` followed by ``best.distance < ratio * second.distance``.

    Parameters
    ----------
    query : (N, D) array
        float32 for ``NORM_L2``, uint8 for ``NORM_HAMMING``.
    train : (M, D) array
        Same dtype and width as ``query``.
    ratio : float
        Lowe's ratio.
    norm : int
        OpenCV norm type.

    Returns
    -------
    query_idx, train_idx : (K,) int64 arrays
        The query rows that pass, in order, and their best train rows.

    Examples
    --------
    >>> train = np.array([[0, 0], [10, 0], [0, 10]], np.float32)
    >>> ratio_matches(np.array([[1, 0], [5, 5]], np.float32), train, 0.8)
    (array([0]), array([0]))
    """
    if len(query) == 0 or len(train) < 2:
        return np.zeros(0, np.int64), np.zeros(0, np.int64)
    dtype = cv2.CV_32S if norm in (cv2.NORM_HAMMING, cv2.NORM_HAMMING2) else cv2.CV_32F
    dist, idx = cv2.batchDistance(query, train, dtype, normType=norm, K=2)
    dist = dist.astype(np.float64)  # DMatch.distance is float32, compared as a Python float
    q = np.flatnonzero(dist[:, 0] < ratio * dist[:, 1])
    return q, idx[q, 0].astype(np.int64)
