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
    """Runs `isomesh trace ARGS`; returns its JSON report and its points, in order."""
    report = tmp_path / "cli.json"
    points = tmp_path / "cli.csv"
    cmd = [str(cli_path()), "trace", *args, "--quiet", "--report", str(report), "--out", str(points)]
    subprocess.run(cmd, check=True, capture_output=True, timeout=600)
    with open(report) as f:
        rep = json.load(f)
    pts = np.loadtxt(points, delimiter=",", skiprows=1, ndmin=2)
    return rep, pts


def sorted_rows(a):
    """The rows of a 2-D array in lexicographic order."""
    a = np.asarray(a)
    return a[np.lexsort(a.T[::-1])]
