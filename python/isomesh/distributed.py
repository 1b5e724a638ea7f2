"""Exhaustive scans sharded over a Dask cluster, assembled exactly.

The box is cut into a grid of shards; each shard is a Dask task that scans its part of the
box widened by a halo, builds that part's cell complex, and keeps what it owns (a point of M
belongs to the shard whose half-open box holds it, a cell to the owner of its first vertex).
Every simplex has a global key, so the parts merge into exactly the single-process scan:
the same keys in the same order, the same points bit for bit, the same complex.

    >>> from dask.distributed import Client, LocalCluster      # doctest: +SKIP
    >>> client = Client(LocalCluster(n_workers=2))               # doctest: +SKIP
    >>> p = isomesh.Problem.preset("torus", edge=0.05)           # doctest: +SKIP
    >>> r = isomesh.distributed.scan(p, [[-1.5, 1.5]] * 2 + [[-0.5, 0.5]], 8)  # doctest: +SKIP
    >>> r.topology["betti_mod2"]                                 # doctest: +SKIP
    [1, 2, 1]

Shard tasks are pure functions of (problem, box, shard): Dask re-runs a task lost with its
worker, and the result does not change. With ``out=`` a directory, each task writes its part
there (``part-NNNNN.npz``) and only counters come back; ``manifest.json`` describes the run
and :func:`merge` assembles the parts when they fit in one process.
"""

from __future__ import annotations

import json
import os
import pickle
import sys
import time
import uuid
from dataclasses import dataclass, field
from typing import Any, Optional, Sequence, Union

import numpy as np

from . import _isomesh
from ._isomesh import Complex, Problem

__all__ = ["scan", "merge", "ShardedScan", "MANIFEST"]

#: The manifest's file name in an ``out=`` directory.
MANIFEST = "manifest.json"
#: The layout version of an ``out=`` directory.
LAYOUT_VERSION = 1


@dataclass
class ShardedScan:
    """The result of :func:`scan` or :func:`merge`.

    ``keys`` (N, W) and ``points`` (N, d) are the sample, sorted by key as
    ``problem.scan(box)`` gives it; ``complex`` its cell complex (``None`` when the parts
    stayed on disk); ``topology`` the complex's topology, or, for parts on disk, the cell
    counts and Euler characteristic summed over the parts; ``report`` per-shard counts and
    times; ``out`` the directory of the parts, if any."""

    keys: Optional[np.ndarray]
    points: Optional[np.ndarray]
    complex: Optional[Complex]
    topology: dict[str, Any]
    report: dict[str, Any]
    out: Optional[str] = None
    shards: list[dict[str, Any]] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.report["simplices"])


def _box(box: Sequence[Sequence[float]], d: int) -> list[list[float]]:
    rows = [[float(lo), float(hi)] for lo, hi in box]
    if len(rows) != d:
        raise ValueError(f"the box has {len(rows)} rows, the ambient dimension is {d}")
    return rows


def _cuts(box: list[list[float]], shards: Union[int, Sequence[Any]]) -> list[list[float]]:
    """Interior cut positions per axis: from a count, per-axis counts, or per-axis lists of
    positions (an int and a list can be mixed)."""
    d = len(box)
    if isinstance(shards, (int, np.integer)):
        if shards < 1:
            raise ValueError(f"shards={shards}: must be at least 1")
        return _isomesh._uniform_cuts(box, _isomesh._split_count(box, int(shards)))
    per_axis = list(shards)
    if len(per_axis) != d:
        raise ValueError(f"shards has {len(per_axis)} entries, the box has {d} axes")
    cuts = []
    for a, s in enumerate(per_axis):
        if isinstance(s, (int, np.integer)):
            if s < 1:
                raise ValueError(f"shards[{a}] = {s}: must be at least 1")
            cuts.append(_isomesh._uniform_cuts([box[a]], [int(s)])[0])
        else:
            cuts.append([float(x) for x in s])
    return cuts


def _worker_threads() -> Optional[int]:
    """The running Dask worker's thread count (its share of the machine), if in one."""
    try:
        from dask.distributed import get_worker

        w = get_worker()
    except (ImportError, ValueError):
        return None
    state = getattr(w, "state", None)
    n = getattr(state, "nthreads", None) or getattr(w, "nthreads", None)
    return int(n) if n else None


def _part_path(out: str, index: int) -> str:
    return os.path.join(out, f"part-{index:05d}.npz")


def _scan_shard(
    problem: Problem,
    box: list[list[float]],
    index: int,
    shard: tuple[list[float], list[float], list[bool]],
    halo: Optional[float],
    options: dict[str, Any],
    out: Optional[str],
) -> dict[str, Any]:
    """One Dask task: the part of `box` that shard `index` owns (written to `out` if given;
    then only its counters are returned)."""
    start = time.perf_counter()
    lo, hi, closed = shard
    threads = options.get("threads") or _worker_threads()
    part = problem._scan_shard(
        box,
        lo,
        hi,
        closed,
        halo,
        backend=options.get("backend", "cpu"),
        threads=threads,
        precision=options.get("precision"),
        max_memory=options.get("max_memory"),
    )
    arrays = {k: v for k, v in part.items() if isinstance(v, np.ndarray)}
    m = int(arrays["meta"][4])
    stats = {
        "index": index,
        "lo": lo,
        "hi": hi,
        "scanned": part["scanned"],
        "owned": part["owned"],
        "cells": [int(arrays["vertex_ids"].shape[0])]
        + [int(arrays[f"ids{j}"].shape[0]) for j in range(1, m + 1)],
        "boundary_cells": _boundary_counts(arrays, m),
        "oracle_calls": part["oracle_calls"],
        "scan_s": part["scan_s"],
        "complex_s": part["complex_s"],
        "threads": threads,
        "worker": _worker_address(),
    }
    if out is None:
        stats["task_s"] = time.perf_counter() - start
        return {"stats": stats, "part": arrays}
    path = _part_path(out, index)
    # Written beside, then renamed: a retried or speculative copy of the task leaves one
    # whole file.
    tmp = f"{path}.{os.getpid()}.{time.monotonic_ns()}.tmp.npz"
    np.savez(tmp, **arrays)
    os.replace(tmp, path)
    stats["file"] = os.path.basename(path)
    stats["task_s"] = time.perf_counter() - start
    return {"stats": stats}


def _boundary_counts(arrays: dict[str, np.ndarray], m: int) -> list[int]:
    """Owned boundary cells per dimension 0..m-1 (ids with tag 1)."""
    out = [int((arrays["vertex_ids"][:, 0] == 1).sum())]
    out += [int((arrays[f"ids{j}"][:, 0] == 1).sum()) for j in range(1, m)]
    return out


def _worker_address() -> Optional[str]:
    try:
        from dask.distributed import get_worker

        return str(get_worker().address)
    except (ImportError, ValueError):
        return None


def _client(client: Any) -> Any:
    if client is not None:
        return client
    try:
        from dask.distributed import get_client
    except ImportError as e:  # pragma: no cover - the message is the point
        raise ImportError(
            "isomesh.distributed needs Dask: pip install 'dask[distributed]'"
        ) from e
    try:
        return get_client()
    except ValueError as e:
        raise ValueError(
            "no Dask client: start one (dask.distributed.Client(...)) or pass client="
        ) from e


def _progress_line(done: int, total: int, start: float, stream: Any) -> None:
    stream.write(f"\risomesh: {done}/{total} shards, {time.perf_counter() - start:.1f} s")
    if done == total:
        stream.write("\n")
    stream.flush()


def scan(
    problem: Problem,
    box: Sequence[Sequence[float]],
    shards: Union[int, Sequence[Any]],
    client: Any = None,
    out: Optional[Union[str, os.PathLike]] = None,
    *,
    halo: Optional[float] = None,
    backend: str = "auto",
    threads: Optional[int] = None,
    precision: Optional[str] = None,
    max_memory: Optional[int] = None,
    progress: bool = False,
) -> ShardedScan:
    """Scans `box` in shards, one Dask task each, and assembles the whole scan.

    `shards` is a count (split along the longest axes), or per axis a count or a list of
    interior cut positions. `client` is a ``dask.distributed.Client`` (default: the current
    one). With `out` a directory, each shard writes its part there and nothing large comes
    back (see :func:`merge`). `halo` (default: 1.1 times the triangulation's edge) widens each
    shard's scan; `threads` per task defaults to the worker's thread count; `backend`
    ("auto": a worker's hardware GPU where `isomesh bench` measured it faster than its CPU,
    else its CPU; the result is the same),
    `precision` and `max_memory` (bytes, per shard) are those of ``Problem.scan``.
    `progress` prints a progress line on stderr (Dask's dashboard shows the tasks too)."""
    if not isinstance(problem, Problem):
        raise TypeError("problem must be an isomesh.Problem")
    whole = _box(box, problem.ambient_dim)
    cuts = _cuts(whole, shards)
    grid = _isomesh._shard_grid(whole, cuts)
    if halo is None:
        halo = problem._default_halo()
    options = {
        "backend": backend,
        "threads": threads,
        "precision": precision,
        "max_memory": max_memory,
    }
    outdir = None
    if out is not None:
        outdir = os.fspath(out)
        # Nothing there is removed: parts of this run replace their namesakes, and the new
        # manifest lists only this run's.
        os.makedirs(outdir, exist_ok=True)
    client = _client(client)
    from dask.distributed import as_completed

    token = uuid.uuid4().hex
    start = time.perf_counter()
    futures = [
        client.submit(
            _scan_shard,
            problem,
            whole,
            i,
            s,
            halo,
            options,
            outdir,
            key=f"isomesh-shard-{token}-{i}",
            pure=False,
        )
        for i, s in enumerate(grid)
    ]
    results: list[Any] = [None] * len(futures)
    index = {f.key: i for i, f in enumerate(futures)}
    for done, fut in enumerate(as_completed(futures), 1):
        results[index[fut.key]] = fut.result()
        if progress:
            _progress_line(done, len(futures), start, sys.stderr)
    wall = time.perf_counter() - start
    stats = [r["stats"] for r in results]
    report = _report(problem, whole, cuts, halo, stats, wall)
    if outdir is not None:
        _write_manifest(outdir, problem, whole, cuts, halo, stats, report)
        return ShardedScan(
            keys=None,
            points=None,
            complex=None,
            topology=_summed_topology(stats),
            report=report,
            out=outdir,
            shards=stats,
        )
    return _assembled(problem, [r["part"] for r in results], report, stats, None)


def _report(
    problem: Problem,
    box: list[list[float]],
    cuts: list[list[float]],
    halo: float,
    stats: list[dict[str, Any]],
    wall: float,
) -> dict[str, Any]:
    return {
        "name": problem.name,
        "box": box,
        "cuts": cuts,
        "shards": len(stats),
        "halo": halo,
        "simplices": sum(s["owned"] for s in stats),
        "scanned": sum(s["scanned"] for s in stats),
        "wall_s": wall,
        "task_s": sum(s["task_s"] for s in stats),
        "per_shard": stats,
    }


def _summed_topology(stats: list[dict[str, Any]]) -> dict[str, Any]:
    cells = [sum(col) for col in zip(*(s["cells"] for s in stats))]
    boundary = [sum(col) for col in zip(*(s["boundary_cells"] for s in stats))]
    return {
        "dim": len(cells) - 1,
        "cells": cells,
        "euler_characteristic": sum((-1) ** j * n for j, n in enumerate(cells)),
        "boundary_cells": boundary,
        "boundary_euler_characteristic": sum((-1) ** j * n for j, n in enumerate(boundary)),
    }


def _assembled(
    problem: Problem,
    parts: list[dict[str, np.ndarray]],
    report: dict[str, Any],
    stats: list[dict[str, Any]],
    out: Optional[str],
) -> ShardedScan:
    t0 = time.perf_counter()
    keys, points, complex_ = problem._assemble(parts)
    report = dict(report, assemble_s=time.perf_counter() - t0)
    return ShardedScan(
        keys=keys,
        points=points,
        complex=complex_,
        topology=complex_.topology,
        report=report,
        out=out,
        shards=stats,
    )


def _write_manifest(
    out: str,
    problem: Problem,
    box: list[list[float]],
    cuts: list[list[float]],
    halo: float,
    stats: list[dict[str, Any]],
    report: dict[str, Any],
) -> None:
    problem_file: Optional[str] = "problem.pickle"
    try:
        # cloudpickle (a Dask dependency) also sends functions defined in a session.
        import cloudpickle

        blob: Optional[bytes] = cloudpickle.dumps(problem)
    except Exception:  # nothing can send this function: merge() then needs problem=
        blob = None
        problem_file = None
    if blob is not None and problem_file is not None:
        with open(os.path.join(out, problem_file), "wb") as f:
            f.write(blob)
    manifest = {
        "layout": LAYOUT_VERSION,
        "name": problem.name,
        "ambient_dim": problem.ambient_dim,
        "codim": problem.codim,
        "equations": problem.equations,
        "problem": problem_file,
        "box": box,
        "cuts": cuts,
        "halo": halo,
        "parts": stats,
        "simplices": report["simplices"],
        "topology": _summed_topology(stats),
    }
    tmp = os.path.join(out, MANIFEST + ".tmp")
    with open(tmp, "w") as f:
        json.dump(manifest, f, indent=1)
    os.replace(tmp, os.path.join(out, MANIFEST))


def merge(
    out: Union[str, os.PathLike],
    path: Optional[Union[str, os.PathLike]] = None,
    *,
    problem: Optional[Problem] = None,
) -> ShardedScan:
    """Assembles the parts a :func:`scan` with ``out=`` wrote into the whole scan (they must
    fit in this process), and writes its mesh to `path` (any mesh format of
    ``Complex.write``) if given. `problem` is needed only if the run's could not be pickled."""
    out = os.fspath(out)
    with open(os.path.join(out, MANIFEST)) as f:
        manifest = json.load(f)
    if manifest.get("layout") != LAYOUT_VERSION:
        raise ValueError(f"{out}: layout {manifest.get('layout')}, expected {LAYOUT_VERSION}")
    if problem is None:
        if not manifest.get("problem"):
            raise ValueError(f"{out}: the problem was not saved; pass problem=")
        with open(os.path.join(out, manifest["problem"]), "rb") as f:
            problem = pickle.load(f)
    parts = []
    for s in manifest["parts"]:
        with np.load(os.path.join(out, s["file"])) as z:
            parts.append({k: z[k] for k in z.files})
    report = {
        "name": manifest["name"],
        "box": manifest["box"],
        "cuts": manifest["cuts"],
        "shards": len(parts),
        "halo": manifest["halo"],
        "simplices": manifest["simplices"],
        "per_shard": manifest["parts"],
    }
    r = _assembled(problem, parts, report, manifest["parts"], out)
    if path is not None:
        r.complex.write(os.fspath(path))
    return r
