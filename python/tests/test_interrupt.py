"""Ctrl-C: SIGINT to a long trace raises KeyboardInterrupt and the process exits cleanly."""

import os
import signal
import subprocess
import sys
import textwrap
import time

import pytest

CHILD = textwrap.dedent("""
    import sys, time
    import numpy as np
    import isomesh
    mode = sys.argv[1]
    if mode == "equations":
        p = isomesh.Problem.preset("3-torus", edge=0.3)
    else:
        def f(x):
            time.sleep(0.01)
            return x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1.0
        p = isomesh.Problem(function=f, ambient_dim=3, codim=1, seeds=[[1, 0, 0]], edge=0.01)
    small = isomesh.Problem.preset("circle")
    print("started", flush=True)
    t0 = time.monotonic()
    try:
        s = p.trace(threads=2)
        print("finished", s.simplex_count, flush=True)
    except KeyboardInterrupt:
        print("interrupted after", round(time.monotonic() - t0, 2), flush=True)
        # Nothing is corrupted: the next trace runs to completion.
        s = small.trace()
        print("next", s.complete, s.simplex_count, flush=True)
""")


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
@pytest.mark.parametrize("mode", ["equations", "function"])
def test_sigint_stops_a_long_trace(mode):
    child = subprocess.Popen([sys.executable, "-c", CHILD, mode], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    assert child.stdout.readline().strip() == "started"
    time.sleep(1.0)
    sent = time.monotonic()
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=60)
    stopped_in = time.monotonic() - sent
    assert child.returncode == 0, err
    lines = out.split("\n")
    assert lines[0].startswith("interrupted after"), out
    assert lines[1].startswith("next True"), out
    assert stopped_in < 20


COMPLEX_CHILD = textwrap.dedent("""
    import time
    import isomesh
    s = isomesh.Problem.preset("sphere", r=3, edge=0.02).trace(threads=2)
    print("traced", s.simplex_count, flush=True)
    t0 = time.monotonic()
    try:
        c = s.complex()
        print("built", flush=True)
    except KeyboardInterrupt:
        print("interrupted after", round(time.monotonic() - t0, 3), flush=True)
        # Nothing was kept half built: the whole build runs again, and is timed.
        t0 = time.monotonic()
        s.complex()
        print("whole in", round(time.monotonic() - t0, 3), flush=True)
""")


@pytest.mark.skipif(sys.platform == "win32", reason="SIGINT")
def test_sigint_stops_the_cell_complex():
    child = subprocess.Popen([sys.executable, "-c", COMPLEX_CHILD], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    assert child.stdout.readline().startswith("traced")
    time.sleep(0.2)
    child.send_signal(signal.SIGINT)
    out, err = child.communicate(timeout=120)
    assert child.returncode == 0, err
    lines = out.split("\n")
    assert lines[0].startswith("interrupted after"), out
    assert lines[1].startswith("whole in"), out
    # Stopped during the build, not when it was done.
    interrupted, whole = float(lines[0].split()[-1]), float(lines[1].split()[-1])
    assert interrupted < 0.5 * whole, out
