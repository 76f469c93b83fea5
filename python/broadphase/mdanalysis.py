"""Drop-in replacements for ``MDAnalysis.lib.distances.capped_distance`` and
``self_capped_distance``: the same signatures and outputs (``pairs`` int
(k, 2), ``distances`` float64 (k,), the interval (min_cutoff, max_cutoff]),
the same neighbours::

    from broadphase.mdanalysis import capped_distance   # was: MDAnalysis.lib.distances
    pairs, d = capped_distance(ref, conf, 3.0, box=u.dimensions)

As MDAnalysis: coordinates are taken as float32 (AtomGroups by their
positions), ``box`` is ``[lx, ly, lz, alpha, beta, gamma]`` or None, and
with a box each pair is reported once at its minimum-image distance.
``method`` is accepted and ignored (one method). Pairs are sorted (by the
first index, then the second); MDAnalysis' order depends on its method.
Distances are computed in double from the float32 coordinates by the rule
of docs/neighbours.md; a distance within a rounding of ``max_cutoff`` may
be decided otherwise than by MDAnalysis.
"""

from __future__ import annotations

import numpy as _np

from ._neighbours import neighbor_list as _neighbor_list
from ._neighbours import neighbor_list_between as _neighbor_list_between

__all__ = ["capped_distance", "self_capped_distance", "triclinic_vectors"]


def triclinic_vectors(dimensions):
    """The box matrix (rows a, b, c) of ``[lx, ly, lz, alpha, beta, gamma]``,
    float32, computed as MDAnalysis' ``triclinic_vectors`` does (double,
    exact right angles); zero for an invalid box."""
    dim = _np.asarray(dimensions, dtype=_np.float64)
    if dim.shape != (6,):
        raise ValueError(f"box: expected [lx, ly, lz, alpha, beta, gamma], got shape {dim.shape}")
    lx, ly, lz, alpha, beta, gamma = dim
    if not (_np.all(dim > 0.0) and alpha < 180.0 and beta < 180.0 and gamma < 180.0):
        return _np.zeros((3, 3), dtype=_np.float32)
    if alpha == beta == gamma == 90.0:
        return _np.diag(dim[:3].astype(_np.float32))
    m = _np.zeros((3, 3), dtype=_np.float64)
    m[0, 0] = lx
    cos_alpha = 0.0 if alpha == 90.0 else _np.cos(_np.deg2rad(alpha))
    cos_beta = 0.0 if beta == 90.0 else _np.cos(_np.deg2rad(beta))
    if gamma == 90.0:
        cos_gamma, sin_gamma = 0.0, 1.0
    else:
        cos_gamma, sin_gamma = _np.cos(_np.deg2rad(gamma)), _np.sin(_np.deg2rad(gamma))
    m[1, 0] = ly * cos_gamma
    m[1, 1] = ly * sin_gamma
    m[2, 0] = lz * cos_beta
    m[2, 1] = lz * (cos_alpha - cos_beta * cos_gamma) / sin_gamma
    m[2, 2] = _np.sqrt(lz * lz - m[2, 0] ** 2 - m[2, 1] ** 2)
    if m[2, 2] > 0:
        return m.astype(_np.float32)
    return _np.zeros((3, 3), dtype=_np.float32)


def _coords(a, name):
    if hasattr(a, "positions"):
        a = a.positions
    try:
        c = _np.asarray(a, dtype=_np.float32)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot be read as coordinates ({e})") from None
    if c.shape == (3,):
        c = c.reshape(1, 3)
    if c.ndim != 2 or c.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (N, 3) or (3,), got {c.shape}")
    return c


def _box(box):
    if box is None:
        return None, False
    m = triclinic_vectors(box)
    if not m.any():
        raise ValueError(f"box: invalid box {list(_np.asarray(box).ravel())}")
    return m.astype(_np.float64), True


def _minimum_image(i, j, d, n_conf):
    """One row per (i, j): the smallest distance (rows sorted by i, j)."""
    if len(i) == 0:
        return i, j, d
    key = i * max(n_conf, 1) + j
    start = _np.flatnonzero(_np.concatenate(([True], key[1:] != key[:-1])))
    return i[start], j[start], _np.minimum.reduceat(d, start)


def _finish(i, j, d, min_cutoff, return_distances):
    if min_cutoff is not None:
        keep = d > min_cutoff
        i, j, d = i[keep], j[keep], d[keep]
    pairs = _np.empty((len(i), 2), dtype=_np.intp)
    pairs[:, 0] = i
    pairs[:, 1] = j
    if return_distances:
        return pairs, _np.asarray(d, dtype=_np.float64)
    return pairs


def capped_distance(reference, configuration, max_cutoff, min_cutoff=None, box=None,
                    method=None, return_distances=True):
    """As MDAnalysis' ``capped_distance``: the pairs (i, j) of
    ``reference[i]`` and ``configuration[j]`` with distance in
    (min_cutoff, max_cutoff], minimum image with a box."""
    ref = _coords(reference, "reference")
    conf = _coords(configuration, "configuration")
    cell, pbc = _box(box)
    i, j, d = _neighbor_list_between("ijd", ref, conf, float(max_cutoff), cell=cell, pbc=pbc)
    if pbc:
        i, j, d = _minimum_image(i, j, d, conf.shape[0])
    return _finish(i, j, d, min_cutoff, return_distances)


def self_capped_distance(reference, max_cutoff, min_cutoff=None, box=None, method=None,
                         return_distances=True):
    """As MDAnalysis' ``self_capped_distance``: the pairs i < j of
    ``reference`` with distance in (min_cutoff, max_cutoff], minimum image
    with a box."""
    ref = _coords(reference, "reference")
    cell, pbc = _box(box)
    i, j, d = _neighbor_list("ijd", ref, float(max_cutoff), cell=cell, pbc=pbc)
    other = i != j  # a point and its own image are not a pair here
    i, j, d = i[other], j[other], d[other]
    if pbc:
        i, j, d = _minimum_image(i, j, d, ref.shape[0])
    return _finish(i, j, d, min_cutoff, return_distances)
