"""k nearest neighbours and radius queries (docs/knn.md), exact against a
brute force with the squared distance ``dx*dx + dy*dy + dz*dz`` in float64
(``dx = q_x - p_x``, left to right; a periodic axis takes the nearest of the
images ``p``, ``p + L``, ``p - L``), each query's neighbours by distance, then
by index."""

from __future__ import annotations

import numpy as np

from . import _broadphase

_REALS = (np.dtype(np.float64), np.dtype(np.float32))


def _points(a, name: str):
    if not (isinstance(a, np.ndarray) and a.dtype in _REALS and a.dtype.isnative):
        try:
            a = np.ascontiguousarray(a, dtype=np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{name}: cannot be read as numbers ({e})") from None
    if a.size == 0 and a.ndim != 2:
        a = a.reshape(0, 3)
    return a


def _box(box):
    if box is None:
        return None
    b = np.asarray(box, dtype=np.float64)
    if b.ndim == 0:
        b = np.full(3, float(b))
    if b.shape != (3,):
        raise ValueError(f"box: expected a length or three lengths (0: not periodic), got shape {b.shape}")
    return [float(v) for v in b]


def _count(value, name: str, least: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"{name}: expected an integer, got {value!r}")
    if value < least:
        raise ValueError(f"{name}: must be at least {least}, got {value}")
    return int(value)


def knn(points, queries=None, k: int = 1, *, box=None, exclude_self: bool = False,
        threads: int = 1):
    """The k nearest of `points` (N, 3) to each of `queries` (M, 3), or to
    each point when `queries` is None (with `exclude_self`, a point is not
    its own neighbour; other points at the same place are).

    Returns ``(distances, indices)`` shaped as ``scipy.spatial.cKDTree.query``
    returns them: (M, k) float64 and int64, (M,) when k is 1, and without the
    first axis for one query of shape (3,). Missing neighbours (k > N) are
    filled as cKDTree fills them: distance inf, index N. Distances are the
    square roots of the exact squared distances. `box`: a periodic box, one
    length or three (0 for an axis that is not periodic); coordinates must
    lie in [0, L] on a periodic axis, and each point counts once, at its
    nearest image. `threads` 0 takes every core; the result does not depend
    on it. float32 input is widened exactly. The GIL is released.
    """
    k = _count(k, "k", 1)
    threads = _count(threads, "threads", 0)
    p = _points(points, "points")
    one = False
    q = None
    if queries is not None:
        if exclude_self:
            raise ValueError("exclude_self: applies only when the points query themselves "
                             "(queries=None)")
        q = _points(queries, "queries")
        if q.ndim == 1 and q.shape[0] == 3:
            q = q.reshape(1, 3)
            one = True
    rows_of = p if q is None else q
    rows = int(rows_of.shape[0]) if rows_of.ndim >= 1 else 0
    d2 = np.empty((rows, k), dtype=np.float64)
    index = np.empty((rows, k), dtype=np.int64)
    _broadphase.knn(p, q, k, _box(box), bool(exclude_self), threads, d2, index)
    np.sqrt(d2, out=d2)
    if k == 1:
        d2, index = d2[:, 0], index[:, 0]
    if one:
        d2, index = d2[0], index[0]
    return d2, index


def within(points, queries, r: float, *, box=None, exclude_self: bool = False,
           distances: bool = False, threads: int = 1):
    """Every point of `points` (N, 3) within `r` of each query (distance
    <= r, that is squared distance <= r*r in float64: touching counts), as
    CSR: ``(offsets, indices)``, or ``(offsets, indices, distances)`` with
    `distances`; query i's neighbours are ``indices[offsets[i]:offsets[i+1]]``
    by distance, then index. `queries` None: the points themselves (with
    `exclude_self`, not a point itself). `box` and `threads` as in `knn`.
    """
    try:
        r = float(r)
    except (TypeError, ValueError):
        raise ValueError(f"r: expected a number, got {r!r}") from None
    threads = _count(threads, "threads", 0)
    p = _points(points, "points")
    if queries is not None and exclude_self:
        raise ValueError("exclude_self: applies only when the points query themselves "
                         "(queries=None)")
    q = None if queries is None else _points(queries, "queries")
    offsets, index, bits = _broadphase.within(p, q, r, _box(box), bool(exclude_self), threads)
    offsets, index = np.asarray(offsets), np.asarray(index)
    if not distances:
        return offsets, index
    return offsets, index, np.sqrt(np.asarray(bits).view(np.float64))
