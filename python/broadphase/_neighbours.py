"""Neighbour lists: the pairs (i, j, S) of points within a cutoff, in free
space, orthorhombic and triclinic periodic cells (docs/neighbours.md).

The exact rule (the C++ header include/broadphase/neighbours.hpp): in
double, left to right, with the shift on j and the positions as given,
``o = (S0*a + S1*b) + S2*c``, ``D = (x_j + o) - x_i``,
``d2 = (Dx*Dx + Dy*Dy) + Dz*Dz``, a pair when ``d2 <= s*s`` (``<`` with
``strict``), s the cutoff or ``c_i + c_j``.
"""

from __future__ import annotations

import numpy as _np

from . import _broadphase
from ._knn import _count

_QUANTITIES = {"i": "i", "j": "j", "S": "S", "d": "d", "D": "D", "o": "offsets"}


def _points(a, name: str):
    """(N, 3) float64/float32 read in place, or a float64 copy."""
    if isinstance(a, _np.ndarray) and a.dtype in (_np.float64, _np.float32) and a.dtype.isnative:
        p = a
    else:
        try:
            p = _np.asarray(a, dtype=_np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"{name}: cannot be read as numbers ({e})") from None
    if p.size == 0 and p.ndim != 2:
        p = p.reshape(0, 3)
    if p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{name}: expected shape (N, 3), got {p.shape}")
    return p


def _cell(cell, pbc):
    """The cell as three rows of floats and pbc as three bools."""
    if cell is None:
        c = _np.zeros((3, 3))
        default_pbc = False
    else:
        try:
            c = _np.asarray(cell, dtype=_np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"cell: cannot be read as numbers ({e})") from None
        if c.ndim == 0 or c.shape == (3,):
            c = _np.diag(_np.broadcast_to(c, (3,)))
        if c.shape != (3, 3):
            raise ValueError(f"cell: expected a length, 3 lengths or a 3x3 matrix, got shape {c.shape}")
        default_pbc = True
    if pbc is None:
        pbc = default_pbc
    p = _np.asarray(pbc)
    if p.dtype != bool or p.ndim > 1 or (p.ndim == 1 and p.shape[0] != 3):
        raise ValueError(f"pbc: expected a bool or 3 bools, got {pbc!r}")
    p = _np.broadcast_to(p, (3,))
    return c.tolist(), [bool(v) for v in p]


def _cutoff(cutoff, n: int):
    """(scalar, None) for one cutoff, (0, array) for per-point cutoffs."""
    if _np.ndim(cutoff) == 0:
        try:
            return float(cutoff), None
        except (TypeError, ValueError) as e:
            raise ValueError(f"cutoff: not a number ({e})") from None
    c = _np.asarray(cutoff)
    if c.dtype not in (_np.float64, _np.float32) or not c.dtype.isnative:
        try:
            c = _np.asarray(c, dtype=_np.float64)
        except (TypeError, ValueError) as e:
            raise ValueError(f"cutoff: cannot be read as numbers ({e})") from None
    if c.shape != (n,):
        raise ValueError(f"cutoff: expected a number or shape ({n},), got shape {c.shape}")
    return 0.0, c


def _quantities(quantities: str):
    if not isinstance(quantities, str) or not quantities:
        raise ValueError(f"quantities: expected a string of i, j, S, d, D, o, got {quantities!r}")
    for q in quantities:
        if q not in _QUANTITIES:
            raise ValueError(f"quantities: unknown quantity {q!r} in {quantities!r} "
                             "(i, j, S, d, D, o)")
    return quantities


def _result(out: dict, quantities: str):
    r = tuple(_np.asarray(out[_QUANTITIES[q]]) for q in quantities)
    return r[0] if len(r) == 1 else r


def _flags(quantities: str) -> dict:
    return {"shifts": "S" in quantities, "distances": "d" in quantities,
            "vectors": "D" in quantities, "offsets": "o" in quantities}


def neighbor_list(quantities: str, positions, cutoff, *, cell=None, pbc=None,
                  full: bool = False, self_interaction: bool = False, strict: bool = False,
                  threads: int = 1):
    """The pairs of points within a cutoff, with their periodic shifts.

    Args:
        quantities: the outputs, in order, one letter each: ``i`` and ``j``
            (int64 indices), ``S`` (int64 (M, 3) shifts: j's image is
            ``x_j + S @ cell``), ``d`` (float64 distances), ``D`` (float64
            (M, 3) vectors from i to j's image), ``o`` (int64 (N + 1,) CSR
            offsets: i's pairs are ``[o[i], o[i + 1])``; with ``j`` that is
            the CSR form ``(offsets, neighbours)``). One letter returns the
            array alone, as ASE does.
        positions: (N, 3) float64 or float32 (read in place), or an
            ``ase.Atoms`` (its positions, cell and pbc, unless given here).
            Points outside a periodic cell are wrapped; S includes that.
        cutoff: one cutoff (pairs with ``|D| <= cutoff``), or (N,)
            per-point cutoffs (pairs with ``|D| <= c_i + c_j``, ASE's rule).
        cell: None (free space), a length, three lengths or a 3x3 matrix
            whose rows are the cell vectors (ASE's ``atoms.cell``).
        pbc: periodicity per axis (a bool or three); default True with a
            cell, False without.
        full: both (i, j, S) and (j, i, -S) (as ASE); default a half list:
            i < j, and a point's pair with its own image once (the shift
            whose first non-zero component is positive).
        self_interaction: include (i, i, 0).
        strict: ``<`` instead of ``<=`` at the cutoff (ASE's boundary).
        threads: threads to find the list on (0: every core); the list does
            not depend on it.

    Every image within the cutoff is reported (cells smaller than the
    cutoff). Sorted by i, then j, then S. The GIL is released while the
    list is found.

    Raises:
        ValueError: unknown quantities, a position, cell or cutoff that is
            not finite, a negative cutoff, degenerate periodic cell vectors,
            a negative or non-integer ``threads``.
    """
    quantities = _quantities(quantities)
    threads = _count(threads, "threads", 0)
    if hasattr(positions, "get_positions") and hasattr(positions, "cell"):
        atoms = positions
        positions = atoms.get_positions()
        if cell is None:
            cell = _np.asarray(atoms.get_cell(complete=True))
        if pbc is None:
            pbc = _np.asarray(atoms.pbc)
    p = _points(positions, "positions")
    c, b = _cell(cell, pbc)
    one, per = _cutoff(cutoff, p.shape[0])
    out = _broadphase.neighbour_list(p, c, b, one, per, bool(full), bool(self_interaction),
                                     bool(strict), **_flags(quantities), threads=threads)
    return _result(out, quantities)


def neighbor_list_between(quantities: str, queries, points, cutoff, *, cell=None, pbc=None,
                          strict: bool = False, threads: int = 1):
    """The pairs (i, j, S) of a query i and a point j whose image
    ``points[j] + S @ cell`` lies within ``cutoff`` of ``queries[i]``; every
    image. ``quantities``, ``cell``, ``pbc``, ``strict`` and ``threads`` as
    for :func:`neighbor_list` (``o``: offsets by query). Sorted by i, j, S."""
    quantities = _quantities(quantities)
    threads = _count(threads, "threads", 0)
    q = _points(queries, "queries")
    p = _points(points, "points")
    c, b = _cell(cell, pbc)
    one, per = _cutoff(cutoff, 0)
    if per is not None:
        raise ValueError("cutoff: one number between two sets")
    out = _broadphase.neighbour_list_between(q, p, c, b, one, bool(strict), **_flags(quantities),
                                             threads=threads)
    return _result(out, quantities)


class NeighbourList:
    """A neighbour list with a skin, reused over the frames of a moving
    system (as molecular dynamics codes keep a Verlet list).

    ``NeighbourList(quantities, cutoff, **kw).update(positions)`` returns on
    every frame exactly what ``neighbor_list(quantities, positions, cutoff,
    **kw)`` returns (the same pairs, shifts, distances and order), but finds
    the candidate pairs (within ``cutoff + skin``) again only when a point
    has moved more than ``skin / 2`` since they were found; in between it
    re-evaluates them with the exact rule. Points may be wrapped back into
    the cell between frames (or not): the shifts follow.

    Args:
        quantities, cutoff, cell, pbc, full, self_interaction, strict,
            threads: as for :func:`neighbor_list`, fixed for the list's
            life (``threads`` is used where the candidates are found);
            per-point cutoffs fix the number of points.
        skin: the skin (a length >= 0); None: 0.3 of the largest reach (the
            cutoff, or twice the largest per-point cutoff), the fastest of
            the skins measured on thermal-like motion (docs/neighbours.md).
            Pairs are looked for again when a point has moved half of it.

    Memory: 32 bytes a candidate (a full list has twice as many), 64 bytes
    a point. ``update`` releases the GIL; two overlapping calls on the same
    list raise RuntimeError.

    Raises:
        ValueError: as :func:`neighbor_list`, a skin that is not finite, and
            (``update``) points whose count differs from the per-point
            cutoffs', or an ``ase.Atoms`` whose cell or pbc is not the list's.
    """

    def __init__(self, quantities: str, cutoff, *, skin=None, cell=None, pbc=None,
                 full: bool = False, self_interaction: bool = False, strict: bool = False,
                 threads: int = 1):
        self._quantities = _quantities(quantities)
        threads = _count(threads, "threads", 0)
        self._cell, self._pbc = _cell(cell, pbc)
        if _np.ndim(cutoff) == 0:
            one, per = _cutoff(cutoff, 0)
        else:
            one, per = _cutoff(cutoff, _np.shape(cutoff)[0])
        if skin is None:
            skin = -1.0
        else:
            try:
                skin = float(skin)
            except (TypeError, ValueError) as e:
                raise ValueError(f"skin: not a number ({e})") from None
            if not skin >= 0:
                raise ValueError(f"skin: must be finite and >= 0 ({skin})")
        self._core = _broadphase.MovingNeighbourList(
            self._cell, self._pbc, one, per, skin, bool(full), bool(self_interaction),
            bool(strict), **_flags(self._quantities), threads=threads)

    def update(self, positions):
        """The list of ``positions`` ((N, 3) float64/float32 read in place,
        or an ``ase.Atoms`` with the list's cell and pbc): the arrays of
        ``quantities``, as :func:`neighbor_list` returns them."""
        if hasattr(positions, "get_positions") and hasattr(positions, "cell"):
            atoms = positions
            c = _np.asarray(atoms.get_cell(complete=True), dtype=_np.float64)
            b = [bool(v) for v in _np.broadcast_to(atoms.pbc, (3,))]
            if b != self._pbc or not _np.array_equal(
                    c * _np.asarray(b)[:, None], _np.asarray(self._cell) * _np.asarray(b)[:, None]):
                raise ValueError("positions: the Atoms' cell or pbc is not the list's")
            positions = atoms.get_positions()
        return _result(self._core.update(_points(positions, "positions")), self._quantities)

    @property
    def skin(self) -> float:
        """The skin in use (a length)."""
        return self._core.skin()

    @property
    def rebuilds(self) -> int:
        """How many times the candidates were found (the first update's
        counts)."""
        return self._core.rebuilds()

    @property
    def candidates(self) -> int:
        """Candidate pairs kept now."""
        return self._core.candidates()

    def memory_bytes(self) -> int:
        """Bytes the list holds."""
        return self._core.memory_bytes()

    def __repr__(self) -> str:
        return (f"broadphase.NeighbourList({self._quantities!r}, skin={self.skin}, "
                f"{self.candidates} candidates, {self.rebuilds} rebuilds)")
