#!/usr/bin/env python3
"""Summarises a tools/mpi_alternate.sh run as markdown: per configuration,
each repeat's two-rank frame against the same one-rank run twice at once,
and the medians over the repeats (ms per frame, each run's median frame)."""
import glob
import json
import os
import re
import statistics
import sys

out = sys.argv[1]
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

print("| kind | skin | repeat | 2 ranks | twice at once: slower | mean | efficiency / ceiling (slower; mean) | rebuilds in 2 ranks |")
print("|---|---|---|---|---|---|---|---|")
medians = []
for (kind, skin), rows in sorted(runs.items()):
    t2s, slow, avg = [], [], []
    for rep, p2, a, b in sorted(rows, key=lambda r: r[0]):
        t2 = p2["median_frame_ms"]
        ta, tb = a["median_frame_ms"], b["median_frame_ms"]
        t2s.append(t2)
        slow.append(max(ta, tb))
        avg.append((ta + tb) / 2)
        print("| %s | %g | %d | %.0f | %.0f | %.0f | %.1f%%; %.1f%% | %d of %d |" % (
            kind, skin, rep, t2, slow[-1], avg[-1], 100 * slow[-1] / t2, 100 * avg[-1] / t2,
            p2.get("rebuilds", p2["frames"]), p2["frames"]))
    medians.append((kind, skin, statistics.median(t2s), statistics.median(slow), statistics.median(avg)))
print("\nMedians over the repeats:\n")
print("| kind | skin | 2 ranks | twice at once: slower | mean | efficiency / ceiling (slower; mean) |")
print("|---|---|---|---|---|---|")
for kind, skin, t2, s, m in medians:
    print("| %s | %g | %.0f | %.0f | %.0f | **%.1f%%**; %.1f%% |" % (kind, skin, t2, s, m, 100 * s / t2, 100 * m / t2))
