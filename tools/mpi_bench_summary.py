#!/usr/bin/env python3
"""Summarises a tools/mpi_bench.sh run (one JSON per run) as markdown:
weak scaling beside the two-process ceiling with the phases, the targets,
identical hashes, the figures for P = 1..16, and a projection to 1000 ranks
and 10^9 objects from a latency-bandwidth model (assumed parameters)."""
import json
import math
import os
import sys

out = sys.argv[1]


def load(name):
    p = os.path.join(out, name)
    if not os.path.exists(p) or os.path.getsize(p) == 0:
        return None
    with open(p) as f:
        return json.load(f)


def mean(v):
    return sum(v) / len(v) if v else 0.0


print("## Weak scaling, 1 -> 2 ranks\n")
# "Two runs at once" is the time by which both are done (the slower of the
# two): a two-rank frame ends when its slower rank does, and the VM's two
# cores ran the same binary up to 1.5x apart. The mean of the two is shown
# beside it.
print("| kind | objects per rank | 1 rank ms/frame | two 1-rank runs at once (slower; mean) | 2 ranks | efficiency | ceiling | efficiency / ceiling (by the mean) |")
print("|---|---|---|---|---|---|---|---|")
phase_rows = []
for kind in ("scaled-even", "scaled-uneven", "scaled-even-skin", "scaled-uneven-skin"):
    p1, a, b, p2 = (load("weak-%s-%s.json" % (kind, s)) for s in ("p1", "pair-a", "pair-b", "p2"))
    if not (p1 and a and b and p2):
        if not kind.endswith("-skin"):
            print("| %s | not measured (run did not finish) | | | | | | |" % kind)
        continue
    if kind.endswith("-skin"):
        kind = "%s, skin %g (%d and %d rebuilds in %d frames)" % (
            kind[:-5], p2.get("skin", 0), p1.get("rebuilds", 0), p2.get("rebuilds", 0), p2["frames"])
    t1 = p1["median_frame_ms"]
    tp = max(a["median_frame_ms"], b["median_frame_ms"])
    tm = mean([a["median_frame_ms"], b["median_frame_ms"]])
    t2 = p2["median_frame_ms"]
    print("| %s | %d | %.0f | %.0f; %.0f | %.0f | %.1f%% | %.1f%% | %.1f%% (%.1f%%) |" % (
        kind, p1["n"], t1, tp, tm, t2, 100 * t1 / t2, 100 * t1 / tp, 100 * tp / t2, 100 * tm / t2))
    for label, j in (("1 rank", p1), ("2 ranks", p2)):
        ph = j["phases"]
        phase_rows.append("| %s | %s | %s | %.2f | %.3f |" % (
            kind, label, " | ".join("%.0f" % ph[k]["max_ms_per_frame"] for k in
                                    ("local_pairs", "ghost_exchange", "migration", "balancing", "reduction", "step")),
            j["ghosts_over_owned"], j["load_imbalance_last"]))
print("\nPer phase (ms per frame, the slowest rank):\n")
print("| kind | run | local pairs | ghost exchange | migration | balancing | reduction | motion | ghosts/owned | imbalance |")
print("|---|---|---|---|---|---|---|---|---|---|")
for r in phase_rows:
    print(r)

print("\n## Targets at 1 024 000 objects per rank, 8 ranks\n")
g = load("ghosts-scaled-even-p8-2x2x2.json")
i = load("imbalance-scaled-uneven-p8-bisect.json")
if g:
    print("- ghosts / owned, scaled-even, 2x2x2: **%.4f** (target <= 0.20); bytes per rank per frame %.3g, messages %.1f" % (
        g["ghosts_over_owned"], mean(g["bytes_per_rank_per_frame"]), mean(g["messages_per_rank_per_frame"])))
else:
    print("- ghosts / owned, scaled-even, 2x2x2: not measured (run did not finish)")
if i:
    print("- most loaded rank / mean after balancing, scaled-uneven, bisection: **%.4f** (target <= 1.1; %d rebalances)" % (
        i["load_imbalance_last"], i["rebalances"]))
else:
    print("- imbalance, scaled-uneven, bisection: not measured (run did not finish)")

print("\n## Identical hashes over the rank counts (scaled-uneven, 32 000 objects, bisection, 3 frames)\n")
print("| ranks | pairs_total | hash_total |")
print("|---|---|---|")
hashes = set()
for p in (1, 2, 3, 4, 8):
    j = load("hash-p%d.json" % p)
    if j:
        hashes.add((j["pairs_total"], j["hash_total"]))
        print("| %d | %d | %s |" % (p, j["pairs_total"], j["hash_total"]))
print("\nIdentical: **%s**" % ("not measured" if not hashes else "yes" if len(hashes) == 1 else "NO"))

print("\n## Identical hashes at 8 192 000 objects (scaled-even, 3 frames, pairs included)\n")
print("| run | pairs_total | hash_total | median ms/frame |")
print("|---|---|---|---|")
big = set()
for name, label in (("hash-big-p1.json", "1 process"), ("hash-big-p8.json", "8 ranks, 2x2x2 (oversubscribed on 2 cores)")):
    j = load(name)
    if j:
        big.add((j["pairs_total"], j["hash_total"]))
        print("| %s | %d | %s | %.0f |" % (label, j["pairs_total"], j["hash_total"], j["median_frame_ms"]))
print("\nIdentical: **%s**" % ("not measured" if len(big) == 0 else "yes" if len(big) == 1 else "NO"))

print("\n## Figures for P = 1..16 (32 000 objects per rank, decomposition only)\n")
print("| P | even: grid | ghosts/owned | bytes/rank/frame | messages/rank/frame | imbalance | uneven (bisection): ghosts/owned | bytes | messages | imbalance |")
print("|---|---|---|---|---|---|---|---|---|---|")
fig = {}
for p in range(1, 17):
    e = load("figures-even-p%d.json" % p)
    u = load("figures-uneven-p%d.json" % p)
    if not (e and u):
        continue
    fig[p] = (e, u)
    print("| %d | %s | %.4f | %.3g | %.1f | %.3f | %.4f | %.3g | %.1f | %.3f |" % (
        p, e["decomposition"], e["ghosts_over_owned"], mean(e["bytes_per_rank_per_frame"]),
        mean(e["messages_per_rank_per_frame"]), e["load_imbalance_last"], u["ghosts_over_owned"],
        mean(u["bytes_per_rank_per_frame"]), mean(u["messages_per_rank_per_frame"]), u["load_imbalance_last"]))

print("\n## Projection to 1000 ranks and 10^9 objects (model, not a measurement)\n")
p1 = load("weak-scaled-even-p1.json")
alpha = 2e-6      # ASSUMED: latency per message, s (InfiniBand-class network)
beta = 10e9       # ASSUMED: bandwidth per rank, bytes/s
record = 64       # bytes per ghost or migrated object (measured: the record's size)
collectives = 14  # small collectives per frame in the code (counted), log2(P) steps each
n_rank = 1e6
if p1:
    t_local = p1["phases"]["local_pairs"]["max_ms_per_frame"] / 1e3 * n_rank / p1["n"]
    t_other = sum(p1["phases"][k]["max_ms_per_frame"] for k in ("ghost_exchange", "migration", "step")) / 1e3 * n_rank / p1["n"]
    # Ghosts scale as the surface of a cube holding n_rank objects: the
    # measured 2x2x2 fraction at 1 024 000 per rank stands for an interior
    # rank with its six faces counted twice (a 2x2x2 rank has three).
    gfrac = (g["ghosts_over_owned"] * 2) if g else 0.03
    ghost_bytes = gfrac * n_rank * record
    migrate_bytes = 0.2 * n_rank * record * 0.01  # ASSUMED: 1% of movers leave per frame
    msgs = 26 + 26  # ghosts and migration to the 26 neighbours of a 3-D grid
    t_net = msgs * alpha + (ghost_bytes + migrate_bytes) / beta
    t_coll = collectives * math.log2(1000) * alpha + 1000 * alpha  # + the alltoall of counts: O(P)
    total = t_local + t_other + t_net + t_coll
    print("| term | seconds per frame |")
    print("|---|---|")
    print("| local pairs at 10^6 objects (measured, 1 rank, scaled to 10^6) | %.3f |" % t_local)
    print("| ghost choice, copies, migration, motion (measured, scaled) | %.3f |" % t_other)
    print("| point-to-point: %d messages x alpha + %.3g bytes / beta | %.4f |" % (msgs, ghost_bytes + migrate_bytes, t_net))
    print("| collectives: %d x log2(1000) x alpha + alltoall of counts 1000 x alpha | %.4f |" % (collectives, t_coll))
    print("| **total** | **%.3f** (efficiency vs 1 rank: %.1f%%) |" % (total, 100 * (t_local + t_other) / total))
    print("\nAssumed (labelled, not measured): alpha = %.0f us, beta = %.0f GB/s per rank, 1%% of movers change rank per frame, an interior rank's ghosts = twice the 2x2x2 rank's (six faces instead of three). The O(P) alltoall of counts is the first term that grows with P: at 1000 ranks it is %.1f ms per frame; a neighbour exchange (MPI_Neighbor_alltoall over the grid) would remove it." % (
        alpha * 1e6, beta / 1e9, 1000 * alpha * 1e3))
else:
    print("not computed: the one-rank weak-scaling run did not finish")
