"""broadphase: exact broad-phase collision detection for numpy arrays.

Finds every pair of overlapping spheres and axis-aligned boxes, exactly by
the library's contract: objects i and j are reported when the predicate of
docs/scene-format.md holds in double precision (float32 input is widened
exactly), touching counts, each pair once, as ``i < j``.

Arrays in, arrays out:

- ``centers`` is an (N, 3) array; ``radii`` a scalar or an (N,) array;
  ``half_extents`` an (N, 3) array; ``kinds`` an (N,) array of 0 (sphere)
  and 1 (box) when a set mixes both.
- float64 and float32 arrays are read in place, without a copy, whatever
  their strides (C or Fortran order, slices, read-only arrays). Anything
  else (lists, integers, other byte orders) is converted to float64 first.
- Pairs come back as an int64 (M, 2) array that owns its memory.
- NaN, infinities, negative radii and wrong shapes raise ValueError naming
  the argument and the index.
- Collision filters, optional on every call that builds pairs: ``groups``
  and ``masks``, (N,) arrays of 32-bit bits; objects i and j pair only when
  ``groups[i] & masks[j]`` and ``groups[j] & masks[i]`` are both non-zero
  (Bullet's group/mask, Box2D's category/mask). One of the two alone takes
  the default for the other (group 1, mask 0xffffffff).
- Every call releases the GIL while it runs.

>>> import numpy as np, broadphase
>>> c = np.array([[0, 0, 0], [1.5, 0, 0], [5, 0, 0]], dtype=float)
>>> broadphase.sphere_pairs(c, 1.0)
array([[0, 1]])
"""

from __future__ import annotations

from typing import Iterator, Optional, Sequence

import numpy as np

from . import _broadphase
from ._broadphase import IndexCore as _IndexCore
from . import ase, mdanalysis
from ._neighbours import NeighbourList, neighbor_list, neighbor_list_between
from ._knn import knn, within

__all__ = [
    "sphere_pairs",
    "box_pairs",
    "pairs",
    "pairs_between",
    "ray_cast",
    "Index",
    "to_sparse",
    "structures",
    "scratch_bytes",
    "set_scratch_limit",
    "neighbor_list",
    "neighbor_list_between",
    "NeighbourList",
    "ase",
    "mdanalysis",
    "knn",
    "within",
]
__version__ = "0.1.0"

_REALS = (np.dtype(np.float64), np.dtype(np.float32))


def _real(a, name: str):
    """`a` as a float64/float32 array the module can read in place, or a copy."""
    if isinstance(a, np.ndarray) and a.dtype in _REALS and a.dtype.isnative:
        return a
    try:
        return np.ascontiguousarray(a, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: cannot be read as numbers ({e})") from None


def _centers(a, name: str = "centers"):
    a = _real(a, name)
    if a.size == 0 and a.ndim != 2:
        a = a.reshape(0, 3)
    return a


def _radii(a, name: str = "radii"):
    if a is None:
        return None
    a = _real(a, name)
    if a.ndim == 1 and a.shape[0] == 1:
        # One radius for all, as a scalar would be.
        a = a.reshape(())
    return a


def _kinds(k):
    if k is None:
        return None
    k = np.asarray(k)
    if k.dtype != np.uint8 and k.dtype != np.bool_:
        if k.dtype.kind not in "iu":
            raise ValueError(f"kinds: expected integers 0 (sphere) and 1 (box), got dtype {k.dtype}")
        bad = np.flatnonzero((k < 0) | (k > 1)) if k.ndim == 1 else []
        if len(bad):
            raise ValueError(f"kinds[{bad[0]}] is {k[bad[0]]} (0 is a sphere, 1 a box)")
        k = k.astype(np.uint8)
    return k


def _ids(ids):
    a = np.asarray(ids)
    if a.ndim == 0:
        a = a.reshape(1)
    if a.size and a.dtype.kind not in "iu":
        raise ValueError(f"ids: expected integers, got dtype {a.dtype}")
    return np.ascontiguousarray(a, dtype=np.int64)


def _filter_column(a, name: str):
    if a is None:
        return None
    a = np.asarray(a)
    if a.dtype.kind not in "iu":
        raise ValueError(f"{name}: expected integers (32-bit filter bits), got dtype {a.dtype}")
    if a.ndim != 1:
        raise ValueError(f"{name}: expected shape (N,), got {a.shape}")
    if a.size:
        bad = np.flatnonzero((a < 0) | (a > 0xFFFFFFFF))
        if len(bad):
            raise ValueError(f"{name}[{bad[0]}] is {a[bad[0]]} (filter bits are 0 to 2**32 - 1)")
    return np.ascontiguousarray(a, dtype=np.uint32)


def _filters(groups, masks, n: int, prefix: str = ""):
    """(groups, masks) as uint32 (n,) arrays, or (None, None) for no filters."""
    if groups is None and masks is None:
        return None, None
    g = _filter_column(groups, prefix + "groups")
    m = _filter_column(masks, prefix + "masks")
    if g is None:
        g = np.ones(n, dtype=np.uint32)
    if m is None:
        m = np.full(n, 0xFFFFFFFF, dtype=np.uint32)
    for a, name in ((g, "groups"), (m, "masks")):
        if a.shape[0] != n:
            raise ValueError(
                f"{prefix}{name}: expected {n} values (one per object), got {a.shape[0]}")
    return g, m


def _periodic_cell(box, periodic):
    """(lengths, axes) of a periodic cell from ``box`` and ``periodic``."""
    if box is None:
        raise ValueError("box: periodic axes need the cell's lengths (box=(Lx, Ly, Lz))")
    try:
        b = np.asarray(box, dtype=np.float64)
    except (TypeError, ValueError) as e:
        raise ValueError(f"box: cannot be read as numbers ({e})") from None
    if b.ndim == 0:
        b = np.repeat(b, 3)
    if b.shape != (3,):
        raise ValueError(f"box: expected one length or three (Lx, Ly, Lz), got shape {b.shape}")
    axes = "xyz" if periodic is None else periodic
    if not isinstance(axes, str) or not axes:
        raise ValueError(f"periodic: expected letters among 'xyz', got {axes!r}")
    flags = [False, False, False]
    for ch in axes:
        if ch not in "xyz":
            raise ValueError(f"periodic: {ch!r} is not an axis (x, y or z)")
        if flags["xyz".index(ch)]:
            raise ValueError(f"periodic: axis {ch!r} given twice")
        flags["xyz".index(ch)] = True
    for a in range(3):
        if flags[a] and not (np.isfinite(b[a]) and b[a] > 0):
            raise ValueError(f"box[{a}]: the length of a periodic axis must be finite and "
                             f"positive, got {b[a]!r}")
    return [float(v) for v in b], flags


def _rows(centers) -> int:
    return int(centers.shape[0]) if centers.ndim >= 1 else 0


def _out(buf) -> np.ndarray:
    # numpy wraps the module's buffer without a copy; the buffer object is
    # the array's base and keeps the memory alive.
    return np.asarray(buf)


def pairs(
    centers,
    radii=None,
    half_extents=None,
    kinds=None,
    *,
    sorted: bool = False,
    threads: int = 1,
    groups=None,
    masks=None,
    box=None,
    periodic=None,
):
    """All overlapping pairs of a set of spheres and/or boxes.

    Args:
        centers: (N, 3) centres.
        radii: sphere radii, a scalar or (N,); None for a set of boxes.
        half_extents: (N, 3) box half-extents; None for a set of spheres.
        kinds: (N,) 0 for a sphere, 1 for a box, needed when both
            ``radii`` and ``half_extents`` are given (each object reads its own).
        sorted: sort the pairs by i, then j (otherwise a deterministic
            order that does not depend on ``threads``).
        threads: threads to use (1: the calling thread only; 0: every core).
        groups, masks: (N,) collision filter bits (see the module's
            documentation); None: every pair passes.
        box: a periodic cell ``(Lx, Ly, Lz)`` (or one length for a cube),
            the cell ``[0, L]`` per axis; None: no cell.
        periodic: the periodic axes of ``box``, letters among ``"xyz"``
            (``"xy"`` a slab, ``"x"`` a tube); default ``"xyz"``. On them
            every centre lies in ``[0, L]`` and every size is below ``L/2``.

    Returns:
        int64 array of shape (M, 2), each row ``i < j``. With ``box``, a
        tuple ``(pairs, shifts)``: ``shifts`` an int8 (M, 3) array S in
        {-1, 0, 1} per axis, row k meaning that object i overlaps object j
        moved by ``S * (Lx, Ly, Lz)`` (docs/periodic.md); a pair may come
        with two shifts near half the cell; each pair's shifts in
        increasing order of ``(Sx+1) + 3(Sy+1) + 9(Sz+1)``.

    Raises:
        ValueError: a wrong shape, NaN, infinity or negative size, filter
            columns of another length or of a non-integer dtype (the
            message names the argument and the index); with ``box``, a
            centre outside ``[0, L]`` or a size of ``L/2`` or more on a
            periodic axis, a bad length or axis.
    """
    c = _centers(centers)
    g, m = _filters(groups, masks, _rows(c))
    if box is not None or periodic is not None:
        lengths, axes = _periodic_cell(box, periodic)
        p, s = _broadphase.find_periodic_pairs(
            c,
            _radii(radii),
            None if half_extents is None else _real(half_extents, "half_extents"),
            _kinds(kinds),
            lengths,
            axes,
            bool(sorted),
            g,
            m,
        )
        return _out(p), _out(s).astype(np.int8)
    return _out(
        _broadphase.find_pairs(
            c,
            _radii(radii),
            None if half_extents is None else _real(half_extents, "half_extents"),
            _kinds(kinds),
            bool(sorted),
            int(threads),
            g,
            m,
        )
    )


def sphere_pairs(
    centers, radii, *, sorted: bool = False, threads: int = 1, groups=None, masks=None
) -> np.ndarray:
    """All overlapping pairs of spheres: ``|ci - cj|^2 <= (ri + rj)^2``.

    Args:
        centers: (N, 3) float64 or float32 array (any strides, read in place).
        radii: a scalar (one radius for all) or an (N,) array; 0 is a point.
        sorted: sort the pairs by i, then j.
        threads: threads to use (1: the calling thread; 0: every core).
        groups, masks: (N,) collision filter bits; None: every pair passes.

    Returns:
        int64 array of shape (M, 2), each row ``i < j``; touching counts.
    """
    if radii is None:
        raise ValueError("radii: give a scalar or one radius per sphere")
    return pairs(centers, radii, sorted=sorted, threads=threads, groups=groups, masks=masks)


def box_pairs(
    lo, hi, *, sorted: bool = False, threads: int = 1, groups=None, masks=None
) -> np.ndarray:
    """All overlapping pairs of axis-aligned boxes ``[lo, hi]``.

    The library holds a box as centre ``(lo + hi) / 2`` and half-extent
    ``(hi - lo) / 2`` (in double), and the exact contract applies to those.
    When a corner is not representable after that rounding, two boxes that
    just touch in lo/hi may round either way; to give the exact numbers,
    call ``pairs(centers, half_extents=...)``.

    Args:
        lo, hi: (N, 3) corners, ``hi >= lo``.
        sorted, threads, groups, masks: as for :func:`sphere_pairs`.

    Returns:
        int64 array of shape (M, 2), each row ``i < j``; touching counts.
    """
    lo = _centers(lo, "lo").astype(np.float64, copy=False)
    hi = _centers(hi, "hi").astype(np.float64, copy=False)
    if lo.shape != hi.shape:
        raise ValueError(f"lo and hi: shapes differ ({lo.shape} and {hi.shape})")
    if lo.ndim == 2 and lo.shape[1] == 3:
        with np.errstate(invalid="ignore"):
            bad = np.argwhere(hi < lo)
        if len(bad):
            i, a = bad[0]
            raise ValueError(f"hi[{i}, {a}] < lo[{i}, {a}] ({hi[i, a]!r} < {lo[i, a]!r})")
    return pairs((lo + hi) / 2, half_extents=(hi - lo) / 2, sorted=sorted, threads=threads,
                 groups=groups, masks=masks)


def pairs_between(
    centers,
    radii=None,
    other_centers=None,
    other_radii=None,
    *,
    half_extents=None,
    kinds=None,
    other_half_extents=None,
    other_kinds=None,
    threads: int = 1,
    groups=None,
    masks=None,
    other_groups=None,
    other_masks=None,
) -> np.ndarray:
    """Overlapping pairs between two sets (bipartite), one-shot.

    ``groups``/``masks`` and ``other_groups``/``other_masks`` are each set's
    collision filter bits (None: the default filter for that set).

    Returns:
        int64 (M, 2) array of ``(i, j)``, i a row of the first set, j of
        the second, sorted by i then j.
    """
    if other_centers is None:
        raise ValueError("other_centers: the second set is missing")
    c = _centers(centers)
    oc = _centers(other_centers, "other_centers")
    g, m = _filters(groups, masks, _rows(c))
    og, om = _filters(other_groups, other_masks, _rows(oc), "other_")
    return _out(
        _broadphase.find_pairs_between(
            c,
            _radii(radii),
            None if half_extents is None else _real(half_extents, "half_extents"),
            _kinds(kinds),
            oc,
            _radii(other_radii, "other_radii"),
            None if other_half_extents is None else _real(other_half_extents, "other_half_extents"),
            _kinds(other_kinds),
            int(threads),
            g,
            m,
            og,
            om,
        )
    )


def _ray_result(out, all_hits: bool):
    # t comes as the bit patterns of its doubles (int64), viewed as float64.
    if all_hits:
        offsets, ids, t = out
        return _out(offsets), _out(ids), _out(t).view(np.float64)
    ids, t = out
    return _out(ids), _out(t).view(np.float64)


def _ray_args(origins, directions, tmax, ray_masks):
    o = _centers(origins, "origins")
    d = _centers(directions, "directions")
    t = None if tmax is None else _real(tmax, "tmax")
    m = None if ray_masks is None else _filter_column(ray_masks, "ray_masks")
    return o, d, t, m


def ray_cast(
    centers,
    radii=None,
    half_extents=None,
    kinds=None,
    *,
    origins,
    directions,
    tmax=None,
    groups=None,
    masks=None,
    ray_masks=None,
    all_hits: bool = False,
    threads: int = 1,
    structure: str = "",
):
    """Casts rays into a set of spheres and/or boxes, exactly by the
    contract's ray test (docs/scene-format.md, "Rays").

    A ray is the points ``origins[r] + t * directions[r]`` for
    ``0 <= t <= tmax[r]``; a ray starting inside an object hits it at
    ``t = 0``, and a hit at exactly ``tmax`` counts.

    Args:
        centers, radii, half_extents, kinds: the objects, as for :func:`pairs`.
        origins, directions: (R, 3) rays (a direction need not be of unit
            length; zero is allowed).
        tmax: scalar or (R,), ``>= 0``; None: no limit (infinity).
        groups, masks: the objects' collision filters, as for :func:`pairs`
            (only ``groups`` matters to rays).
        ray_masks: (R,) bits; a ray sees an object when ``groups & mask``
            is non-zero. None: every object.
        all_hits: every hit of each ray instead of the closest.
        threads: threads sharing the rays (the results do not depend on it).
        structure: the structure built over the objects: ``"lean"`` for the
            lean path's grid (the quickest to build), a library structure by
            name, or ``""`` (the default): the lean grid for fewer rays than
            half the objects, else the k-d tree (the fastest to cast of ours
            measured). The results are the same whichever.

    Returns:
        ``(ids, t)``: the closest hit of each ray (smallest t, then smallest
        id), int64 and float64 (R,) arrays, ``-1`` and ``inf`` where a ray
        hits nothing. With ``all_hits``: ``(offsets, ids, t)`` in CSR form,
        the hits of ray r at ``offsets[r]:offsets[r + 1]``, sorted by t then id.

    Raises:
        ValueError: bad objects as for :func:`pairs`; a NaN or infinite
            origin or direction, a direction whose squared length overflows
            or underflows, a NaN or negative tmax (naming the ray).
    """
    c = _centers(centers)
    g, m = _filters(groups, masks, _rows(c))
    o, d, t, rm = _ray_args(origins, directions, tmax, ray_masks)
    out = _broadphase.ray_cast(
        c,
        _radii(radii),
        None if half_extents is None else _real(half_extents, "half_extents"),
        _kinds(kinds),
        g,
        m,
        o,
        d,
        t,
        rm,
        bool(all_hits),
        int(threads),
        str(structure),
    )
    return _ray_result(out, all_hits)


def structures() -> list:
    """The library's structures by name: a list of (name, description).

    Any of these names, with options after a colon
    (``"grid-verlet:threads=2"``), can back an :class:`Index`.
    """
    return list(_broadphase.structures())


def scratch_bytes() -> int:
    """Bytes of freed memory kept for the next call.

    A call's working arrays of 2 MiB and more and the memory of the last
    freed result array of 4 MiB and more are kept, not returned to the
    system, so that the next call finds its pages in place instead of
    fresh ones the kernel clears (at 10^6 spheres that clearing was about a
    quarter of :func:`sphere_pairs`). Working arrays are kept at most 2
    seconds. See :func:`set_scratch_limit`.
    """
    return int(_broadphase.scratch_bytes())


def set_scratch_limit(limit: int) -> None:
    """Keep at most ``limit`` bytes of working arrays, and a result array's
    memory only up to ``limit`` bytes (512 MiB each by default).

    ``set_scratch_limit(0)`` keeps nothing and returns what is kept now.
    Raises ValueError for a negative limit.
    """
    _broadphase.set_scratch_limit(_byte_count(limit, "limit"))


def _byte_count(value, name: str) -> int:
    """`value` as an int of 0 or more, else ValueError naming `name`."""
    try:
        value = int(value)
    except (TypeError, ValueError) as e:
        raise ValueError(f"{name}: not an integer ({e})") from None
    if value < 0:
        raise ValueError(f"{name}: negative ({value})")
    return value


class Index:
    """A set of spheres and/or boxes that moves, and its overlapping pairs.

    Objects are named by ids: 0..N-1 for the arrays given here, then new,
    increasing ids for :meth:`insert` (an id is never reused after
    :meth:`remove`). Pairs are ``(i, j)`` ids with ``i < j``.

    Storage, default structure (``structure=None``, the lean path over the
    caller's arrays, with a Verlet-skin pair tracker):

    - **borrowing** (as built): the index reads *your* arrays in place, with
      no copy, and keeps them alive. Move objects in your arrays and call
      ``update()`` (or ``update(ids)`` for the ones you moved), or hand new
      arrays with ``update(centers)``. A borrowing index cannot change its
      number of objects. Do not change the arrays between an update and the
      queries that follow except through ``update``.
    - **owning**: :meth:`insert`, :meth:`remove` and ``update(ids, centers)``
      first copy the objects into the index's own storage (once); from then
      on your arrays are no longer read. :attr:`borrowing` tells which.

    With a structure name (any of :func:`structures`, options after a colon,
    e.g. ``"grid-verlet:threads=2"``), the structure always owns copies.

    The pairs are found when the index changes (lean path) or at the first
    query after a change (named structures), then kept: :meth:`pairs`,
    :meth:`count_pairs` and :meth:`iter_pairs` read that list.

    Thread safety: queries (:meth:`pairs`, :meth:`count_pairs`,
    :meth:`iter_pairs`, :meth:`query`, :meth:`query_box`, :meth:`ids`) may run
    from several Python threads at once; each releases the GIL. Mutations
    (:meth:`update`, :meth:`insert`, :meth:`remove`) need exclusive use: one
    that overlaps any other call on the same index raises RuntimeError
    (nothing is changed), as does a query that overlaps a mutation.
    """

    def __init__(
        self,
        centers,
        radii=None,
        half_extents=None,
        kinds=None,
        *,
        structure: Optional[str] = None,
        threads: int = 1,
        skin: float = 0.0,
        spare_bytes: int = 0,
        groups=None,
        masks=None,
    ):
        """Builds the index and finds its pairs.

        Args:
            centers: (N, 3) centres (borrowed when float64/float32).
            radii: scalar or (N,) sphere radii; None for boxes only.
            half_extents: (N, 3) box half-extents; None for spheres only.
            kinds: (N,) 0 sphere / 1 box when both sizes are given.
            structure: None for the lean path (borrows your arrays), or a
                library structure by name with options (owns copies).
            threads: threads of the lean path (1: calling thread; 0: all).
            skin: Verlet skin of the lean tracker relative to the typical
                object size (0: the library's default).
            spare_bytes: the most bytes the lean tracker keeps beyond its
                leanest form where they buy speed, in worlds whose still
                objects overlap often (0: the library's default, 16 MiB;
                ``ArrayOptions::spare_bytes``, docs/arrays.md). More is
                faster on large crowded worlds if the memory is there.
            groups, masks: (N,) collision filter bits (copied; change them
                with :meth:`set_filters`); None: every pair passes. The
                index's :meth:`query` is not filtered.

        Raises:
            ValueError: bad arrays (see :func:`find_pairs`), a negative
                ``spare_bytes``, or a ``skin`` that is NaN, negative or
                infinite.
        """
        # The compiled index holds buffer views of the arrays it borrows,
        # which keep them alive (and numpy from resizing them).
        c = _centers(centers)
        g, m = _filters(groups, masks, _rows(c))
        self._core = _IndexCore(
            c, _radii(radii),
            None if half_extents is None else _real(half_extents, "half_extents"), _kinds(kinds),
            structure or "", int(threads), float(skin), _byte_count(spare_bytes, "spare_bytes"),
            g, m)

    # -- what it is -------------------------------------------------------

    @property
    def structure(self) -> str:
        """The structure's name ("lean" for the default path)."""
        return self._core.structure()

    @property
    def borrowing(self) -> bool:
        """True while the index reads the caller's arrays in place."""
        return self._core.borrowing()

    def __len__(self) -> int:
        """The number of objects."""
        return self._core.size()

    def ids(self) -> np.ndarray:
        """The ids of the objects, increasing (int64)."""
        return _out(self._core.ids())

    def memory_bytes(self) -> int:
        """Bytes the index holds (its own data; borrowed arrays excluded)."""
        return self._core.memory_bytes()

    def validate(self) -> None:
        """Checks the index's invariants; raises RuntimeError if one fails."""
        self._core.validate()

    # -- mutations (exclusive use) -----------------------------------------

    def update(self, a=None, b=None, *, radii=None, half_extents=None) -> None:
        """Moves objects (and may resize them); then finds the pairs again.

        Forms:
            ``update()``: a borrowing index re-reads your arrays, which you
                changed in place; every object may have moved.
            ``update(ids)``: as above, only the objects ``ids`` moved
                (a 1-D integer array).
            ``update(centers, radii=None)``: every object moved; ``centers``
                is (N, 3), one row per id in increasing id order. A borrowing
                index borrows the new arrays (same N); an owning one copies.
            ``update(ids, centers, radii=None)``: objects ``ids`` moved to
                ``centers`` (len(ids), 3). Makes the index owning.

        Sizes (``radii`` for spheres, ``half_extents`` for boxes) are kept
        when not given. Raises ValueError for bad input, RuntimeError when
        another call is using the index.
        """
        hx = None if half_extents is None else _real(half_extents, "half_extents")
        r = _radii(radii)
        if a is None:
            if b is not None:
                raise ValueError("update: centers given without ids")
            self._core.update_in_place(None)
            return
        if b is None and np.ndim(a) == 1:
            self._core.update_in_place(_ids(a))
            return
        if b is None:
            self._core.update_all(_centers(a), r, hx)
            return
        if np.ndim(a) == 2 and np.ndim(b) <= 1:
            # update(centers, radii) positionally.
            self.update(a, radii=b, half_extents=half_extents)
            return
        self._core.update_ids(_ids(a), _centers(b), r, hx)

    def insert(
        self, centers, radii=None, half_extents=None, kinds=None, *, groups=None, masks=None
    ) -> np.ndarray:
        """Adds objects; returns their new ids (int64). Makes the index owning
        (the lean path copies your arrays once). ``groups``/``masks``: the new
        objects' collision filter bits (None: the default filter)."""
        c = _centers(centers)
        g, m = _filters(groups, masks, _rows(c))
        return _out(self._core.insert(
            c, _radii(radii),
            None if half_extents is None else _real(half_extents, "half_extents"), _kinds(kinds),
            g, m))

    def set_filters(self, ids=None, *, groups=None, masks=None) -> None:
        """Changes collision filters: object ``ids[k]`` takes ``groups[k]``
        and ``masks[k]`` (with ``ids`` None, every live object in increasing
        id order); one of the two alone leaves the default for the other.
        The pairs are found again at once (a mutation, as :meth:`update`)."""
        n = len(self) if ids is None else _ids(ids).shape[0]
        g, m = _filters(groups, masks, n)
        if g is None:
            raise ValueError("set_filters: give groups, masks or both")
        self._core.set_filters(None if ids is None else _ids(ids), g, m)

    def remove(self, ids) -> None:
        """Removes the objects ``ids`` (their ids are not reused). Makes the
        index owning (the lean path copies your arrays once)."""
        self._core.remove(_ids(ids))

    # -- queries (may run concurrently) --------------------------------------

    def pairs(self, *, sorted: bool = False) -> np.ndarray:
        """The overlapping pairs as an int64 (M, 2) array of ids, ``i < j``
        (sorted by i then j when ``sorted``). The array owns its memory."""
        return _out(self._core.pairs(bool(sorted)))

    def count_pairs(self) -> int:
        """The number of overlapping pairs (no array is made)."""
        return self._core.count_pairs()

    def iter_pairs(self, chunk: int = 1 << 20) -> Iterator[np.ndarray]:
        """The pairs in int64 (<= chunk, 2) arrays, so that the (M, 2) array
        never exists at once (the index's own list takes 8 bytes per pair, the
        full array 16). Iterates a snapshot: later mutations do not change it."""
        it = self._core.iter_pairs(int(chunk))
        for buf in it:
            yield _out(buf)

    def query(
        self,
        other_centers,
        other_radii=None,
        *,
        half_extents=None,
        kinds=None,
        output: str = "pairs",
    ):
        """Which objects of the index overlap each object of another set.

        Args:
            other_centers: (Q, 3) centres of the query objects.
            other_radii: their radii (scalar or (Q,)), or None for boxes.
            half_extents, kinds: the query objects' box half-extents and
                kinds, as for :func:`pairs`.
            output: ``"pairs"`` or ``"csr"``.

        Returns:
            ``"pairs"``: int64 (M, 2) rows ``(q, id)``, q the query row and id
            an object of the index, sorted by q then id.
            ``"csr"``: ``(indptr, indices)``: the ids overlapping query q are
            ``indices[indptr[q]:indptr[q + 1]]``, increasing.
        """
        if output not in ("pairs", "csr"):
            raise ValueError(f"output: 'pairs' or 'csr', not {output!r}")
        oc = _centers(other_centers, "other_centers")
        p = _out(self._core.query(
            oc, _radii(other_radii, "other_radii"),
            None if half_extents is None else _real(half_extents, "other_half_extents"),
            _kinds(kinds)))
        if output == "pairs":
            return p
        q = oc.shape[0]
        indptr = np.zeros(q + 1, dtype=np.int64)
        np.cumsum(np.bincount(p[:, 0], minlength=q), out=indptr[1:])
        return indptr, np.ascontiguousarray(p[:, 1])

    def ray_cast(
        self,
        origins,
        directions,
        tmax=None,
        *,
        ray_masks=None,
        all_hits: bool = False,
        threads: int = 1,
    ):
        """Casts rays into the index's objects; arguments and results as for
        :func:`ray_cast` (ids are the index's ids). An index built with a
        ``structure`` walks it; a lean index casts through its tracker's
        grid, built at the first cast after a change and kept until the next
        (casts from several threads share it)."""
        o, d, t, rm = _ray_args(origins, directions, tmax, ray_masks)
        return _ray_result(
            self._core.ray_cast(o, d, t, rm, bool(all_hits), int(threads)), all_hits)

    def query_box(self, lo: Sequence[float], hi: Sequence[float]) -> np.ndarray:
        """The ids of the objects that overlap the box [lo, hi], increasing."""
        return _out(self._core.query_box([float(v) for v in lo], [float(v) for v in hi]))

    def __repr__(self) -> str:
        return (f"broadphase.Index({len(self)} objects, structure={self.structure!r}, "
                f"{'borrowing' if self.borrowing else 'owning'})")


def to_sparse(pair_array, n: Optional[int] = None, *, format: str = "csr", symmetric: bool = True):
    """The pairs as a scipy.sparse n x n matrix of ones (needs scipy).

    Args:
        pair_array: (M, 2) integer array, as the functions here return.
        n: the matrix size (default: the largest index + 1).
        format: ``"csr"`` or ``"coo"``.
        symmetric: put each pair at (i, j) and (j, i) (an adjacency matrix);
            False: at (i, j) only (upper triangle).
    """
    import scipy.sparse as sp

    p = np.asarray(pair_array)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ValueError(f"pair_array: expected shape (M, 2), got {p.shape}")
    if n is None:
        n = int(p.max()) + 1 if p.size else 0
    i, j = p[:, 0], p[:, 1]
    if symmetric:
        i, j = np.concatenate([i, j]), np.concatenate([j, i])
    m = sp.coo_matrix((np.ones(len(i), dtype=np.int8), (i, j)), shape=(n, n))
    if format == "coo":
        return m
    if format == "csr":
        return m.tocsr()
    raise ValueError(f"format: 'csr' or 'coo', not {format!r}")


def __dir__() -> list:
    # dir(broadphase) lists the API only: the modules and typing names the
    # code above uses (numpy as np, Optional, ...) stay importable attributes
    # but are not offered.
    return sorted(__all__ + ["__version__"])
