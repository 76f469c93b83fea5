"""broadphase.NeighbourList (a neighbour list with a skin, reused over
frames) against the one-shot broadphase.neighbor_list on every frame of
random walks (free, orthorhombic, triclinic and mixed cells; small moves,
jumps, points wrapped into the cell or left outside; one and per-point
cutoffs; half and full; strict; float32), and against ASE's neighbor_list
on a rattled crystal. Seeds are in the test ids."""

import numpy as np
import pytest

import broadphase

from conftest import QUICK

SEEDS = range(4) if QUICK else range(16)


def _case(rng):
    kind = rng.integers(4)
    small = rng.random() < 0.25
    l = 2.5 if small else 8.0 + 4.0 * rng.random()
    if kind == 0:
        cell, pbc = None, False
        basis = np.eye(3) * 8.0
    elif kind == 1:
        basis = np.diag([l, l * (0.8 + 0.4 * rng.random()), l * (0.8 + 0.4 * rng.random())])
        cell, pbc = basis, [True, True, True]
    else:
        basis = np.array([[l, 0, 0], [0.3 * l * (rng.random() - 0.5), l, 0],
                          [0.3 * l * (rng.random() - 0.5), 0.3 * l * (rng.random() - 0.5), l]])
        cell, pbc = basis, [True, True, True]
    if kind != 0 and rng.random() < 0.3:
        pbc = [bool(v) for v in rng.integers(2, size=3)]
    n = int(rng.integers(20, 120))
    cutoff = 1.5 + rng.random() if small else 1.0 + 1.5 * rng.random()
    if rng.random() < 0.3:
        cutoff = (0.3 + 0.5 * rng.random(n)) * cutoff
    x = (1.2 * rng.random((n, 3)) - 0.1) @ basis
    return cell, pbc, cutoff, x


def _wrap(x, cell, pbc):
    c = np.asarray(cell, dtype=np.float64)
    s = x @ np.linalg.inv(c)
    s = np.where(pbc, np.floor(s), 0.0)
    return x - s @ c


@pytest.mark.parametrize("seed", SEEDS)
def test_frames_match_the_one_shot_list(seed):
    rng = np.random.default_rng(seed)
    cell, pbc, cutoff, x = _case(rng)
    kw = dict(cell=cell, pbc=pbc, full=bool(rng.integers(2)), strict=bool(rng.integers(2)),
              self_interaction=rng.random() < 0.25)
    skin = float((0.05 + 0.4 * rng.random()) * np.max(cutoff))
    f32 = rng.random() < 0.25
    nl = broadphase.NeighbourList("ijSdDo", cutoff, skin=skin, **kw)
    frames = 30
    for frame in range(frames):
        if frame:
            x = x + rng.normal(0, 0.03 * skin, x.shape)
            if rng.random() < 0.05:
                k = rng.integers(len(x), size=3)
                x[k] += (rng.random((3, 3)) - 0.5) * 6.0
            if cell is not None and any(pbc) and rng.random() < 0.5:
                x = _wrap(x, cell, pbc)
        p = x.astype(np.float32) if f32 else x
        want = broadphase.neighbor_list("ijSdDo", p, cutoff, **kw)
        got = nl.update(p)
        for name, a, b in zip("ijSdDo", got, want):
            assert a.dtype == b.dtype and a.shape == b.shape, (seed, frame, name)
            assert np.array_equal(a, b), (seed, frame, name)
    assert 1 <= nl.rebuilds < frames // 2, (seed, nl.rebuilds)


def test_same_neighbours_as_ase_over_frames():
    ase_build = pytest.importorskip("ase.build")
    ase_nl = pytest.importorskip("ase.neighborlist")
    atoms = ase_build.bulk("Cu", "fcc", a=3.6).repeat((4, 3, 3))  # triclinic cell
    rng = np.random.default_rng(44)
    cutoff = 3.0
    nl = broadphase.NeighbourList("ijSd", cutoff, skin=0.4, cell=np.asarray(atoms.cell),
                                  pbc=atoms.pbc, full=True, strict=True)
    velocity = rng.normal(0, 0.02, (len(atoms), 3))
    for frame in range(12):
        atoms.positions += velocity
        if frame % 4 == 3:
            atoms.wrap()
        i, j, S, d = nl.update(atoms)
        ri, rj, rS, rd = ase_nl.neighbor_list("ijSd", atoms, cutoff)
        keep = np.abs(d - cutoff) > 1e-9
        rkeep = np.abs(rd - cutoff) > 1e-9
        got = {(a, b, *s) for a, b, s in zip(i[keep], j[keep], S[keep].tolist())}
        want = {(a, b, *s) for a, b, s in zip(ri[rkeep], rj[rkeep], rS[rkeep].tolist())}
        assert got == want and len(got) > 0, frame
        assert len(i) - keep.sum() < 4
    assert nl.rebuilds < 12


def test_skin_default_and_reuse():
    x = np.random.default_rng(1).random((200, 3)) * 10
    nl = broadphase.NeighbourList("ij", 2.0, cell=10.0)
    assert nl.skin == pytest.approx(0.6)
    for _ in range(5):
        i, j = nl.update(x)
        x += 0.001
    assert nl.rebuilds == 1 and nl.candidates >= len(i) and nl.memory_bytes() > 0
    assert "NeighbourList" in repr(nl)
    one = broadphase.NeighbourList("j", 2.0, cell=10.0).update(x)
    assert isinstance(one, np.ndarray)


@pytest.mark.parametrize("make,message", [
    (lambda: broadphase.NeighbourList("ijX", 1.0), "quantities"),
    (lambda: broadphase.NeighbourList("ij", float("nan")), "cutoff"),
    (lambda: broadphase.NeighbourList("ij", 1.0, skin=float("nan")), "skin"),
    (lambda: broadphase.NeighbourList("ij", 1.0, skin=-0.5), "skin"),
    (lambda: broadphase.NeighbourList("ij", 1.0, skin="a"), "skin"),
    (lambda: broadphase.NeighbourList("ij", [1.0, -1.0]), "cutoffs[1]"),
    (lambda: broadphase.NeighbourList("ij", 1.0, cell=[[1, 0, 0], [1, 0, 0], [0, 0, 1]]), "cell"),
    (lambda: broadphase.NeighbourList("ij", [1.0, 1.0]).update(np.zeros((3, 3))), "per-point"),
    (lambda: broadphase.NeighbourList("ij", 1.0).update(np.zeros((3, 2))), "positions"),
    (lambda: broadphase.NeighbourList("ij", 1.0).update([[0, 0, float("inf")]]), "positions[0, 2]"),
])
def test_bad_input_raises_value_error(make, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]")):
        make()


def test_atoms_with_another_cell_is_refused():
    ase_build = pytest.importorskip("ase.build")
    atoms = ase_build.bulk("Cu", "fcc", a=3.6, cubic=True)
    nl = broadphase.NeighbourList("ij", 3.0, cell=np.asarray(atoms.cell), pbc=True)
    assert len(nl.update(atoms)[0]) > 0
    atoms.set_cell(atoms.cell * 1.1)
    with pytest.raises(ValueError, match="cell or pbc"):
        nl.update(atoms)
