"""Bad input: Python exceptions with clear messages, never a crash."""

import numpy as np
import pytest

import isomesh


def test_malformed_equation_names_line_and_column():
    with pytest.raises(ValueError, match=r"line 1, column \d+"):
        isomesh.Problem(["x^2 + * y"], ambient_dim=3)
    with pytest.raises(ValueError, match=r"line \d+, column \d+ \(equation 2"):
        isomesh.Problem(["x^2 + y^2 + z^2 - 1", "x + (y"], ambient_dim=3)


def test_unknown_preset_and_parameter():
    with pytest.raises(ValueError, match="unknown preset 'doughnut'"):
        isomesh.Problem.preset("doughnut")
    with pytest.raises(ValueError):
        isomesh.Problem.preset("torus", Q=2.0)


def test_no_seed_and_no_box():
    p = isomesh.Problem(["x^2 + y^2 + z^2 - 1"], ambient_dim=3)
    with pytest.raises(ValueError, match="no seed and no box"):
        p.trace()
    with pytest.raises(ValueError, match="needs a box"):
        p.scan()


def test_bad_arguments():
    with pytest.raises(ValueError, match="ambient dimension is unknown"):
        isomesh.Problem(["x1^2 - 1"])
    with pytest.raises(ValueError, match="seed 1 has 2 coordinates"):
        isomesh.Problem(["x^2 + y^2 + z^2 - 1"], seeds=[[1, 0]], ambient_dim=3)
    with pytest.raises(ValueError, match="backend 'tpu'"):
        isomesh.Problem.preset("circle").trace(backend="tpu")
    with pytest.raises(ValueError, match="needs ambient_dim"):
        isomesh.Problem(function=lambda x: x[:, :1])
    with pytest.raises(TypeError, match="callable"):
        isomesh.Problem(function=3, ambient_dim=3, codim=1)
    with pytest.raises(FileNotFoundError, match="nowhere.toml"):
        isomesh.Problem.from_toml("/nowhere.toml")


def problem(f, **kw):
    return isomesh.Problem(function=f, ambient_dim=3, codim=1, seeds=[[1, 0, 0]], edge=0.2, **kw)


def test_wrong_output_shape():
    with pytest.raises(ValueError, match=r"shape \(\d+, 2\).*expected \(\d+, 1\)"):
        problem(lambda x: np.zeros((len(x), 2))).trace()
    with pytest.raises(ValueError, match=r"shape \(3,\)"):
        problem(lambda x: np.zeros(3)).trace()


def test_output_that_is_no_array():
    with pytest.raises(ValueError, match="array of floats"):
        problem(lambda x: ["a"] * len(x)).trace()


def test_nan_from_the_function():
    def f(x):
        out = x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1.0
        out[x[:, 2] > 0.5] = np.nan
        return out

    with pytest.raises(ValueError, match="NaN at the point"):
        problem(f).trace()


class Boom(Exception):
    pass


def test_exception_propagates_with_its_traceback():
    def f(x):
        if len(x) > 100:
            raise Boom("no more")
        return x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1.0

    with pytest.raises(Boom, match="no more") as info:
        problem(f).trace()
    assert any(entry.name == "f" for entry in info.traceback)
    # The problem is still usable afterwards.
    good = problem(lambda x: x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1.0)
    assert good.trace().complete


def test_mesh_format_that_does_not_hold_the_manifold(tmp_path):
    c = isomesh.Problem.preset("circle").trace().complex()
    with pytest.raises(OSError, match="cannot hold a 1-manifold"):
        c.write(tmp_path / "x.stl")
    with pytest.raises(OSError, match="unknown output format"):
        c.write(tmp_path / "x.docx")
    with pytest.raises(IndexError):
        c.cells(2)


def test_boxes_and_seeds_that_are_no_numbers_or_too_wide():
    # A box wider than the largest float, an empty one, a seed that is not finite: clear
    # errors, not "internal error".
    p = isomesh.Problem(["x^2 + y^2 + z^2 - 1"], ambient_dim=3)
    with pytest.raises(ValueError, match="wider than the largest number"):
        p.scan(box=[[-1.2e308, 1.2e308]] * 3)
    with pytest.raises(ValueError, match="lo < hi"):
        p.scan(box=[[1.5, -1.5]] * 3)
    with pytest.raises(ValueError, match="exhaustive scan"):
        p.scan(box=[[-3e306, 3e306]] * 3)
    with pytest.raises(ValueError, match="non-finite"):
        isomesh.Problem(["x^2 + y^2 + z^2 - 1"], seeds=[[float("nan"), 0, 0]], ambient_dim=3)


def test_finding_nothing_is_an_error_not_an_empty_result():
    # As on the command line: no zero in the box, or f NaN everywhere, raises and says why.
    p = isomesh.Problem(["x^2 + y^2 + z^2 + 0.75"], ambient_dim=3)
    with pytest.raises(ValueError, match="no crossed simplex was found"):
        p.scan(box=[[-1.25, 1.25]] * 3)
    with pytest.raises(ValueError, match="no crossed simplex was found"):
        p.trace(box=[[-1.25, 1.25]] * 3)
    nan = isomesh.Problem(["sqrt(-3 - x^2) + y"], ambient_dim=3)
    with pytest.raises(ValueError, match="NaN or infinite"):
        nan.scan(box=[[-1, 1]] * 3)


def test_zero_equations_and_zero_regions_are_errors():
    with pytest.raises(ValueError, match="identically 0"):
        isomesh.Problem(["0 * x + y - y"], ambient_dim=3).scan(box=[[-1, 1]] * 3)
    half = isomesh.Problem(["max(y - 0.3, 0)"], ambient_dim=3)
    with pytest.raises(ValueError, match="identically 0 around"):
        half.scan(box=[[-1, 1]] * 3)
    with pytest.raises(ValueError, match="identically 0 around"):
        half.trace(box=[[-1, 1]] * 3)


def test_a_parameter_may_not_take_a_coordinates_name():
    with pytest.raises(ValueError, match="always name the coordinates"):
        isomesh.Problem(["x1^2 + x2^2 + x3^2 - 1"], ambient_dim=3, parameters={"x2": 0.0})


def test_a_manifold_in_a_face_of_the_box_is_kept_whole():
    p = isomesh.Problem(["y - 0.45"], ambient_dim=3)
    for box in ([[-1, 1], [0.45, 1.3], [-1, 1]], [[-1, 1], [-0.2, 0.45], [-1, 1]]):
        topo = p.scan(box=box).complex().topology
        assert (topo["components"], topo["euler_characteristic"]) == (1, 1), box


def test_unbounded_inputs_and_thread_counts_are_capped():
    # A spec that never ends is read only so far; a thread count beyond the machine runs the
    # machine's cap, with a warning.
    with pytest.raises(ValueError, match="a spec file is at most"):
        isomesh.Problem.from_toml("/dev/zero")
    p = isomesh.Problem.preset("circle")
    with pytest.warns(RuntimeWarning, match="more than this machine can use"):
        s = p.trace(threads=123457)
    assert 1 <= s.report["threads"] <= 1024
    assert s.simplex_count == p.trace(threads=1).simplex_count


def test_the_report_measures_peak_memory():
    r = isomesh.Problem.preset("sphere", edge=0.05).trace().report
    assert r["peak_memory_bytes"] > 100_000, r["peak_memory_bytes"]


def test_runs_at_once_on_one_problem_keep_their_errors_apart():
    # Two threads scan one problem at once; the function raises only in the first one's box.
    # Each run has its own stop flag and error slot: the first always raises, the second
    # never does and finds what it finds alone.
    import threading

    def f(x):
        if (x[:, 0] > 1.7).any():
            raise Boom("beyond 1.7")
        return x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 0.8

    p = problem(f)
    wide = [[-1.3, 2.4], [-1.3, 1.3], [-1.3, 1.3]]
    near = [[-1.2, 1.2]] * 3
    alone = p.scan(box=near).simplex_count
    for _ in range(6):
        got = {}

        def run(name, box):
            try:
                got[name] = p.scan(box=box).simplex_count
            except Boom as e:
                got[name] = e

        threads = [
            threading.Thread(target=run, args=("wide", wide)),
            threading.Thread(target=run, args=("near", near)),
        ]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert isinstance(got["wide"], Boom), got
        assert got["near"] == alone, got


def test_complex_values_wrong_seed_lengths_and_control_characters():
    with pytest.raises(ValueError, match="complex numbers"):
        problem(lambda x: (x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1.0) + 0j).trace()
    # d read off a seed of two coordinates: the message says where d came from.
    with pytest.raises(ValueError, match="taken from the seeds"):
        isomesh.Problem(["x^2 + y^2 + z^2 - 1"], seeds=[[0.6, 0.8]])
    # User text echoed in a message is escaped, as on the command line.
    with pytest.raises(ValueError) as info:
        isomesh.Problem(["x^2 + y\x00 - 1"], ambient_dim=3)
    assert "\x00" not in str(info.value) and "\\0" in str(info.value), str(info.value)


def test_a_function_may_trace_its_own_problem():
    # The function runs a trace and a scan of its own problem (1 and 2 threads) while the
    # outer run waits on it: each run has its own pool and stop flag, so neither waits on
    # the other. A watchdog turns a deadlock into a failure.
    import threading

    calls = {"n": 0}
    inner = []

    def f(x):
        calls["n"] += 1
        if calls["n"] in (3, 30):
            for threads in (1, 2):
                inner.append(p.trace(threads=threads).simplex_count)
                inner.append(p.scan(box=[[-1.5, 1.5]] * 3, threads=threads).simplex_count)
        return x[:, 0] ** 2 + x[:, 1] ** 2 + x[:, 2] ** 2 - 1

    p = isomesh.Problem(function=f, ambient_dim=3, codim=1, seeds=[[1, 0, 0]], edge=0.2)
    for threads, mode in [(1, "trace"), (2, "trace"), (1, "scan"), (2, "scan")]:
        calls["n"], got = 0, {}

        def run():
            if mode == "trace":
                got["n"] = p.trace(threads=threads).simplex_count
            else:
                got["n"] = p.scan(box=[[-1.5, 1.5]] * 3, threads=threads).simplex_count

        t = threading.Thread(target=run, daemon=True)
        t.start()
        t.join(120)
        assert not t.is_alive(), f"{mode} with {threads} threads: deadlocked"
        assert got["n"] > 0 and all(n == got["n"] for n in inner), (mode, threads, got, inner)
        inner.clear()
