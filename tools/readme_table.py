#!/usr/bin/env python3
"""Prints the README's "which structure" figures from a lab run's results.csv:
median frame ms at the study's 6400 objects (even, uneven) and at the largest
scaled size each structure reached, query ns at 6400 uneven, bytes/object."""
import csv
import sys
from collections import defaultdict

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
    r = val[s].get(("memory", "even", 6400))
    if r is None or r["median"] in ("", "nan"):
        return "—"
    return "{:.0f}".format(float(r["median"]) / 6400)


print("| structure | frame ms, even 6400 | frame ms, uneven 6400 | largest scaled N: frame ms | query ns, uneven 6400 | bytes/object, even 6400 |")
print("|---|---:|---:|---:|---:|---:|")
for s in order:
    peer = any(r["peer"] == "1" for r in rows if r["structure"] == s)
    scaled = sorted({k[2] for k in val[s] if k[0] == "frame_time" and k[1] == "even" and k[2] > 6400 and val[s][k]["median"] not in ("", "nan")})
    big = f"{scaled[-1]:,}: {get(s, 'frame_time', 'even', scaled[-1])}" if scaled else "—"
    name = f"`{s}`" + (" (peer)" if peer else "")
    print(f"| {name} | {get(s, 'frame_time', 'even', 6400)} | {get(s, 'frame_time', 'uneven', 6400)} | {big} | "
          f"{get(s, 'query_time', 'uneven', 6400)} | {per_object(s)} |")
