"""Shared helpers of the broadphase Python tests: the O(N^2) oracle, the
scene reader and replay of docs/scene-format.md, the pair hash."""

import os
import pathlib

import numpy as np
import pytest

DATA = pathlib.Path(os.environ.get("BROADPHASE_TEST_DATA",
                                   pathlib.Path(__file__).resolve().parents[2] / "tests" / "data"))
# Set under the sanitizers, where everything runs several times slower.
QUICK = os.environ.get("BROADPHASE_TEST_QUICK") == "1"


def oracle_pairs(centers, radii=None, half=None, kinds=None, shift=None):
    """Every pair i < j the contract reports, by brute force in numpy, with
    the predicates' arithmetic exactly as written (one IEEE operation per
    ufunc, so nothing is contracted into an FMA). With ``shift`` (three
    numbers), j's centre is moved by it first (a periodic pair's S·L)."""
    c = np.asarray(centers, dtype=np.float64).reshape(-1, 3)
    n = len(c)
    if n < 2:
        return np.zeros((0, 2), dtype=np.int64)
    if kinds is None:
        kinds = np.zeros(n, np.uint8) if radii is not None else np.ones(n, np.uint8)
    kinds = np.asarray(kinds)
    r = np.zeros(n) if radii is None else np.broadcast_to(np.asarray(radii, np.float64), (n,))
    h = np.zeros((n, 3)) if half is None else np.asarray(half, np.float64).reshape(n, 3)
    i, j = np.triu_indices(n, 1)
    ci, cj = c[i], c[j]
    if shift is not None:
        cj = cj + np.asarray(shift, dtype=np.float64)
    ki, kj = kinds[i], kinds[j]
    # sphere-sphere
    dx = ci[:, 0] - cj[:, 0]
    dy = ci[:, 1] - cj[:, 1]
    dz = ci[:, 2] - cj[:, 2]
    d2 = dx * dx + dy * dy + dz * dz
    s = r[i] + r[j]
    ss = d2 <= s * s
    # box-box
    bb = np.ones(len(i), bool)
    for a in range(3):
        bb &= np.abs(ci[:, a] - cj[:, a]) <= h[i, a] + h[j, a]
    # sphere-box, sphere first
    def sb(cs, rs, cb, hb):
        d2 = np.zeros(len(cs))
        for a in range(3):
            e = np.abs(cs[:, a] - cb[:, a]) - hb[:, a]
            d2 = d2 + np.where(e > 0, e * e, 0.0)
        return d2 <= rs * rs
    sbx = sb(ci, r[i], cj, h[j])
    bsx = sb(cj, r[j], ci, h[i])
    hit = np.where((ki == 0) & (kj == 0), ss,
                   np.where((ki == 1) & (kj == 1), bb, np.where(ki == 0, sbx, bsx)))
    return np.stack([i[hit], j[hit]], axis=1).astype(np.int64)


def as_set(p):
    p = np.asarray(p)
    assert p.ndim == 2 and p.shape[1] == 2, p.shape
    assert (p[:, 0] < p[:, 1]).all(), "pairs must be i < j"
    s = set(map(tuple, p.tolist()))
    assert len(s) == len(p), "a pair reported twice"
    return s


def splitmix64(x):
    x = np.asarray(x, dtype=np.uint64)
    with np.errstate(over="ignore"):
        z = x + np.uint64(0x9E3779B97F4A7C15)
        z = (z ^ (z >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
        z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))


def pair_hash(p):
    """The frame hash of docs/scene-format.md: the sum mod 2^64 of splitmix64(i << 32 | j)."""
    p = np.asarray(p, dtype=np.uint64).reshape(-1, 2)
    keys = (p[:, 0] << np.uint64(32)) | p[:, 1]
    with np.errstate(over="ignore"):
        return int(splitmix64(keys).sum(dtype=np.uint64)) if len(p) else 0


class Scene:
    """A scene file (version 1 or 2) read into arrays."""

    def __init__(self, path):
        lines = [ln.strip() for ln in pathlib.Path(path).read_text().splitlines()]
        header, rest = lines[0], [ln for ln in lines[1:] if ln and not ln.startswith("#")]
        assert header in ("broadphase-scene 1", "broadphase-scene 2"), header
        version = int(header.split()[1])
        assert rest[0].split()[0] == "world" and rest[1].split()[0] == "objects"
        self.world = float(rest[0].split()[1])
        n = int(rest[1].split()[1])
        rows = [ln.split() for ln in rest[2:]]
        assert len(rows) == n
        self.kinds = np.zeros(n, np.uint8)
        self.centers = np.zeros((n, 3))
        self.radii = np.zeros(n)
        self.half = np.zeros((n, 3))
        self.vel = np.zeros((n, 3))
        for k, f in enumerate(rows):
            if version == 1:
                f = ["sphere"] + f
            if f[0] == "sphere":
                assert len(f) == 8
                self.centers[k] = [float(v) for v in f[1:4]]
                self.radii[k] = float(f[4])
                self.vel[k] = [float(v) for v in f[5:8]]
            else:
                assert f[0] == "box" and len(f) == 10
                self.kinds[k] = 1
                self.centers[k] = [float(v) for v in f[1:4]]
                self.half[k] = [float(v) for v in f[4:7]]
                self.vel[k] = [float(v) for v in f[7:10]]
        self.moving = np.flatnonzero((self.vel != 0).any(axis=1))

    @property
    def mixed(self):
        return bool(self.kinds.any())

    def step(self, centers):
        """One frame of motion in place: p += v, then the reflection at the walls."""
        L = self.world
        m = self.moving
        p = centers[m]
        v = self.vel[m]
        p += v
        lo = p < 0
        hi = p > L
        p[lo] = -p[lo]
        p[hi] = 2 * L - p[hi]
        v[lo | hi] = -v[lo | hi]
        centers[m] = p
        self.vel[m] = v


def read_expected(path):
    out = []
    for ln in pathlib.Path(path).read_text().split("\n"):
        if ln.strip():
            f, n, h = ln.split()
            out.append((int(f), int(n), int(h, 16)))
    return out


def scene_files():
    return sorted((DATA / "scenes").glob("*.scene"))


@pytest.fixture
def rng(request):
    """A seeded generator; the seed is printed (pytest shows it on failure)."""
    seed = int(os.environ.get("BROADPHASE_TEST_SEED", np.random.SeedSequence().entropy % (1 << 32)))
    print(f"seed {seed} (rerun with BROADPHASE_TEST_SEED={seed})")
    return np.random.default_rng(seed)
