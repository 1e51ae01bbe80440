"""Lowe's ratio test of query descriptors against a fixed set, as arrays rather than ``DMatch`` lists.

``cv2.BFMatcher(norm).knnMatch(query, train, k=2)`` finds each query
descriptor's two nearest train descriptors with ``cv2.batchDistance`` and then
builds two ``DMatch`` objects per query, which the caller loops over in
Python. :func:`ratio_matches` calls ``cv2.batchDistance`` itself and applies
the ratio test to the whole array: the same matches in the same order.

A matrix product (``|q|^2 + |t|^2 - 2 q.t``) would be about three times faster
for SIFT's 128 dimensions, but numpy's BLAS then runs on all cores, and on a
busy two-core machine it measured five to ten times slower than
``cv2.batchDistance``; see ``benchmarks/object_gate.py``. OpenCV's own
``cv2.gemm`` does not stall so and is still about three times faster:
:class:`RatioMatcher` takes the distances from it, bounds their rounding
error, and sends the few queries whose outcome that error could change to
:func:`ratio_matches`, so its matches are :func:`ratio_matches`' to the bit.
"""
from __future__ import annotations

import math

import cv2
import numpy as np

__all__ = ["RatioMatcher", "ratio_matches"]

_U = 2.0 ** -24  # float32's unit roundoff


def _gamma(n: int) -> float:
    """Bound on the relative rounding error of a float32 sum of n products (Higham's gamma_n)."""
    return n * _U / (1.0 - n * _U)


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


class RatioMatcher:
    """:func:`ratio_matches` (``NORM_L2``) against a fixed float32 train set, by one matrix product.

    ``cv2.batchDistance`` takes every query-train distance on its own and
    keeps the two nearest by insertion; most of its time goes there. Here
    ``|t|^2 - 2 q.t`` comes for all pairs from one ``cv2.gemm`` of the query
    (with a column of ones) and the train set (times -2, with ``|t|^2``), and
    a query's two nearest from ``argmin`` and ``min``. Both sums round
    differently, but within known bounds (a float32 sum of ``n`` products is
    off by at most ``gamma_n`` times the sum of their magnitudes): a query
    whose ratio test passes or fails by more than both bounds together has
    the outcome ``ratio_matches`` gives it, and when it passes, the same best
    row (the others are farther than the second). The rest (about one query
    in a thousand on the office run) go through :func:`ratio_matches`
    itself, which treats every query on its own. So the matches are
    ``ratio_matches``', in the same order; about three times faster.

    Parameters
    ----------
    train : (M, D) float32 array
    ratio : float
        Lowe's ratio.

    Examples
    --------
    >>> train = np.array([[0, 0], [10, 0], [0, 10]], np.float32)
    >>> RatioMatcher(train, 0.8)(np.array([[1, 0], [5, 5]], np.float32))
    (array([0]), array([0]))
    """

    def __init__(self, train: np.ndarray, ratio: float) -> None:
        self.train = np.ascontiguousarray(train, dtype=np.float32)
        self.ratio = float(ratio)
        t = self.train.astype(np.float64)
        squares = np.einsum("ij,ij->i", t, t)
        self._augmented = np.hstack([-2.0 * self.train, squares.astype(np.float32)[:, None]])
        self._longest = math.sqrt(float(squares.max())) if len(squares) else 0.0
        dims = self.train.shape[1]
        self._product_error = 2.0 * (_gamma(dims + 1) + _U)  # of the product, per (|q| + |t|)^2
        self._distance_error = 2.0 * _gamma(dims + 4)  # of batchDistance's squares, relative

    def __call__(self, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The query rows that pass the ratio test, in order, and their best train rows.

        Parameters
        ----------
        query : (N, D) float32 array

        Returns
        -------
        query_idx, train_idx : (K,) int64 arrays
            As :func:`ratio_matches` returns them.
        """
        n = len(query)
        if n == 0 or len(self.train) < 2:
            return np.zeros(0, np.int64), np.zeros(0, np.int64)
        query = np.asarray(query, dtype=np.float32)
        best, first, second = self._two_nearest(query)
        q = query.astype(np.float64)
        lengths = np.einsum("ij,ij->i", q, q)
        err = self._product_error * (np.sqrt(lengths) + self._longest) ** 2
        grow, shrink = 1.0 + self._distance_error, 1.0 - self._distance_error
        # squared distances as batchDistance may find them: within [lo, hi]
        lo1, hi1 = (lengths + first - err) * shrink, (lengths + first + err) * grow
        lo2, hi2 = (lengths + second - err) * shrink, (lengths + second + err) * grow
        r2 = self.ratio * self.ratio
        sure_pass = hi1 < r2 * lo2 * (1.0 - 1e-9)
        sure_fail = lo1 > r2 * hi2 * (1.0 + 1e-9)
        rows = np.flatnonzero(sure_pass)
        train_rows = best[rows].astype(np.int64)
        unsure = np.flatnonzero(~(sure_pass | sure_fail))
        if len(unsure) == 0:
            return rows, train_rows
        uq, ut = ratio_matches(query[unsure], self.train, self.ratio)
        rows = np.concatenate([rows, unsure[uq]])
        order = np.argsort(rows, kind="stable")
        return rows[order], np.concatenate([train_rows, ut])[order]

    def _two_nearest(self, query: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per query: the nearest row and ``|t|^2 - 2 q.t`` of the nearest and second nearest."""
        n, dims = query.shape
        augmented = np.empty((n, dims + 1), np.float32)
        augmented[:, :dims] = query
        augmented[:, dims] = 1.0
        # as (train rows, queries), then transposed: cv2.gemm is slow for a product with
        # few rows (~10x at 50 rows), and numpy's argmin down columns is slow too
        e = cv2.transpose(cv2.gemm(self._augmented, augmented, 1.0, None, 0.0,
                                   flags=cv2.GEMM_2_T))
        rows = np.arange(n)
        best = e.argmin(axis=1)
        first = e[rows, best].astype(np.float64)
        e[rows, best] = np.inf
        return best, first, e.min(axis=1).astype(np.float64)
