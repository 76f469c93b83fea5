#!/usr/bin/env python3
"""Checks the relative Markdown links of docs/*.md, README.md and
results/README.md (and, with --results, every .md under results/): each
link's path must exist in the tree, and a #fragment into a Markdown file
must name one of its headings (GitHub's anchors: lower case, punctuation
dropped, spaces as hyphens). Code blocks are skipped.

Usage: tools/check_doc_links.py [ROOT] [--results]; exits 1 when a link
is broken, printing each."""
import glob
import os
import re
import sys


def anchors(path):
    out = set()
    in_code = False
    with open(path, encoding="utf-8") as f:
        for line in f:
            if line.startswith("```"):
                in_code = not in_code
                continue
            m = None if in_code else re.match(r"^#+\s+(.*)", line)
            if m:
                t = re.sub(r"[^\w\- ]", "", m.group(1).strip().lower())
                out.add(t.replace(" ", "-"))
            out.update(re.findall(r'<a (?:name|id)="([^"]+)"', line))
    return out


def main(argv):
    root = next((a for a in argv if not a.startswith("--")), ".")
    os.chdir(root)
    files = sorted(glob.glob("docs/*.md")) + ["README.md", "results/README.md"]
    if "--results" in argv:
        files += sorted(set(glob.glob("results/**/*.md", recursive=True)) - set(files))
    bad = 0
    for f in files:
        with open(f, encoding="utf-8") as fh:
            text = re.sub(r"```.*?```", "", fh.read(), flags=re.S)
        for m in re.finditer(r"\]\(([^)\s]+)\)", text):
            url = m.group(1)
            if re.match(r"^[a-z]+:", url):
                continue
            path, _, frag = url.partition("#")
            target = os.path.normpath(os.path.join(os.path.dirname(f), path)) if path else f
            if not os.path.exists(target):
                print(f"{f}: missing {url}")
                bad += 1
            elif frag and target.endswith(".md") and frag not in anchors(target):
                print(f"{f}: no heading for {url}")
                bad += 1
    print(f"{len(files)} files, {bad} broken links")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
