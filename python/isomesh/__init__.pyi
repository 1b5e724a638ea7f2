"""Type stubs of isomesh (the native module `isomesh._isomesh`)."""

import os
from typing import Any, Callable, Literal, Mapping, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import distributed as distributed

__version__: str

Backend = Literal["cpu", "gpu", "auto"]
PathLike = Union[str, os.PathLike]
Box = Sequence[Sequence[float]]
Points = Union[Sequence[Sequence[float]], npt.NDArray[np.float64]]
Function = Callable[[npt.NDArray[np.float64]], npt.ArrayLike]

def presets() -> dict[str, dict[str, Any]]:
    """The built-in manifolds: name -> {"about": str, "params": {name: default}}."""

class Problem:
    """An implicit manifold f^-1(0) to mesh: f, seeds near it, a box, a triangulation."""

    def __init__(
        self,
        equations: Union[str, Sequence[str], None] = None,
        *,
        function: Optional[Function] = None,
        ambient_dim: Optional[int] = None,
        codim: Optional[int] = None,
        variables: Optional[Sequence[str]] = None,
        parameters: Optional[Mapping[str, float]] = None,
        boundary: Optional[Sequence[str]] = None,
        seeds: Optional[Points] = None,
        box: Optional[Box] = None,
        edge: Optional[float] = None,
        triangulation: Optional[Literal["coxeter", "freudenthal"]] = None,
        offset_seed: Optional[int] = None,
        rotation_seed: Optional[int] = None,
        rotate: Optional[bool] = None,
        name: Optional[str] = None,
    ) -> None:
        """f as equations in the CLI's language, or `function`: an (n, d) float64 array in,
        an (n, k) array out (CPU backend only)."""

    @staticmethod
    def preset(
        name: str,
        *,
        seeds: Optional[Points] = None,
        box: Optional[Box] = None,
        triangulation: Optional[str] = None,
        offset_seed: Optional[int] = None,
        rotation_seed: Optional[int] = None,
        rotate: Optional[bool] = None,
        **params: float,
    ) -> Problem:
        """A built-in manifold; other keywords (edge, R, r, d, ...) are its parameters."""

    @staticmethod
    def from_toml(source: Union[PathLike, str], name: Optional[str] = None) -> Problem:
        """A spec in the CLI's TOML format: a path, or the text itself."""

    def trace(
        self,
        *,
        backend: Backend = "cpu",
        threads: Optional[int] = None,
        seeds: Optional[Points] = None,
        box: Optional[Box] = None,
        search: Optional[int] = None,
        search_seed: int = 1,
        precision: Optional[Literal["f32", "f64", "auto"]] = None,
        max_memory: Optional[int] = None,
    ) -> Sample:
        """Traces M from the seeds, or from points found in the box."""

    def scan(
        self,
        box: Optional[Box] = None,
        *,
        backend: Backend = "cpu",
        threads: Optional[int] = None,
        precision: Optional[Literal["f32", "f64", "auto"]] = None,
        max_memory: Optional[int] = None,
    ) -> Sample:
        """Scans every k-simplex of the triangulation in the box."""

    @property
    def name(self) -> str: ...
    @property
    def ambient_dim(self) -> int: ...
    @property
    def codim(self) -> int: ...
    @property
    def equations(self) -> Optional[list[str]]: ...
    @property
    def seeds(self) -> list[list[float]]: ...
    @property
    def box(self) -> Optional[list[list[float]]]: ...
    @property
    def edge(self) -> float: ...

class Sample:
    """The crossed k-simplices of a trace or scan."""

    @property
    def simplex_count(self) -> int: ...
    @property
    def ambient_dim(self) -> int: ...
    @property
    def codim(self) -> int: ...
    @property
    def complete(self) -> bool:
        """False when the run stopped early (memory limit)."""
    @property
    def points(self) -> npt.NDArray[np.float64]:
        """(N, d): the point of M in each simplex."""
    @property
    def keys(self) -> npt.NDArray[np.uint64]:
        """(N, W): the simplices' keys."""
    @property
    def report(self) -> dict[str, Any]:
        """The keys of the CLI's --report JSON."""
    def complex(self) -> Complex:
        """The cell complex (built once)."""
    def write(self, path: PathLike, format: Optional[str] = None) -> None:
        """The points as .csv, .xyz or .txt, or the simplices' keys as .keys."""
    def __len__(self) -> int: ...

class Complex:
    """The cell complex of a sample (its Hasse diagram)."""

    @property
    def dim(self) -> int: ...
    @property
    def ambient_dim(self) -> int: ...
    @property
    def vertices(self) -> npt.NDArray[np.float64]:
        """(N, d) vertices."""
    @property
    def boundary_vertices(self) -> npt.NDArray[np.bool_]: ...
    def cells(self, j: int) -> tuple[npt.NDArray[np.uint32], npt.NDArray[np.uint64]]:
        """(facets, offsets) of the j-cells, 1 <= j <= dim."""
    def boundary_cells(self, j: int) -> npt.NDArray[np.bool_]: ...
    @property
    def topology(self) -> dict[str, Any]:
        """cells, euler_characteristic, manifold, closed, betti_mod2, ..."""
    def mesh_arrays(self, projection: str = "auto") -> dict[str, npt.NDArray[Any]]: ...
    def to_meshio(self, projection: str = "auto") -> Any:
        """A meshio.Mesh."""
    def write(self, path: PathLike, format: Optional[str] = None, projection: str = "auto",
              ascii: bool = False) -> None:
        """Every output format of the CLI, chosen by the extension; PLY and VTU are binary
        unless ascii=True."""
    def picture(self, path: PathLike, width: int = 1200, height: int = 900,
                projection: str = "auto") -> None:
        """A PNG picture of the mesh."""
