"""isomesh: piecewise-linear meshes of implicit manifolds f^-1(0), f: R^d -> R^k, of any
dimension and codimension, traced on Coxeter triangulations.

    >>> import isomesh
    >>> p = isomesh.Problem(["x^2 + y^2 + z^2 - 1"], seeds=[[1, 0, 0]], edge=0.2)
    >>> s = p.trace()
    >>> s.complex().topology["euler_characteristic"]
    2
"""

from ._isomesh import Complex, Problem, Sample, __version__, presets
from . import distributed

__all__ = ["Complex", "Problem", "Sample", "distributed", "presets", "__version__"]
