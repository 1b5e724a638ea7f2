"""f as a NumPy callable: the same arithmetic as an equation gives the same simplices."""

import numpy as np
import pytest

import isomesh
from conftest import sorted_rows


def sphere(x):
    return x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1] + x[:, 2] * x[:, 2] - 1.0


def torus(x):
    t = np.sqrt(x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1]) - 1.0
    return (t * t + x[:, 2] * x[:, 2] - 0.16)[:, None]


def flat_torus(x):
    return np.stack([x[:, 0] * x[:, 0] + x[:, 1] * x[:, 1] - 1.0,
                     x[:, 2] * x[:, 2] + x[:, 3] * x[:, 3] - 1.0], axis=1)


CASES = [
    ("sphere", ["x^2 + y^2 + z^2 - 1"], sphere, [[1.0, 0.0, 0.0]], 0.1),
    ("torus", ["(sqrt(x^2 + y^2) - 1)^2 + z^2 - 0.16"], torus, [[1.4, 0.0, 0.0]], 0.08),
    ("flat torus", ["x1^2 + x2^2 - 1", "x3^2 + x4^2 - 1"], flat_torus, [[1.0, 0.0, 1.0, 0.0]], 0.2),
]


@pytest.mark.parametrize("label,equations,f,seeds,edge", CASES, ids=[c[0] for c in CASES])
def test_callable_gives_the_equation_keys(label, equations, f, seeds, edge):
    d, k = len(seeds[0]), len(equations)
    by_text = isomesh.Problem(equations, seeds=seeds, edge=edge).trace()
    calls = []

    def counted(x):
        calls.append(x.shape)
        return f(x)

    by_function = isomesh.Problem(function=counted, ambient_dim=d, codim=k, seeds=seeds,
                                  edge=edge).trace()
    assert by_function.simplex_count == by_text.simplex_count > 0
    assert np.array_equal(sorted_rows(by_function.keys), sorted_rows(by_text.keys))
    assert all(len(s) == 2 and s[1] == d for s in calls)
    assert by_function.report["function_calls"] == len(calls)
    chi = by_function.complex().topology["euler_characteristic"]
    assert chi == by_text.complex().topology["euler_characteristic"]


def test_callable_gets_whole_batches():
    """Each trace level's vertices come in one call, not in per-thread chunks."""
    sizes = []

    def f(x):
        sizes.append(len(x))
        return sphere(x)

    p = isomesh.Problem(function=f, ambient_dim=3, codim=1, seeds=[[1, 0, 0]], edge=0.01)
    s = p.trace(threads=2)
    # A level of this trace has about 900 new vertices; in parallel chunks (2 threads, 4
    # chunks each) no call would see more than about 120.
    assert max(sizes) >= 800
    assert s.report["function_points"] == sum(sizes)


def test_callable_scan_and_box_search():
    box = [[-1.5, 1.5]] * 3
    p = isomesh.Problem(function=sphere, ambient_dim=3, codim=1, box=box, edge=0.2)
    q = isomesh.Problem(["x^2 + y^2 + z^2 - 1"], box=box, edge=0.2)
    assert np.array_equal(sorted_rows(p.scan().keys), sorted_rows(q.scan().keys))
    assert np.array_equal(sorted_rows(p.trace().keys), sorted_rows(q.trace().keys))


def test_callable_on_gpu_is_refused_naming_why():
    p = isomesh.Problem(function=sphere, ambient_dim=3, codim=1, seeds=[[1, 0, 0]])
    with pytest.raises(RuntimeError, match="runs on the CPU backend"):
        p.trace(backend="gpu")
    # auto falls back to the CPU for a callable.
    assert p.trace(backend="auto").report["backend"] == "cpu"
