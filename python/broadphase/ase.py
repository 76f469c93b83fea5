"""Drop-in replacements for ``ase.neighborlist.neighbor_list`` and
``primitive_neighbor_list``: the same signatures, quantities and output
order (sorted by i; within i, by j then S), the same neighbours::

    from broadphase.ase import neighbor_list   # was: from ase.neighborlist import ...
    i, j, S = neighbor_list('ijS', atoms, 3.0)

ASE's rule at the cutoff is ``|d| < cutoff`` (``< c_i + c_j`` per atom), and
so is this one (``strict``). ASE computes ``d`` as ``sqrt(sum(D*D))`` with
``D = x_j - x_i + S @ cell``; here ``D = (x_j + S @ cell) - x_i`` in the
order of docs/neighbours.md, so a distance within a rounding of the cutoff
may be decided the other way. ASE itself is not imported (except for an
element-pair cutoff dict with element symbols).
"""

from __future__ import annotations

import numpy as _np

from ._neighbours import neighbor_list as _neighbor_list

__all__ = ["neighbor_list", "primitive_neighbor_list"]


def primitive_neighbor_list(quantities, pbc, cell, positions, cutoff, numbers=None,
                            self_interaction=False, use_scaled_positions=False, max_nbins=1e6):
    """As ``ase.neighborlist.primitive_neighbor_list``: ``quantities`` of
    ``i``, ``j``, ``D``, ``d``, ``S``; ``cutoff`` a number, per-atom radii,
    or a dict ``{(a, b): cutoff}`` of element pairs (needs ``numbers``).
    ``max_nbins`` is accepted and not needed (the bins are sized to the
    points)."""
    for q in quantities:
        if q not in "ijdDS":
            raise ValueError("Unsupported quantity specified.")
    cell = _np.asarray(cell, dtype=_np.float64)
    positions = _np.asarray(positions, dtype=_np.float64)
    if use_scaled_positions:
        positions = _np.dot(positions, cell)
    if isinstance(cutoff, dict):
        return _by_element_pair(quantities, pbc, cell, positions, cutoff, numbers,
                                self_interaction)
    return _neighbor_list(quantities, positions, cutoff, cell=cell, pbc=pbc, full=True,
                          self_interaction=self_interaction, strict=True)


def neighbor_list(quantities, a, cutoff, self_interaction=False, max_nbins=1e6):
    """As ``ase.neighborlist.neighbor_list(quantities, a, cutoff,
    self_interaction=False)``: the full list of the atoms ``a`` (both
    directions), sorted by i."""
    return primitive_neighbor_list(quantities, a.pbc, a.get_cell(complete=True), a.positions,
                                   cutoff, numbers=a.numbers, self_interaction=self_interaction,
                                   max_nbins=max_nbins)


def _by_element_pair(quantities, pbc, cell, positions, cutoff, numbers, self_interaction):
    """ASE's dict cutoff: the list at the largest cutoff, then each pair
    against the cutoff of its two elements (0 for pairs not in the dict)."""
    if numbers is None:
        raise ValueError("cutoff: a dict of element pairs needs the atomic numbers")
    numbers = _np.asarray(numbers)
    largest = max(cutoff.values()) if cutoff else 0.0
    i, j, S, d, D = _neighbor_list("ijSdD", positions, largest, cell=cell, pbc=pbc, full=True,
                                   self_interaction=self_interaction, strict=True)
    per_pair = _np.zeros_like(d)
    for (z1, z2), c in cutoff.items():
        z1, z2 = _number(z1), _number(z2)
        ni, nj = numbers[i], numbers[j]
        if z1 == z2:
            m = (ni == z1) & (nj == z2)
        else:
            m = ((ni == z1) & (nj == z2)) | ((ni == z2) & (nj == z1))
        per_pair[m] = c
    keep = d < per_pair
    found = {"i": i[keep], "j": j[keep], "S": S[keep], "d": d[keep], "D": D[keep]}
    r = tuple(found[q] for q in quantities)
    return r[0] if len(r) == 1 else r


def _number(z):
    if isinstance(z, str):
        from ase.data import atomic_numbers

        return atomic_numbers[z]
    return z
