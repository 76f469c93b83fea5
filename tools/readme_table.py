#!/usr/bin/env python3
"""Prints the README's "which structure" figures from a lab run's results.csv:
median frame ms at the study's 6400 objects (even, uneven) and at the largest
scaled size each structure reached, query ns at 6400 uneven, bytes/object."""
import csv
import json
import os
import sys
from collections import defaultdict

# The metrics' names and units are defined once, in lab/metrics.json.
with open(os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "lab", "metrics.json")) as f:
    METRICS = {m["name"]: m for m in json.load(f)["metrics"]}
FRAME, QUERY, MEMORY = METRICS["frame_time"], METRICS["query_time"], METRICS["memory"]

rows = list(csv.DictReader(open(sys.argv[1])))
val = defaultdict(dict)
for r in rows:
    val[r["structure"]][(r["test"], r["placement"], int(r["n"]))] = r
order = []
for r in rows:
    if r["structure"] not in order:
        order.append(r["structure"])


def get(s, test, placement, n, fmt="{:.3g}"):
    r = val[s].get((test, placement, n))
    if r is None or r["median"] in ("", "nan"):
        return "—"
    return fmt.format(float(r["median"]))


def per_object(s):
    r = val[s].get((MEMORY["name"], "even", 6400))
    if r is None or r["median"] in ("", "nan"):
        return "—"
    return "{:.0f}".format(float(r["median"]) / 6400)


f, q = FRAME["unit"], QUERY["unit"]
print(f"| structure | frame {f}, even 6400 | frame {f}, uneven 6400 | largest scaled N: frame {f} | query {q}, uneven 6400 | {MEMORY['unit']}/object, even 6400 |")
print("|---|---:|---:|---:|---:|---:|")
for s in order:
    peer = any(r["peer"] == "1" for r in rows if r["structure"] == s)
    scaled = sorted({k[2] for k in val[s] if k[0] == FRAME["name"] and k[1] == "even" and k[2] > 6400 and val[s][k]["median"] not in ("", "nan")})
    big = f"{scaled[-1]:,}: {get(s, FRAME['name'], 'even', scaled[-1])}" if scaled else "—"
    name = f"`{s}`" + (" (peer)" if peer else "")
    print(f"| {name} | {get(s, FRAME['name'], 'even', 6400)} | {get(s, FRAME['name'], 'uneven', 6400)} | {big} | "
          f"{get(s, QUERY['name'], 'uneven', 6400)} | {per_object(s)} |")
