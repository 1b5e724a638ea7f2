"""isomesh.distributed on a LocalCluster of two worker processes: sharded scans equal the
single-process scan (keys, points, every cell), whatever the cuts; a worker killed mid-run
changes nothing; parts written to disk under a per-shard memory limit merge to the whole."""

import os
import pickle
import warnings

import numpy as np
import pytest

import isomesh
from isomesh import distributed

dask_distributed = pytest.importorskip("dask.distributed")

TORUS_BOX = [[-1.5, 1.5], [-1.5, 1.5], [-0.5, 0.5]]
THREE_TORUS_BOX = [[-0.7, 0.7]] * 2 + [[-1.2, 1.2]] * 2 + [[-2.2, 2.2]] * 2

CASES = {
    "sphere": (dict(name="sphere", edge=0.15), [[-1.3, 1.3]] * 3, [1, 0, 1]),
    "torus": (dict(name="torus", edge=0.1), TORUS_BOX, [1, 2, 1]),
    "flat-torus": (dict(name="flat-torus", edge=0.3), [[-1.2, 1.2]] * 4, [1, 2, 1]),
    "3-torus": (dict(name="3-torus", edge=0.9), THREE_TORUS_BOX, [1, 3, 3, 1]),
}


@pytest.fixture(scope="module")
def client():
    cluster = dask_distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    )
    c = dask_distributed.Client(cluster)
    yield c
    c.close()
    cluster.close()


def preset(spec):
    spec = dict(spec)
    return isomesh.Problem.preset(spec.pop("name"), **spec)


_singles = {}


def single(name):
    """The single-process scan of a case, and its complex (computed once)."""
    if name not in _singles:
        spec, box, _ = CASES[name]
        s = preset(spec).scan(box)
        _singles[name] = (s, s.complex())
    return _singles[name]


def assert_same_scan(r, s, c, what):
    assert np.array_equal(r.keys, s.keys), f"{what}: keys"
    assert r.points.tobytes() == s.points.tobytes(), f"{what}: points, bit for bit"
    rc = r.complex
    assert rc.vertices.tobytes() == c.vertices.tobytes(), f"{what}: vertices"
    assert np.array_equal(rc.boundary_vertices, c.boundary_vertices), what
    for j in range(1, c.dim + 1):
        for a, b in zip(rc.cells(j), c.cells(j)):
            assert np.array_equal(a, b), f"{what}: {j}-cells"
        assert np.array_equal(rc.boundary_cells(j), c.boundary_cells(j)), what
    t, u = r.topology, c.topology
    for key in ("cells", "euler_characteristic", "betti_mod2", "manifold", "closed",
                "components", "boundary_cells", "orientable"):
        assert t[key] == u[key], f"{what}: {key}"


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize("shards", [1, 2, 5, 8])
def test_sharded_scan_is_the_single_scan(client, name, shards):
    spec, box, betti = CASES[name]
    s, c = single(name)
    assert c.topology["betti_mod2"] == betti  # the case is the manifold it claims to be
    r = distributed.scan(preset(spec), box, shards, client=client)
    assert r.report["shards"] == shards
    assert sum(x["owned"] for x in r.report["per_shard"]) == len(s)
    assert_same_scan(r, s, c, f"{name}, {shards} shards")


def test_cuts_through_crossings_and_at_arbitrary_positions(client):
    spec, box, _ = CASES["torus"]
    s, c = single("torus")
    pts = s.points
    n = len(s)
    # A cut exactly at a crossing, and within 1e-12 of two others, on every axis.
    near = [
        sorted({pts[n // 3, a], pts[n // 2, a] + 1e-12, pts[2 * n // 3, a] - 1e-12})
        for a in range(3)
    ]
    r = distributed.scan(preset(spec), box, near, client=client)
    assert_same_scan(r, s, c, "cuts at crossings")
    # Arbitrary positions, mixed with counts.
    r = distributed.scan(preset(spec), box, [[-0.123456789], 3, [0.0101]], client=client)
    assert_same_scan(r, s, c, "arbitrary cuts")
    # At multiples of the edge length near a crossing (cuts through lattice vertices
    # themselves are in tests/shard.rs, which sees the triangulation).
    e = preset(spec).edge
    grid = [[float(np.round(pts[n // 4, a] / e) * e)] for a in range(3)]
    r = distributed.scan(preset(spec), box, grid, client=client)
    assert_same_scan(r, s, c, "cuts at multiples of the edge")


def test_a_killed_worker_changes_nothing(client, tmp_path):
    marker = str(tmp_path / "killed-once")

    def sphere(x):
        # The first call in any worker kills that worker's process, once.
        if not os.path.exists(marker):
            open(marker, "w").close()
            os._exit(1)
        return (x**2).sum(axis=1, keepdims=True) - 1.0

    box = [[-1.3, 1.3]] * 3
    p = isomesh.Problem(function=sphere, ambient_dim=3, codim=1, edge=0.15)
    r = distributed.scan(p, box, 4, client=client)
    # The marker is made just before the worker's process exits: one was killed mid-task.
    assert os.path.exists(marker), "no worker was killed"
    q = isomesh.Problem(
        "x1^2 + x2^2 + x3^2 - 1", ambient_dim=3, edge=0.15
    )
    s = q.scan(box)
    assert_same_scan(r, s, s.complex(), "after a worker was killed")


def test_parts_on_disk_under_a_memory_limit_merge_to_the_whole(client, tmp_path):
    spec, box = dict(name="torus", edge=0.05), TORUS_BOX
    s = preset(spec).scan(box)
    c = s.complex()
    # A limit under what the whole box's scan needs (its grid, about 5 MiB, is refused)...
    limit = 2 << 20
    with pytest.raises(ValueError, match="over the memory limit"):
        preset(spec).scan(box, max_memory=limit)
    # ...while each of 16 shards fits, and their parts merge to the whole scan.
    out = tmp_path / "parts"
    r = distributed.scan(preset(spec), box, 16, client=client, out=out, max_memory=limit)
    assert r.complex is None and r.keys is None
    files = sorted(os.listdir(out))
    assert files.count(distributed.MANIFEST) == 1
    assert sum(f.startswith("part-") for f in files) == 16
    assert r.topology["cells"] == c.topology["cells"]
    assert r.topology["euler_characteristic"] == c.topology["euler_characteristic"]
    merged = distributed.merge(out, tmp_path / "torus.ply")
    assert_same_scan(merged, s, c, "merged parts")
    assert (tmp_path / "torus.ply").stat().st_size > 0


def test_problems_pickle_whatever_made_them(tmp_path):
    spec = tmp_path / "circle.toml"
    spec.write_text('ambient_dim = 2\nequations = ["x1^2 + x2^2 - 1"]\nseeds = [[1, 0]]\n')
    problems = [
        isomesh.Problem("x^2 + y^2 - 1", variables=["x", "y"], seeds=[[1, 0]], edge=0.2),
        isomesh.Problem.preset("torus", R=1.2, r=0.3, edge=0.1, offset_seed=3),
        isomesh.Problem.from_toml(spec),
        isomesh.Problem.from_toml(spec.read_text(), name="text"),
    ]
    for p in problems:
        q = pickle.loads(pickle.dumps(p))
        assert (q.name, q.equations, q.edge, q.box, q.seeds) == (
            p.name, p.equations, p.edge, p.box, p.seeds)
        assert np.array_equal(q.trace().keys, p.trace().keys), p.name
    # The spec file is not needed where the pickle goes.
    blob = pickle.dumps(problems[2])
    spec.unlink()
    assert pickle.loads(blob).name == "circle"


def test_bad_shards_and_a_missing_client_are_clear_errors(client):
    p = preset(CASES["sphere"][0])
    box = CASES["sphere"][1]
    with pytest.raises(ValueError, match="at least 1"):
        distributed.scan(p, box, 0, client=client)
    with pytest.raises(ValueError, match="3 axes"):
        distributed.scan(p, box, (2, 2), client=client)
    with pytest.raises(ValueError, match="cuts must increase"):
        distributed.scan(p, box, [[0.5, 0.1], 1, 1], client=client)
    with pytest.raises(ValueError, match="rows"):
        distributed.scan(p, box[:2], 2, client=client)
    with pytest.raises(ValueError, match="halo"):
        distributed.scan(p, box, 2, client=client, halo=0.01)
