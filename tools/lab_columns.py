#!/usr/bin/env python3
"""Prints the Markdown tables of results.csv's columns and metrics from
lab/metrics.json (where they are defined once), as docs/lab.md shows them.

Usage: lab_columns.py [--check docs/lab.md]   (--check: exit 1 when the
document's tables differ from the file's)."""
import json
import os
import sys

HERE = os.path.dirname(os.path.abspath(__file__))


def tables():
    with open(os.path.join(HERE, "..", "lab", "metrics.json")) as f:
        m = json.load(f)
    out = ["| column | meaning |", "|---|---|"]
    out += ["| `%s` | %s |" % (c["name"], c["what"]) for c in m["columns"]]
    out += ["", "| metric (`test`) | unit | what | the study's test |", "|---|---|---|---|"]
    for x in m["metrics"]:
        tests = ", ".join("%s %d" % kv for kv in x["study_test"].items()) or "–"
        out.append("| `%s` | %s | %s | %s |" % (x["name"], x["unit"], x["what"], tests))
    return "\n".join(out)


def main():
    text = tables()
    if len(sys.argv) == 3 and sys.argv[1] == "--check":
        with open(sys.argv[2]) as f:
            doc = f.read()
        start = doc.index("<!-- columns:")
        start = doc.index("\n", start) + 1
        end = doc.index("<!-- end of columns -->")
        if doc[start:end].strip() != text.strip():
            print(sys.argv[2] + ": the column tables differ from lab/metrics.json "
                  "(regenerate them with tools/lab_columns.py)", file=sys.stderr)
            return 1
        return 0
    print(text)
    return 0


if __name__ == "__main__":
    sys.exit(main())
