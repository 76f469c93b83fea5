"""The reference scenes replayed from Python: same per-frame pair counts and
hashes as the brute-force *.expected files, for the lean index (objects moved
in place in the borrowed arrays, and new arrays each frame), the one-shot
call, and every library structure."""

import pytest

import broadphase
from conftest import QUICK, Scene, as_set, pair_hash, read_expected, scene_files

SCENES = scene_files()


def sizes(scene, centers):
    if scene.mixed:
        return dict(radii=scene.radii, half_extents=scene.half, kinds=scene.kinds)
    return dict(radii=scene.radii)


def check(expected, frame, p):
    f, n, h = expected[frame]
    assert f == frame
    as_set(p)
    assert (len(p), pair_hash(p)) == (n, h), f"frame {frame}: got {len(p)} {pair_hash(p):016x}"


def test_scenes_are_there():
    assert len(SCENES) >= 10, f"reference scenes missing under {SCENES}"


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_lean_index_in_place(path):
    scene = Scene(path)
    expected = read_expected(path.with_suffix(".expected"))
    centers = scene.centers.copy()
    ix = broadphase.Index(centers, **sizes(scene, centers))
    assert ix.borrowing
    for frame in range(len(expected)):
        if frame:
            scene.step(centers)  # moves the borrowed array in place
            ix.update(scene.moving) if frame % 2 else ix.update()
        check(expected, frame, ix.pairs())
        assert ix.count_pairs() == expected[frame][1]
    ix.validate()


@pytest.mark.parametrize("path", SCENES, ids=lambda p: p.stem)
def test_one_shot_and_new_arrays(path):
    scene = Scene(path)
    expected = read_expected(path.with_suffix(".expected"))
    centers = scene.centers.copy()
    ix = broadphase.Index(centers.copy(), **sizes(scene, centers), threads=2)
    for frame in range(len(expected)):
        if frame:
            scene.step(centers)
            ix.update(centers.copy())  # all moved, new arrays borrowed
        check(expected, frame, broadphase.pairs(centers, **sizes(scene, centers)))
        check(expected, frame, ix.pairs(sorted=True))


STRUCTURES = [name for name, _ in broadphase.structures()] + ["grid-verlet:threads=3,grain=1"]


@pytest.mark.parametrize("structure", STRUCTURES)
def test_every_structure_replays_the_scenes(structure):
    paths = SCENES[::3] if QUICK else SCENES
    for path in paths:
        scene = Scene(path)
        expected = read_expected(path.with_suffix(".expected"))
        centers = scene.centers.copy()
        ix = broadphase.Index(centers, **sizes(scene, centers), structure=structure)
        assert not ix.borrowing
        for frame in range(len(expected)):
            if frame:
                scene.step(centers)
                if frame % 2:
                    ix.update(scene.moving, centers[scene.moving])
                else:
                    ix.update(centers)
            check(expected, frame, ix.pairs())
        ix.validate()
