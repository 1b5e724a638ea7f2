"""Shared helpers: the `isomesh` command line next to the package, and sorted keys."""

import json
import os
import pathlib
import subprocess

import numpy as np
import pytest

ROOT = pathlib.Path(__file__).resolve().parents[2]


def cli_path():
    """The CLI binary: $ISOMESH_CLI, else the workspace's target directory."""
    env = os.environ.get("ISOMESH_CLI")
    if env:
        return pathlib.Path(env)
    target = pathlib.Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    for profile in ("debug", "release"):
        p = target / profile / "isomesh"
        if p.exists():
            return p
    pytest.fail("no isomesh binary: run `cargo build` or set ISOMESH_CLI")


def run_cli(tmp_path, *args):
    """Runs `isomesh trace ARGS`; returns its JSON report and its points, in order (its keys
    are left in `tmp_path`, for `cli_keys`)."""
    report = tmp_path / "cli.json"
    points = tmp_path / "cli.csv"
    keys = tmp_path / "cli.keys"
    cmd = [str(cli_path()), "trace", *args, "--quiet", "--report", str(report), "--out", str(points),
           "--out", str(keys)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=600)
    with open(report) as f:
        rep = json.load(f)
    pts = np.loadtxt(points, delimiter=",", skiprows=1, ndmin=2)
    return rep, pts


def cli_keys(tmp_path):
    """The simplex keys the last `run_cli` in `tmp_path` wrote, (N, W) uint64, in order."""
    return np.loadtxt(tmp_path / "cli.keys", dtype=np.uint64, ndmin=2)


def sorted_rows(a):
    """The rows of a 2-D array in lexicographic order."""
    a = np.asarray(a)
    return a[np.lexsort(a.T[::-1])]
