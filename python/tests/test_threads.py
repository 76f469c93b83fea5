"""The GIL is released during calls; queries run from several threads at
once; a mutation that overlaps a query raises RuntimeError instead of racing."""

import threading
import time

import numpy as np

import broadphase
from conftest import as_set


class Counter(threading.Thread):
    """Runs Python code as fast as it can (it only advances while it holds the
    GIL) and notes the time every thousand steps."""

    def __init__(self):
        super().__init__(daemon=True)
        self.stamps = []
        self.stop = False

    def run(self):
        while not self.stop:
            for _ in range(1000):
                pass
            self.stamps.append(time.perf_counter())


def long_index(rng, min_seconds=0.3):
    """A naive index whose first pairs() takes at least `min_seconds`."""
    n = 4000
    while True:
        c = rng.random((n, 3))
        ix = broadphase.Index(c, 0.001, structure="naive")
        t = time.perf_counter()
        ix.pairs()
        if time.perf_counter() - t >= min_seconds or n > 200000:
            return c
        n *= 2


def test_a_python_thread_runs_during_a_long_call(rng):
    c = long_index(rng)
    counter = Counter()
    counter.start()
    time.sleep(0.05)
    ix = broadphase.Index(c, 0.001, structure="naive")
    t0 = time.perf_counter()
    ix.pairs()  # the pairs are found in this call
    t1 = time.perf_counter()
    counter.stop = True
    counter.join()
    # A call that held the GIL would let the counter run only at its start and
    # end (a switch interval each, 5 ms); released, the counter runs all along,
    # so it notes times in the middle half of the call too.
    lo, hi = t0 + (t1 - t0) / 4, t1 - (t1 - t0) / 4
    middle = sum(lo <= s <= hi for s in counter.stamps)
    print(f"the counter noted {middle} times in the middle half of a {t1 - t0:.2f} s call")
    assert middle >= 5


def test_queries_run_concurrently_with_the_same_answers(rng):
    c = rng.random((5000, 3))
    for structure in (None, "grid-verlet", "naive"):
        ix = broadphase.Index(c, 0.02, structure=structure)
        q = rng.random((300, 3))
        want_pairs = ix.pairs(sorted=True)
        want_query = ix.query(q, 0.02)
        errors = []

        def work():
            try:
                for _ in range(5):
                    assert np.array_equal(ix.pairs(sorted=True), want_pairs)
                    assert np.array_equal(ix.query(q, 0.02), want_query)
                    assert ix.count_pairs() == len(want_pairs)
            except Exception as e:  # noqa: BLE001 - reported below
                errors.append(e)

        threads = [threading.Thread(target=work) for _ in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert not errors, errors


def test_a_mutation_during_a_query_raises_runtime_error(rng):
    c = long_index(rng, 0.5)
    ix = broadphase.Index(c, 0.001, structure="naive")
    done = []
    t = threading.Thread(target=lambda: done.append(ix.count_pairs()))
    t.start()
    refused = 0
    while t.is_alive():
        try:
            ix.update([0], [[0.5, 0.5, 0.5]])
        except RuntimeError as e:
            assert "exclusive use" in str(e)
            refused += 1
        time.sleep(0.01)
    t.join()
    assert refused > 0 and len(done) == 1
    ix.update([0], [[0.25, 0.25, 0.25]])  # free again
    assert as_set(ix.pairs()) == as_set(broadphase.sphere_pairs(ix_centers(c), 0.001))


def ix_centers(c):
    c = c.copy()
    c[0] = 0.25
    return c
