"""Sonar readings summed on a grid exactly, as row runs, and kept up to date as they change.

The offline map (:mod:`blocks.maps.offline`) adds each reading's log-odds to
every cell of its cone, one reading after the other in float32.  A cone cut
off at a range is, on each grid row, a run of cells (:func:`blocks.maps.cones.cone_spans`),
so a reading can instead leave a value at the start of each run and take it
back after its end, on a difference grid; a cumulative sum along the rows
then gives every cell its total.  That is work per row, not per cell.

The sums are exact: a reading's log-odds are float32 numbers, each a whole
multiple of ``2**-e`` for a small ``e`` (27 for the default weights), and
float64 adds such numbers without rounding as long as the totals stay below
``2**(52 - e)``.  So the result does not depend on the order of the readings,
and a sum can be updated by subtracting the readings that left or changed
and adding the new ones (:class:`BeamSums`), with the same result as a sum
from scratch.  (The float32 sums of the offline map differ from these by
their rounding, about 1e-6 per reading.)

A reading ("beam") is given by codes in half cells, as in the offline map:
its free space covers the cone's cells with a range code below ``free``, its
echo darkens the cells with ``lo <= code <= hi`` (``hi < lo``: no echo), the
echo winning where the two meet.

Which cells a reading touched is not kept: a cell whose sum is not 0 was
touched, and a touched cell whose readings cancel out exactly has
probability 1/2, unknown like an untouched one.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import numpy as np

from .cones import ConeSpans

__all__ = ["BeamSums", "Beams", "add_runs", "beam_rings", "beam_terms", "block_sums",
           "exact_weights", "fraction_bits", "run_ends", "sum_beams"]


@dataclass(frozen=True)
class Beams:
    """Readings on a grid, one row each (all (N,) arrays).

    Attributes
    ----------
    row, col
        The apex cell (grid indices of the map frame: ``floor(y / res)``,
        ``floor(x / res)``).
    degree
        Heading in whole degrees, 0..359.
    free, lo, hi
        Range codes in half cells: free below ``free``; darkened from ``lo`` to
        ``hi`` inclusive (none if ``hi < lo``).
    free_value, occ_value
        Log-odds added to a free and to a darkened cell (float32 values, as float64).
    """

    row: np.ndarray
    col: np.ndarray
    degree: np.ndarray
    free: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    free_value: np.ndarray
    occ_value: np.ndarray

    def __len__(self) -> int:
        return len(self.row)

    def take(self, index: np.ndarray) -> Beams:
        return Beams(*(getattr(self, name)[index] for name in self.__dataclass_fields__))

    def table(self) -> np.ndarray:
        """(N, 8) float64: every field, to compare readings row by row."""
        return np.column_stack([getattr(self, name) for name in self.__dataclass_fields__]
                               ).astype(np.float64)


def beam_terms(beams: Beams, limit: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Each reading as a signed sum of cut cones ``{code < t}``.

    A reading adds ``free_value`` where ``code < free`` and not darkened, and
    ``occ_value`` where ``lo <= code <= hi``; with ``S(t) = {code < t}`` and
    ``h = hi + 1``, ``l = min(lo, h)`` that is::

        free_value * (S(free) - S(min(free, h)) + S(min(free, l))) + occ_value * (S(h) - S(l))

    Returns
    -------
    beam, t, value
        One row per term: the reading, the code bound ``t`` (1..limit) and
        the log-odds.

    Examples
    --------
    >>> b = Beams(*[np.array([v]) for v in (0, 0, 0, 6, 6, 9, -0.4, 0.85)])
    >>> beam, t, value = beam_terms(b, limit=100)
    >>> t.tolist(), value.tolist()
    ([6, 10, 6], [-0.4, 0.85, -0.85])
    """
    t, value, keep = _term_table(beams)
    beam = np.broadcast_to(np.arange(len(beams))[:, None], t.shape)
    return beam[keep], np.minimum(t[keep], limit), value[keep]


def beam_rings(beams: Beams, limit: int
               ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The terms of :func:`beam_terms`, each pair ``value * (S(h) - S(l))`` as one ring.

    Why: a ring ``{l <= code < h}`` lies on a few rows of its cone (an echo's
    arc across a cone that points along the columns: a thirtieth of them),
    where its two cones drawn apart have runs on every row, equal outside the
    ring, that cancel.

    Returns
    -------
    beam, outer, inner, value
        One row per ring: the reading, the code bounds (both clipped to
        ``limit``; ``inner`` 0 for a whole cut cone ``S(outer)``) and the log-odds.

    Examples
    --------
    >>> b = Beams(*[np.array([v]) for v in (0, 0, 0, 6, 6, 9, -0.4, 0.85)])
    >>> beam, outer, inner, value = beam_rings(b, limit=100)
    >>> outer.tolist(), inner.tolist(), value.tolist()
    ([6, 10], [0, 6], [-0.4, 0.85])
    """
    t, value, keep = _term_table(beams)
    inner = np.zeros_like(t)
    for o, i in ((1, 2), (3, 4)):  # the pairs of a reading with the same value, negated
        pair = keep[:, o] & keep[:, i]
        inner[:, o] = np.where(pair, t[:, i], 0)
        keep[:, i] &= ~pair
    beam = np.broadcast_to(np.arange(len(beams))[:, None], t.shape)
    return (beam[keep], np.minimum(t[keep], limit), np.minimum(inner[keep], limit),
            value[keep])


def _term_table(beams: Beams) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(N, 5) the code bounds and the log-odds of :func:`beam_terms`' terms, and which count;
    columns 1, 2 and 3, 4 are pairs ``v * (S(h) - S(l))``, with ``h >= l``."""
    free = beams.free
    occ = beams.hi >= beams.lo
    h = np.where(occ, beams.hi + 1, 0)
    l = np.where(occ, np.maximum(np.minimum(beams.lo, h), 0), 0)  # noqa: E741
    live = np.maximum(free, beams.hi) > 0  # as the offline map: nothing when both bounds are 0
    fv, ov = beams.free_value, beams.occ_value
    t = np.stack([free, np.minimum(free, h), np.minimum(free, l), h, l], axis=1)
    value = np.stack([fv, -fv, fv, ov, -ov], axis=1)
    keep = live[:, None] & (t > 0) & (value != 0)
    # S(a) - S(a) terms cancel: drop pairs of equal bounds with opposite signs
    same_fh = t[:, 0] == t[:, 1]
    keep[:, 0] &= ~same_fh
    keep[:, 1] &= ~same_fh
    same_hl = t[:, 3] == t[:, 4]
    keep[:, 3] &= ~same_hl
    keep[:, 4] &= ~same_hl
    return t, value, keep


#: Runs drawn at once by :func:`add_runs`: temporaries of ~100 kB, that stay in cache and
#: that the allocator hands back instead of mapping fresh pages for each.
RUN_PIECE = 16384


def run_ends(spans: ConeSpans, beams: Beams, corner: tuple[int, int], stride: int, *,
             exact: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """The difference-grid entries of ``beams``: flat indices and log-odds.

    The grid's element [0, 0] is cell ``corner`` = (row, col); its rows are
    ``stride`` long (one more than the map is wide, for the ends of runs that
    reach the last column).  Every cone must lie inside the grid.  A run that
    the disk cuts away entirely starts and ends at the same place: its two
    entries cancel.  With ``exact`` (the log-odds sum exactly in any order:
    :func:`exact_weights`), only the rows whose entries do not cancel out are
    drawn (:func:`beam_rings`: an echo's arc on the rows it crosses, a cut
    cone on the rows it reaches), which changes no sum; else every row within
    the disk's reach is drawn, as the sums' rounding then depends on it.
    """
    parts = [part for piece in _run_pieces(spans, beams, corner, stride, exact, None)
             for part in piece]
    return (np.concatenate([index for index, _, _ in parts]),
            np.concatenate([np.negative(value) if taken else value for _, value, taken in parts]))


def add_runs(flat: np.ndarray, spans: ConeSpans, beams: Beams, corner: tuple[int, int],
             stride: int, *, check: bool = False) -> None:
    """Add the entries of :func:`run_ends` (``exact``) to the difference grid ``flat``
    (raveled), :data:`RUN_PIECE` runs at a time; with ``check``, first make sure that
    each lands inside it.  The run starts and ends are added and taken away part by
    part, without joining them or negating values first (the sums are exact)."""
    for piece in _run_pieces(spans, beams, corner, stride, True, RUN_PIECE):
        if check and any(index.size and (index.min() < 0 or index.max() >= flat.size)
                         for index, _, _ in piece):
            raise ValueError("a reading's cone reaches outside the grid")
        for index, value, taken in piece:
            (np.subtract if taken else np.add).at(flat, index, value)


def _run_pieces(spans: ConeSpans, beams: Beams, corner: tuple[int, int], stride: int,
                exact: bool, budget: int | None
                ) -> Iterator[list[tuple[np.ndarray, np.ndarray, bool]]]:
    """:func:`run_ends` in pieces of about ``budget`` runs (None: one piece, run starts
    then run ends, in the order of :func:`beam_terms`), each piece as parts (flat
    indices, log-odds, whether they are taken away instead of added)."""
    if exact:  # the rings of beam_rings on the rows where their two cuts differ
        beam, outer, inner, value = beam_rings(beams, spans.limit)
        order = np.argsort(inner > 0, kind="stable")  # whole cones first, then the rings
        beam, outer, inner, value = beam[order], outer[order], inner[order], value[order]
        degree = beams.degree[beam]
        e0 = np.maximum(spans.reached_from[degree, outer], spans.beyond_from[degree, inner])
        n = np.maximum(np.minimum(spans.reached_to[degree, outer],
                                  spans.beyond_to[degree, inner]) - e0, 0)
    else:  # each cut cone on every row within its disk's reach
        beam, outer, value = beam_terms(beams, spans.limit)
        inner = np.zeros_like(outer)
        y = spans.rows_below[outer]
        degree = beams.degree[beam]
        e0 = spans.first[degree, spans.reach - y]
        n = np.maximum(spans.first[degree, spans.reach + y + 1] - e0, 0)
    for part in _pieces(n, budget):
        runs = _RunTables(spans, beams, beam[part], corner, stride, e0[part], n[part])
        a, b = runs.cut(outer[part])
        v = np.repeat(value[part], n[part])
        parts = [(a, v, False), (b, v, True)]
        rings = inner[part] > 0
        cones = int(np.searchsorted(rings, True))  # the rings come last
        if cones < len(rings):  # and their inner cuts (a whole cone's S(0) is empty)
            a_in, b_in = runs.cut(inner[part][cones:], cones)
            ring_v = v[int(n[part][:cones].sum()):]
            parts += [(a_in, ring_v, True), (b_in, ring_v, False)]
        yield parts


def _pieces(n: np.ndarray, budget: int | None) -> Iterator[slice]:
    """Slices of consecutive terms with about ``budget`` runs (``n`` per term) each."""
    total = int(n.sum())
    if budget is None or total <= budget:
        yield slice(0, len(n))
        return
    cuts = np.searchsorted(np.cumsum(n), np.arange(budget, total, budget), side="right")
    bounds = np.unique(np.concatenate([[0], cuts, [len(n)]]))
    for first, stop in zip(bounds[:-1].tolist(), bounds[1:].tolist()):
        yield slice(first, stop)


class _RunTables:
    """The runs of many terms, each on its cone's rows ``e0 .. e0 + n`` of the tables, as
    flat grid indices, to be cut at a code bound per term (:meth:`cut`).

    Per run in int32 where that holds every value (half the memory traffic of int64):
    table offsets, and flat indices up to the farthest apex plus a cone's rows.
    """

    def __init__(self, spans: ConeSpans, beams: Beams, beam: np.ndarray,
                 corner: tuple[int, int], stride: int, e0: np.ndarray, n: np.ndarray) -> None:
        total = int(n.sum())
        apex = (beams.row[beam] - corner[0]) * stride + beams.col[beam] - corner[1]
        largest = (int(np.abs(apex).max()) if len(apex) else 0) \
            + (spans.reach + 2) * (stride + 2)
        small = spans.small if max(largest, total) < 2 ** 31 else spans
        itype = small.row.dtype
        entry = np.arange(total, dtype=itype)
        entry += np.repeat((e0 - (np.cumsum(n) - n)).astype(itype), n)
        base = small.row[entry]
        base *= stride
        base += np.repeat(apex.astype(itype), n)
        self.spans, self.small, self.itype, self.n = spans, small, itype, n
        self.entry, self.base = entry, base

    def cut(self, t: np.ndarray, first: int = 0) -> tuple[np.ndarray, np.ndarray]:
        """The flat indices (int64) of the starts and of the ends of the runs of terms
        ``first, first + 1, ...`` cut to ``{code < t}`` (``t`` per term)."""
        n = self.n[first:]
        skip = int(self.n[:first].sum())
        entry, base, small = self.entry[skip:], self.base[skip:], self.small
        w = small.half_width.ravel()[np.repeat((t * (self.spans.reach + 1)).astype(self.itype),
                                               n) + small.abs_row[entry]]
        a = small.start[entry]
        np.maximum(a, -w, out=a)
        w += 1
        b = small.stop[entry]
        np.minimum(b, w, out=b)
        np.maximum(b, a, out=b)
        return np.add(a, base, dtype=np.int64), np.add(b, base, dtype=np.int64)


def sum_beams(spans: ConeSpans, beams: Beams, corner: tuple[int, int],
              shape: tuple[int, int]) -> np.ndarray:
    """The log-odds (float64) of ``beams`` on a grid of ``shape`` at ``corner``.

    The sums are exact for :func:`exact_weights` log-odds, else within float64 rounding.
    """
    exact = exact_weights(np.concatenate([beams.free_value, beams.occ_value]), 2 * len(beams))
    return _integrate(_difference_grid(spans, beams, corner, shape, exact), shape[1], exact)


def _difference_grid(spans: ConeSpans, beams: Beams, corner: tuple[int, int],
                     shape: tuple[int, int], exact: bool) -> np.ndarray:
    h, w = shape
    if exact:  # in any order: a piece at a time
        diff = np.zeros(h * (w + 1))
        add_runs(diff, spans, beams, corner, w + 1, check=True)
        return diff.reshape(h, w + 1)
    index, value = run_ends(spans, beams, corner, w + 1)
    if index.size and (index.min() < 0 or index.max() >= h * (w + 1)):
        raise ValueError("a reading's cone reaches outside the grid")
    return np.bincount(index, value, minlength=h * (w + 1)).reshape(h, w + 1)


def _integrate(diff: np.ndarray, width: int, exact: bool = False) -> np.ndarray:
    """The first ``width`` columns of the running sums along the rows of ``diff``: in the
    order of ``np.cumsum``, or with ``exact`` (sums exact in any order) in blocks
    (:func:`block_sums`, the same numbers)."""
    if exact:
        return block_sums(diff, width)
    return np.cumsum(diff, axis=1)[:, :width]


#: Columns summed a block at a time by :func:`block_sums`.
SUM_BLOCK = 32


def block_sums(diff: np.ndarray, width: int, block: int | None = None) -> np.ndarray:
    """``np.cumsum(diff, axis=1)[:, :width]`` for sums that are exact in any order.

    Why: numpy's running sum goes element after element (each waits for the last),
    about 3 ns a cell.  Here the rows are cut into blocks of ``block`` columns: the
    running sums within every block at once, a column of blocks at a time (whole
    strided columns added, ``block - 1`` of them), then each block's start, the
    running sum of the blocks' totals (a ``block``-th of the cells).  Every partial
    sum here is the difference of two running sums of a row, multiples of ``2**-e``
    below ``2**(52 - e)`` (:func:`exact_weights`), so it is one below ``2**(53 - e)``,
    which float64 holds exactly: nothing rounds, and the result is the same to the
    bit.  It is a view of a (rows, whole blocks) array.

    Examples
    --------
    >>> diff = np.array([[1.0, 0.5, 0.0, -1.5, 0.0], [0.0, 2.0, 0.0, 0.0, -2.0]])
    >>> block_sums(diff, 4, block=2).tolist()
    [[1.0, 1.5, 1.5, 0.0], [0.0, 2.0, 2.0, 2.0]]
    """
    block = SUM_BLOCK if block is None else block
    h = diff.shape[0]
    count = -(-width // block)  # blocks that hold the first width columns
    out = np.zeros((h, count * block))
    out[:, :width] = diff[:, :width]
    blocks = out.reshape(h, count, block)
    for k in range(1, block):
        blocks[:, :, k] += blocks[:, :, k - 1]
    if count > 1:
        blocks[:, 1:, :] += np.cumsum(blocks[:, :-1, block - 1], axis=1)[:, :, None]
    return out[:, :width]


def exact_weights(values: np.ndarray, readings: int) -> bool:
    """Whether sums of ``readings`` of these log-odds are exact in float64 in any order.

    True when every value is a whole multiple of ``2**-e`` and ``readings``
    times the largest stays below ``2**(52 - e)``.

    Examples
    --------
    >>> exact_weights(np.float32([-0.4, 0.85]).astype(np.float64), 10_000)
    True
    >>> exact_weights(np.array([0.1]), 10)  # 0.1 needs all 53 bits of a float64
    False
    """
    values = np.asarray(values, dtype=np.float64)
    values = values[values != 0]
    if values.size == 0:
        return True
    if not np.isfinite(values).all():
        return False
    e = fraction_bits(values)
    if e > 60:
        return False
    return readings * float(np.abs(values).max()) < 2.0 ** (52 - e)


def fraction_bits(values: np.ndarray) -> int:
    """The least ``e >= 0`` with every value (finite, non-zero float64) a whole multiple of
    ``2**-e``: read off each value's bits (its odd mantissa's exponent), where trying
    ``e = 0, 1, ...`` on the distinct values would sort them first.

    Examples
    --------
    >>> fraction_bits(np.array([3.0, 0.75, -0.125]))  # 0.125 = 2**-3
    3
    >>> fraction_bits(np.array([6.0, 1e300]))
    0
    """
    bits = np.abs(np.asarray(values, dtype=np.float64)).view(np.int64)
    biased = bits >> 52
    # the mantissa with its leading bit (none below the normal numbers, where the bits
    # below are not all 0, so setting it leaves the lowest set bit as it is)
    mantissa = (bits & ((1 << 52) - 1)) | (1 << 52)
    lowest = mantissa & -mantissa  # its lowest set bit, a power of two up to 2**52
    odd_exponent = np.frexp(lowest.astype(np.float64))[1] - 1 \
        + np.maximum(biased, 1) - 1075  # value = odd * 2**odd_exponent
    return int(max(0, -int(odd_exponent.min())))


def _joined(gone: Beams, new: Beams) -> Beams:
    """``gone`` with negated log-odds, then ``new``: their run ends are those of the two
    apart, the first negated (``beam_terms`` and ``beam_rings`` keep a term by its value
    being non-zero, which negation keeps)."""
    fields = Beams.__dataclass_fields__
    parts = {name: np.concatenate([getattr(gone, name), getattr(new, name)]) for name in fields}
    for name in ("free_value", "occ_value"):
        np.negative(parts[name][:len(gone)], out=parts[name][:len(gone)])
    return Beams(**parts)


@dataclass
class _State:
    keys: np.ndarray  # (N,) sorted reading keys
    table: np.ndarray  # (N, 8) the readings, as Beams.table()
    beams: Beams
    corner: tuple[int, int]
    diff: np.ndarray  # (H, W + 1) log-odds difference grid


class BeamSums:
    """Exact sums of readings that mostly recur from one call to the next.

    Each call gives the readings of a map with a key each (e.g. scan number x
    16 + sensor); the sums start from the kept call whose readings differ
    least from the new ones, subtract the readings that are gone or changed
    and add the new ones.  The result is the same as :func:`sum_beams` from
    scratch (exactly: see the module), whatever the history.

    Parameters
    ----------
    spans
        The cone runs (:func:`blocks.maps.cones.cone_spans`).
    keep
        How many past calls to keep (each holds a float64 grid).
    """

    def __init__(self, spans: ConeSpans, keep: int = 6) -> None:
        self.spans = spans
        self.keep = keep
        self._states: list[_State] = []
        self.readings_drawn = 0  # readings added or subtracted, over all calls (for tests)

    def __call__(self, keys: np.ndarray, beams: Beams, corner: tuple[int, int],
                 shape: tuple[int, int]) -> np.ndarray:
        """The log-odds of ``beams`` (keys sorted, unique) on the grid at ``corner``."""
        keys = np.asarray(keys, dtype=np.int64)
        table = beams.table()
        exact = exact_weights(np.concatenate([beams.free_value, beams.occ_value]),
                              2 * len(beams))
        base, plan = self._best_start(keys, table) if exact else (None, None)
        if base is None:
            diff = _difference_grid(self.spans, beams, corner, shape, exact)
            self.readings_drawn += len(beams)
        else:
            gone, new = plan
            diff = self._update(base, beams, gone, new, corner, shape)
        if exact:
            self._states.insert(0, _State(keys, table, beams, corner, diff))
            del self._states[self.keep:]
        return _integrate(diff, shape[1], exact)

    def _best_start(self, keys: np.ndarray, table: np.ndarray):
        """The kept call that needs the fewest readings changed, and what to change."""
        best, best_cost, best_plan = None, len(keys), None
        for state in self._states:
            # only the new keys within the kept ones' range can be shared (both sorted)
            lo = int(np.searchsorted(keys, state.keys[0]))
            hi = int(np.searchsorted(keys, state.keys[-1], side="right"))
            if len(state.keys) + len(keys) - 2 * (hi - lo) >= best_cost:
                continue  # even if all of them were shared and the same, no cheaper
            at = np.minimum(np.searchsorted(state.keys, keys[lo:hi]), len(state.keys) - 1)
            i_new = np.flatnonzero(state.keys[at] == keys[lo:hi])  # unique in both
            if len(state.keys) + len(keys) - 2 * len(i_new) >= best_cost:
                continue  # even if every shared reading were the same, no cheaper
            i_old = at[i_new]
            i_new += lo
            same = (state.table[i_old] == table[i_new]).all(axis=1)
            kept_old = np.zeros(len(state.keys), dtype=bool)
            kept_old[i_old[same]] = True
            kept_new = np.zeros(len(keys), dtype=bool)
            kept_new[i_new[same]] = True
            cost = int((~kept_old).sum() + (~kept_new).sum())
            if cost < best_cost:
                best, best_cost = state, cost
                best_plan = (np.flatnonzero(~kept_old), np.flatnonzero(~kept_new))
        return best, best_plan

    def _update(self, base: _State, beams: Beams, gone: np.ndarray, new: np.ndarray,
                corner: tuple[int, int], shape: tuple[int, int]) -> np.ndarray:
        """The kept grid, less the readings gone, plus the new ones, on a grid that holds
        both (what lies outside the new grid then cancels to exactly 0), cut to the new."""
        h, w = shape
        bh, bw = base.diff.shape[0], base.diff.shape[1] - 1
        r0, c0 = min(corner[0], base.corner[0]), min(corner[1], base.corner[1])
        r1 = max(corner[0] + h, base.corner[0] + bh)
        c1 = max(corner[1] + w, base.corner[1] + bw)
        union = (r1 - r0, c1 - c0)
        stride = union[1] + 1
        if (r0, c0) == base.corner and union == (bh, bw):
            diff = base.diff.copy()
        else:
            diff = np.zeros((union[0], stride))
            br, bc = base.corner[0] - r0, base.corner[1] - c0
            diff[br:br + bh, bc:bc + bw + 1] = base.diff
        # the readings gone, with their log-odds negated, then the new ones (exact sums:
        # in any order, a piece at a time)
        add_runs(diff.reshape(-1), self.spans, _joined(base.beams.take(gone), beams.take(new)),
                 (r0, c0), stride)  # only exact sums are kept
        self.readings_drawn += len(gone) + len(new)
        nr, nc = corner[0] - r0, corner[1] - c0
        if (nr, nc) == (0, 0) and union == shape:
            return diff
        return diff[nr:nr + h, nc:nc + w + 1].copy()
