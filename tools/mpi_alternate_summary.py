#!/usr/bin/env python3
"""Summarises a tools/mpi_alternate.sh run as markdown: per configuration,
each repeat's two-rank frame against the same one-rank run twice at once,
and the medians over the repeats (ms per frame, each run's median frame).

The headline is the median of the repeats' own ratios: each repeat's two
runs saw the host at the same moment, so its ratio is a paired comparison.
The ratio of the medians (times from different moments) stands beside it."""
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
    t2s, slow, avg, ratio_slow, ratio_avg = [], [], [], [], []
    for rep, p2, a, b in sorted(rows, key=lambda r: r[0]):
        t2 = p2["median_frame_ms"]
        ta, tb = a["median_frame_ms"], b["median_frame_ms"]
        t2s.append(t2)
        slow.append(max(ta, tb))
        avg.append((ta + tb) / 2)
        ratio_slow.append(slow[-1] / t2)
        ratio_avg.append(avg[-1] / t2)
        print("| %s | %g | %d | %.0f | %.0f | %.0f | %.1f%%; %.1f%% | %d of %d |" % (
            kind, skin, rep, t2, slow[-1], avg[-1], 100 * slow[-1] / t2, 100 * avg[-1] / t2,
            p2.get("rebuilds", p2["frames"]), p2["frames"]))
    medians.append((kind, skin, len(rows), statistics.median(t2s), statistics.median(slow),
                    statistics.median(avg), statistics.median(ratio_slow), statistics.median(ratio_avg),
                    min(ratio_slow), max(ratio_slow)))
print("\nMedians over the repeats:\n")
print("| kind | skin | repeats | 2 ranks | twice at once: slower | mean "
      "| efficiency / ceiling, median of the repeats' ratios (slower; mean) | range (slower) "
      "| ratio of the medians (slower; mean) |")
print("|---|---|---|---|---|---|---|---|---|")
for kind, skin, k, t2, s, m, rs, ra, lo, hi in medians:
    print("| %s | %g | %d | %.0f | %.0f | %.0f | **%.1f%%**; %.1f%% | %.1f–%.1f%% | %.1f%%; %.1f%% |" % (
        kind, skin, k, t2, s, m, 100 * rs, 100 * ra, 100 * lo, 100 * hi, 100 * s / t2, 100 * m / t2))
