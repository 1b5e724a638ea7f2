"""Sharded scans on a local Dask cluster: workers, sharding overhead, the halo's extra work.

    python python/bench/sharded_scan.py [--case 3-torus] [--workers 2] [--shards 8] [--json F]
    python python/bench/sharded_scan.py --halo-sweep [--case torus]

One run starts a LocalCluster of `--workers` worker processes (one thread each), scans the
case's box in `--shards` shards (the cluster's start not included), checks the keys against a
single-process scan, and prints the sharded run's wall time, the sum of its task times, and the
single-process scan of the same box with one thread (the same work as one task doing it all).
`--halo-sweep` prints, per shard count, the crossed simplices the shards' scans found (halo
included) against those they own.
"""

import argparse
import json
import sys
import time

import numpy as np

import isomesh
from isomesh import distributed

CASES = {
    "torus": ("torus", dict(edge=0.015), [[-1.5, 1.5], [-1.5, 1.5], [-0.5, 0.5]]),
    "3-torus": ("3-torus", dict(edge=0.6),
                [[-0.7, 0.7]] * 2 + [[-1.2, 1.2]] * 2 + [[-2.2, 2.2]] * 2),
    "flat-torus": ("flat-torus", dict(edge=0.12), [[-1.2, 1.2]] * 4),
}


def problem(case):
    name, params, box = CASES[case]
    return isomesh.Problem.preset(name, **params), box


def single(case, threads):
    p, box = problem(case)
    t = time.perf_counter()
    s = p.scan(box, threads=threads)
    s.complex()
    return s, time.perf_counter() - t


def sharded(case, workers, shards):
    from dask.distributed import Client, LocalCluster

    p, box = problem(case)
    with LocalCluster(n_workers=workers, threads_per_worker=1, dashboard_address=None) as cl, \
            Client(cl) as client:
        # One small task per worker first: imports and the first pickled problem out of the way.
        distributed.scan(p, box, workers, client=client, halo=None)
        t = time.perf_counter()
        r = distributed.scan(p, box, shards, client=client)
        wall = time.perf_counter() - t
    return r, wall


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--case", default="3-torus", choices=sorted(CASES))
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--shards", type=int, default=8)
    ap.add_argument("--halo-sweep", action="store_true")
    ap.add_argument("--no-single", action="store_true")
    ap.add_argument("--json")
    a = ap.parse_args()
    if a.halo_sweep:
        from dask.distributed import Client, LocalCluster

        p, box = problem(a.case)
        rows = []
        with LocalCluster(n_workers=2, threads_per_worker=1, dashboard_address=None) as cl, \
                Client(cl) as client:
            for n in (1, 2, 4, 8, 16, 32, 64):
                r = distributed.scan(p, box, n, client=client)
                rep = r.report
                rows.append({"shards": n, "owned": rep["simplices"], "scanned": rep["scanned"],
                             "extra": rep["scanned"] / rep["simplices"] - 1.0,
                             "task_s": rep["task_s"], "wall_s": rep["wall_s"]})
                print(f"{n:3d} shards: scanned {rep['scanned']:9d} for {rep['simplices']:9d} "
                      f"owned (+{100 * rows[-1]['extra']:.1f}%), tasks {rep['task_s']:.2f} s, "
                      f"wall {rep['wall_s']:.2f} s", flush=True)
        out = {"case": a.case, "halo": r.report["halo"], "rows": rows}
    else:
        r, wall = sharded(a.case, a.workers, a.shards)
        out = {"case": a.case, "workers": a.workers, "shards": a.shards, "wall_s": wall,
               "task_s": r.report["task_s"], "assemble_s": r.report["assemble_s"],
               "simplices": r.report["simplices"], "scanned": r.report["scanned"]}
        if not a.no_single:
            s, t1 = single(a.case, 1)
            if not np.array_equal(s.keys, r.keys):
                sys.exit("the sharded scan's keys differ from the single scan's")
            out["single_1_thread_s"] = t1
        print(json.dumps(out))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
