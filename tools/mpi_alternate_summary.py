#!/usr/bin/env python3
"""Summarises tools/mpi_alternate.sh runs as markdown: per configuration,
each repeat's two-rank frame against the same one-rank run twice at once,
and the medians over the repeats (ms per frame, each run's median frame).

The headline is the median of the repeats' own ratios: each repeat's two
runs saw the host at the same moment, so its ratio is a paired comparison.
The ratio of the medians (times from different moments) stands beside it.

Usage: mpi_alternate_summary.py OUT [OUT ...]: with several runs, each
one's medians, then the medians over all their repeats pooled."""
import glob
import json
import os
import re
import statistics
import sys


def load(out):
    runs = {}
    for path in glob.glob(os.path.join(out, "*-p2.json")):
        m = re.match(r"(.*)-s([0-9.]+)-r(\d+)-p2\.json$", os.path.basename(path))
        kind, skin, rep = m.group(1), m.group(2), int(m.group(3))
        base = path[: -len("-p2.json")]
        try:
            p2, a, b = (json.load(open(base + s)) for s in ("-p2.json", "-a.json", "-b.json"))
        except (OSError, ValueError):
            continue
        runs.setdefault((kind, float(skin)), []).append((rep, p2, a, b))
    return runs


def times(p2, a, b):
    """A repeat's two-rank frame, the slower and the mean of its two
    one-rank runs at once (ms, each run's median frame)."""
    ta, tb = a["median_frame_ms"], b["median_frame_ms"]
    return p2["median_frame_ms"], max(ta, tb), (ta + tb) / 2


def repeats_table(runs):
    print("| kind | skin | repeat | 2 ranks | twice at once: slower | mean | efficiency / ceiling (slower; mean) | rebuilds in 2 ranks |")
    print("|---|---|---|---|---|---|---|---|")
    for (kind, skin), rows in sorted(runs.items()):
        for rep, p2, a, b in sorted(rows, key=lambda r: r[0]):
            t2, slow, avg = times(p2, a, b)
            print("| %s | %g | %d | %.0f | %.0f | %.0f | %.1f%%; %.1f%% | %d of %d |" % (
                kind, skin, rep, t2, slow, avg, 100 * slow / t2, 100 * avg / t2,
                p2.get("rebuilds", p2["frames"]), p2["frames"]))


def medians_table(runs, label):
    print("\n%s:\n" % label)
    print("| kind | skin | repeats | 2 ranks | twice at once: slower | mean "
          "| efficiency / ceiling, median of the repeats' ratios (slower; mean) | range (slower) "
          "| ratio of the medians (slower; mean) |")
    print("|---|---|---|---|---|---|---|---|---|")
    for (kind, skin), rows in sorted(runs.items()):
        t2s, slow, avg, rs, ra = [], [], [], [], []
        for rep, p2, a, b in rows:
            t2, s, m = times(p2, a, b)
            t2s.append(t2)
            slow.append(s)
            avg.append(m)
            rs.append(slow[-1] / t2)
            ra.append(avg[-1] / t2)
        m = statistics.median
        print("| %s | %g | %d | %.0f | %.0f | %.0f | **%.1f%%**; %.1f%% | %.1f–%.1f%% | %.1f%%; %.1f%% |" % (
            kind, skin, len(rows), m(t2s), m(slow), m(avg), 100 * m(rs), 100 * m(ra),
            100 * min(rs), 100 * max(rs), 100 * m(slow) / m(t2s), 100 * m(avg) / m(t2s)))


outs = sys.argv[1:]
if len(outs) == 1:
    runs = load(outs[0])
    repeats_table(runs)
    medians_table(runs, "Medians over the repeats")
else:
    pooled = {}
    for out in outs:
        runs = load(out)
        medians_table(runs, "%s, medians over its repeats" % os.path.basename(os.path.normpath(out)))
        for key, rows in runs.items():
            pooled.setdefault(key, []).extend(rows)
    medians_table(pooled, "All %d runs, their repeats pooled" % len(outs))
