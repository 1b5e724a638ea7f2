"""Every preset: the package gives the CLI's sample, in the same order, and its topology."""

import os

import numpy as np
import pytest

import isomesh
from conftest import cli_keys, run_cli

# Edges coarse enough that the whole table runs in seconds; the rest is each preset's default.
EDGES = {
    "circle": 0.05,
    "sphere": 0.1,
    "torus": 0.1,
    "chair": 0.1,
    "flat-torus": 0.2,
    "3-torus": 1.0,
    "complex-cosine": 0.2,
    "bagel-klein": 0.4,
    "cut-flat-torus": 0.3,
}


def test_every_preset_is_covered():
    assert sorted(isomesh.presets()) == sorted(EDGES)


@pytest.mark.parametrize("name", sorted(EDGES))
def test_preset_matches_cli(tmp_path, name):
    edge = EDGES[name]
    rep, cli_points = run_cli(tmp_path, "--preset", name, "--param", f"edge={edge}")
    s = isomesh.Problem.preset(name, edge=edge).trace(backend="cpu")
    assert s.complete
    assert s.simplex_count == rep["simplex_count"] > 0
    # The CLI writes each simplex's point, in the sample's order, in shortest round-trip form:
    # equal arrays mean the same simplices in the same order.
    assert np.array_equal(s.points, cli_points)
    keys = s.keys
    assert keys.shape[0] == s.simplex_count and keys.dtype == np.uint64
    assert len(np.unique(keys, axis=0)) == s.simplex_count
    # The same simplices, by their exact names, in the same order.
    assert np.array_equal(keys, cli_keys(tmp_path))
    topo = s.complex().topology
    assert topo["euler_characteristic"] == rep["euler_characteristic"]
    assert topo["cells"] == rep["cells"]
    report = s.report
    for key in ("simplex_count", "edge", "triangulation", "components", "euler_characteristic",
                "manifold", "closed", "betti_mod2", "offset"):
        assert report[key] == rep[key], key
    assert set(report) == set(rep)


def test_preset_flags_match_cli(tmp_path):
    """Triangulation flags mean the same in both."""
    rep, cli_points = run_cli(
        tmp_path, "--preset", "torus", "--edge", "0.15", "--triangulation", "freudenthal",
        "--offset-seed", "7", "--rotation-seed", "3")
    s = isomesh.Problem.preset("torus", edge=0.15, triangulation="freudenthal", offset_seed=7,
                               rotation_seed=3).trace()
    assert rep["triangulation"] == "freudenthal"
    assert s.simplex_count == rep["simplex_count"]
    assert np.array_equal(s.points, cli_points)
    assert np.array_equal(s.keys, cli_keys(tmp_path))


def test_keys_are_deterministic():
    p = isomesh.Problem.preset("torus", edge=0.1)
    a, b = p.trace(threads=1), p.trace(threads=2)
    assert np.array_equal(a.keys, b.keys)
    assert np.array_equal(a.points, b.points)


def test_a_gpu_report_says_what_crossed_to_the_device():
    p = isomesh.Problem.preset("torus", edge=0.1)
    try:
        s = p.trace(backend="gpu")
    except RuntimeError as e:
        if os.environ.get("ISOMESH_REQUIRE_GPU"):
            raise
        pytest.skip(f"no GPU: {e}")
    rep = s.report
    assert rep["backend"].startswith("gpu: ")
    assert rep["upload_bytes"] > 0 and rep["readback_bytes"] > 0
    assert rep["host_s"] >= 0.0
    cpu = p.trace(backend="cpu").report
    assert cpu["upload_bytes"] is None and cpu["host_s"] is None
    assert cpu["simplex_count"] == rep["simplex_count"]
