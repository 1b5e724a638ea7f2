"""The Python layer against the CLI, and the callable form against the equation form.

    python python/bench/overhead.py --cli target/release/isomesh [--rounds 5] [--json out.json]

Runs A and B alternately (A B A B ...) and prints medians and ratios:
- every tracing reference case, `isomesh trace --preset P --edge E --no-complex` (a fresh
  process: its report's `elapsed_s`, the trace itself, and the process's wall time) against
  `Problem.preset(P, edge=E).trace()` in this process (its report's `elapsed_s`, and the wall
  time of the whole call: trace, suspect-crossing count, report); both give the same keys
  in the same order, checked first;
- the torus as an equation against the same f as a NumPy function: whole trace time, and the
  callable's points per second.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import isomesh

CASES = [
    ("S^2 in R^3", "sphere", {}, 0.0707),
    ("chair", "chair", {}, 0.0707),
    ("flat torus in R^4", "flat-torus", {}, 0.0775),
    ("S^2 in R^8", "sphere", {"d": 8}, 0.4216),
    ("flat torus in R^10", "flat-torus", {"d": 10}, 0.2335),
    ("3-torus in R^6", "3-torus", {}, 0.5555),
]


def cli_args(preset, params, edge):
    args = ["trace", "--preset", preset, "--edge", str(edge), "--quiet"]
    for k, v in params.items():
        args += ["--param", f"{k}={v}"]
    return args


def run_cli(cli, args, tmp):
    report = os.path.join(tmp, "r.json")
    t0 = time.perf_counter()
    subprocess.run([cli, *args, "--no-complex", "--report", report], check=True)
    wall = time.perf_counter() - t0
    with open(report) as f:
        return json.load(f)["elapsed_s"], wall


def same_keys(cli, preset, params, edge, tmp):
    """Whether the CLI and the package find the same simplices (their keys), in the same order."""
    out = os.path.join(tmp, "k.keys")
    subprocess.run([cli, *cli_args(preset, params, edge), "--no-complex", "--out", out],
                   check=True)
    ref = np.loadtxt(out, dtype=np.uint64, ndmin=2)
    s = isomesh.Problem.preset(preset, edge=edge, **params).trace()
    return s.simplex_count, np.array_equal(ref, s.keys)


def sorted_rows(a):
    return a[np.lexsort(a.T[::-1])]


def torus_function(x):
    t = np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1]) - 1.0
    return t * t + x[:, 2] * x[:, 2] - 0.16


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--cli", required=True)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--threads", type=int, default=None)
    ap.add_argument("--json")
    a = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for label, preset, params, edge in CASES:
            n, same = same_keys(a.cli, preset, params, edge, tmp)
            p = isomesh.Problem.preset(preset, edge=edge, **params)
            args = cli_args(preset, params, edge)
            if a.threads:
                args += ["--threads", str(a.threads)]
            cli_in, cli_wall, py, py_in = [], [], [], []
            for _ in range(a.rounds):
                e, w = run_cli(a.cli, args, tmp)
                cli_in.append(e)
                cli_wall.append(w)
                t0 = time.perf_counter()
                s = p.trace(threads=a.threads)
                py.append(time.perf_counter() - t0)
                py_in.append(s.report["elapsed_s"])
            m = {k: statistics.median(v) for k, v in
                 (("cli_elapsed_s", cli_in), ("cli_process_s", cli_wall), ("python_s", py),
                  ("python_elapsed_s", py_in))}
            rows.append({"case": label, "simplices": n, "same_keys": same, **m,
                         "elapsed_ratio": m["python_elapsed_s"] / m["cli_elapsed_s"],
                         "python_over_cli_elapsed": m["python_s"] / m["cli_elapsed_s"],
                         "python_over_cli_process": m["python_s"] / m["cli_process_s"]})
            r = rows[-1]
            print(f"{label:20} {n:>8} same keys={same}  elapsed_s: cli {m['cli_elapsed_s']:.4f} "
                  f"python {m['python_elapsed_s']:.4f} ratio {r['elapsed_ratio']:.3f}; "
                  f"whole call {m['python_s']:.4f} s against the process "
                  f"{m['cli_process_s']:.4f} s, ratio {r['python_over_cli_process']:.3f}",
                  flush=True)

        seeds = [[1.4, 0.0, 0.0]]
        text = isomesh.Problem(["(sqrt(x^2 + y^2) - 1)^2 + z^2 - 0.16"], seeds=seeds, edge=0.05)
        func = isomesh.Problem(function=torus_function, ambient_dim=3, codim=1, seeds=seeds,
                               edge=0.05)
        te, tf, rates, calls = [], [], [], []
        for _ in range(a.rounds):
            t0 = time.perf_counter()
            se = text.trace(threads=a.threads)
            te.append(time.perf_counter() - t0)
            t0 = time.perf_counter()
            sf = func.trace(threads=a.threads)
            tf.append(time.perf_counter() - t0)
            r = sf.report
            rates.append(r["function_points"] / r["function_s"])
            calls.append((r["function_calls"], r["function_points"]))
        same = np.array_equal(sorted_rows(se.keys), sorted_rows(sf.keys))
        m_e, m_f = statistics.median(te), statistics.median(tf)
        callable_row = {"case": "torus edge 0.05: equation vs NumPy function",
                        "simplices": se.simplex_count, "same_keys": bool(same),
                        "equation_s": m_e, "function_s": m_f, "ratio": m_f / m_e,
                        "function_points_per_s": statistics.median(rates),
                        "calls_points": calls[-1]}
        print(f"torus: equation {m_e:.4f} s, function {m_f:.4f} s, ratio {m_f / m_e:.2f}; "
              f"callable {statistics.median(rates):.3g} points/s over {calls[-1][0]} calls "
              f"({calls[-1][1]} points); same keys {same}", flush=True)
    if a.json:
        with open(a.json, "w") as f:
            json.dump({"rounds": a.rounds, "cases": rows, "callable": callable_row,
                       "python": sys.version.split()[0]}, f, indent=1)


if __name__ == "__main__":
    main()
