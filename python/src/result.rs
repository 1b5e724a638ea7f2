//! `isomesh.Sample` (the crossed k-simplices of a trace or scan) and `isomesh.Complex` (the
//! cell complex built from them), with NumPy arrays and every output format of the CLI.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use isomesh::complex::Topology;
use isomesh::export::{Mesh, Projection};
use isomesh::expr::ImplicitFunction;
use isomesh::mesher::{picture_complex, write_complex};
use isomesh::{Manifold, WriteOptions};
use numpy::ndarray::{Array1, Array2};
use numpy::{IntoPyArray, PyArray1, PyArray2};
use pyo3::exceptions::{PyIndexError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::callable::{CallStats, PyFunction};
use crate::interrupt::interruptible;
use crate::{json_to_py, to_py};

/// The crossed k-simplices of a trace or scan: keys, points on M, counters.
#[pyclass(module = "isomesh", frozen)]
pub struct Sample {
    inner: Arc<Manifold>,
    name: String,
    callable: Option<Arc<PyFunction>>,
    calls: Option<CallStats>,
}

impl Sample {
    pub(crate) fn new(
        inner: Manifold,
        name: String,
        callable: Option<Arc<PyFunction>>,
        calls: Option<CallStats>,
    ) -> Self {
        Sample {
            inner: Arc::new(inner),
            name,
            callable,
            calls,
        }
    }
}

/// Runs `work` with the GIL released, then re-raises what the Python function raised in it.
fn released<T: Send>(
    py: Python<'_>,
    callable: &Option<Arc<PyFunction>>,
    work: impl FnOnce() -> isomesh::Result<T> + Send,
) -> PyResult<T> {
    if let Some(c) = callable {
        c.reset();
    }
    let r = py.detach(work);
    if let Some(e) = callable.as_ref().and_then(|c| c.take_error()) {
        return Err(e);
    }
    r.map_err(to_py)
}

pub(crate) fn array2<'py, T: numpy::Element>(
    py: Python<'py>,
    rows: usize,
    cols: usize,
    v: Vec<T>,
) -> PyResult<Bound<'py, PyArray2<T>>> {
    Ok(Array2::from_shape_vec((rows, cols), v)
        .map_err(|e| PyValueError::new_err(e.to_string()))?
        .into_pyarray(py))
}

#[pymethods]
impl Sample {
    /// Number of crossed k-simplices.
    #[getter]
    fn simplex_count(&self) -> usize {
        self.inner.sample().len()
    }

    fn __len__(&self) -> usize {
        self.inner.sample().len()
    }

    /// d.
    #[getter]
    fn ambient_dim(&self) -> usize {
        self.inner.sample().ambient_dim()
    }

    /// k.
    #[getter]
    fn codim(&self) -> usize {
        self.inner.sample().codim()
    }

    /// False when the run stopped early (memory limit): what was found so far.
    #[getter]
    fn complete(&self) -> bool {
        self.inner.sample().stats.stopped.is_none()
    }

    /// The point of M in each simplex, (N, d) float64.
    #[getter]
    fn points<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let s = self.inner.sample();
        let pts = py.detach(|| s.points());
        array2(py, s.len(), s.ambient_dim(), pts)
    }

    /// The simplices' keys, (N, W) uint64, in the sample's order.
    #[getter]
    fn keys<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<u64>>> {
        let s = self.inner.sample();
        let w = s.codec().words();
        let mut v = Vec::with_capacity(s.len() * w);
        for i in 0..s.len() {
            v.extend_from_slice(s.key(i));
        }
        array2(py, s.len(), w, v)
    }

    /// The CLI's `--report` keys, with the topology's once `complex()` was built.
    #[getter]
    fn report<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let mut v = serde_json::to_value(self.inner.report())
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        if let (Some(st), Some(r)) = (self.calls, v.as_object_mut()) {
            r.insert("function_calls".into(), st.calls.into());
            r.insert("function_points".into(), st.points.into());
            r.insert("function_s".into(), st.seconds.into());
        }
        json_to_py(py, &v)
    }

    /// The cell complex (built once, within the run's memory limit).
    fn complex(&self, py: Python<'_>) -> PyResult<Complex> {
        let inner = self.inner.clone();
        // Ctrl-C stops the build and raises KeyboardInterrupt.
        if let Some(c) = &self.callable {
            c.reset();
        }
        let cancel = AtomicBool::new(false);
        interruptible(py, &cancel, self.callable.as_deref(), || {
            inner.complex_cancellable(&cancel).map(|_| ())
        })?;
        Ok(Complex {
            inner: Source::Run(self.inner.clone()),
            name: self.name.clone(),
            callable: self.callable.clone(),
        })
    }

    /// Writes the points (.csv, .xyz, .txt), the simplices' keys (.keys) or, building the
    /// complex, the mesh (.ply, .obj, .off, .stl, .mesh, .vtu, .npz); `format` overrides the
    /// extension.
    #[pyo3(signature = (path, format=None))]
    fn write(&self, py: Python<'_>, path: PathBuf, format: Option<&str>) -> PyResult<()> {
        let opts = WriteOptions {
            format: format.map(str::to_string),
            ..WriteOptions::default()
        };
        let inner = self.inner.clone();
        released(py, &self.callable, move || inner.write_with(&path, &opts))
    }

    fn __repr__(&self) -> String {
        let s = self.inner.sample();
        format!(
            "Sample('{}', {} simplices, R^{} -> R^{}{})",
            self.name,
            s.len(),
            s.ambient_dim(),
            s.codim(),
            if self.complete() { "" } else { ", incomplete" }
        )
    }
}

/// The cell complex of a sample: vertices, cells of every dimension with their facets (the
/// Hasse diagram), topology, meshes.
#[pyclass(module = "isomesh", frozen)]
pub struct Complex {
    inner: Source,
    name: String,
    callable: Option<Arc<PyFunction>>,
}

/// Where a complex comes from: a run, or an assembly of a sharded scan's parts.
enum Source {
    Run(Arc<Manifold>),
    Assembled(Arc<Assembled>),
}

/// An assembled complex, with f (to orient its cells) and its topology once asked for.
pub(crate) struct Assembled {
    pub complex: isomesh::complex::Complex,
    pub function: Arc<dyn ImplicitFunction>,
    pub topology: OnceLock<(Topology, f64)>,
}

impl Assembled {
    fn topology(&self) -> &(Topology, f64) {
        self.topology.get_or_init(|| {
            let t0 = Instant::now();
            let t = self.complex.topology();
            (t, t0.elapsed().as_secs_f64())
        })
    }
}

impl Complex {
    /// The complex of a sharded scan, assembled.
    pub(crate) fn assembled(
        complex: isomesh::complex::Complex,
        function: Arc<dyn ImplicitFunction>,
        name: String,
        callable: Option<Arc<PyFunction>>,
    ) -> Self {
        Complex {
            inner: Source::Assembled(Arc::new(Assembled {
                complex,
                function,
                topology: OnceLock::new(),
            })),
            name,
            callable,
        }
    }

    fn get(&self) -> &isomesh::complex::Complex {
        match &self.inner {
            Source::Run(m) => m
                .complex()
                .expect("a Complex is made after its build succeeded"),
            Source::Assembled(a) => &a.complex,
        }
    }

    fn function(&self) -> &dyn ImplicitFunction {
        match &self.inner {
            Source::Run(m) => m.function(),
            Source::Assembled(a) => &*a.function,
        }
    }

    /// The topology and the seconds it took.
    fn topology_and_time(&self) -> isomesh::Result<(&Topology, Option<f64>)> {
        match &self.inner {
            Source::Run(m) => Ok((m.topology()?, m.report().complex.map(|r| r.topology_s))),
            Source::Assembled(a) => {
                let (t, secs) = a.topology();
                Ok((t, Some(*secs)))
            }
        }
    }

    fn mesh_then<T: Send>(
        &self,
        py: Python<'_>,
        projection: &str,
        work: impl FnOnce(&Mesh) -> isomesh::Result<T> + Send,
    ) -> PyResult<T> {
        let c = self.get();
        let d = c.ambient_dim();
        let projection = Projection::parse(projection, d).map_err(to_py)?;
        let (name, f) = (self.name.clone(), self.function());
        released(py, &self.callable, move || {
            let mesh = Mesh::new(c, Some(f), &projection, &name);
            work(&mesh)
        })
    }
}

#[pymethods]
impl Complex {
    /// m, the dimension of the manifold.
    #[getter]
    fn dim(&self) -> usize {
        self.get().dim()
    }

    /// d.
    #[getter]
    fn ambient_dim(&self) -> usize {
        self.get().ambient_dim()
    }

    /// The vertices, (N, d) float64: row i is vertex i of `cells(1)`.
    #[getter]
    fn vertices<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyArray2<f64>>> {
        let c = self.get();
        array2(py, c.vertex_count(), c.ambient_dim(), c.points().to_vec())
    }

    /// Whether each vertex lies on the boundary of M (a cut of the box or boundary), (N,) bool.
    #[getter]
    fn boundary_vertices<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        let c = self.get();
        let n = c.interior_vertex_count();
        Array1::from_iter((0..c.vertex_count()).map(|i| i >= n)).into_pyarray(py)
    }

    /// The j-cells, 1 <= j <= m, as in the .npz export: `(facets, offsets)` where the facets
    /// of cell i (indices of (j-1)-cells; of vertices for j = 1) are
    /// `facets[offsets[i]:offsets[i + 1]]`.
    #[allow(clippy::type_complexity)]
    fn cells<'py>(
        &self,
        py: Python<'py>,
        j: usize,
    ) -> PyResult<(Bound<'py, PyArray1<u32>>, Bound<'py, PyArray1<u64>>)> {
        let c = self.get();
        if j == 0 || j > c.dim() {
            return Err(PyIndexError::new_err(format!(
                "cells({j}): j must be from 1 to the manifold dimension {} (the vertices are \
                 `vertices`)",
                c.dim()
            )));
        }
        let level = c.level(j);
        let mut facets = Vec::new();
        let mut offsets = Vec::with_capacity(level.len() + 1);
        offsets.push(0u64);
        for i in 0..level.len() {
            facets.extend_from_slice(level.facets(i));
            offsets.push(facets.len() as u64);
        }
        Ok((facets.into_pyarray(py), offsets.into_pyarray(py)))
    }

    /// Whether each j-cell lies on the boundary of M, (n_j,) bool.
    fn boundary_cells<'py>(
        &self,
        py: Python<'py>,
        j: usize,
    ) -> PyResult<Bound<'py, PyArray1<bool>>> {
        let c = self.get();
        if j == 0 || j > c.dim() {
            return Err(PyIndexError::new_err(format!(
                "boundary_cells({j}): j must be from 1 to {}",
                c.dim()
            )));
        }
        let level = c.level(j);
        Ok(Array1::from_iter((0..level.len()).map(|i| level.on_boundary(i))).into_pyarray(py))
    }

    /// cells, euler_characteristic, manifold, closed, boundary_cells, orientable, betti_mod2,
    /// components, ... (the topology keys of the CLI's report).
    #[getter]
    fn topology<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let c = self.get();
        let (t, topo_s) = self.topology_and_time().map_err(to_py)?;
        let v = serde_json::json!({
            "dim": t.dim,
            "cells": t.cells,
            "euler_characteristic": t.euler_characteristic,
            "manifold": t.manifold,
            "closed": t.closed,
            "boundary_cells": t.boundary_cells,
            "boundary_euler_characteristic": t.boundary_euler_characteristic,
            "components": t.components,
            "closed_components": t.closed_components,
            "orientable": t.orientable,
            "betti_mod2": t.betti_mod2,
            "offender_count": t.offender_count,
            "offenders": t.offenders,
            "defects": t.defects,
            "complex_s": c.stats.elapsed_s,
            "topology_s": topo_s,
        });
        json_to_py(py, &v)
    }

    /// Arrays for a mesh viewer: `points` (N, 3) seen through `projection` ("auto": the
    /// coordinates up to d = 3, else PCA; "pca"; or coordinates such as "1,2,4"), and the
    /// `lines`, `triangles` or `tetrahedra` (vertex indices) that the manifold's dimension has.
    #[pyo3(signature = (projection="auto"))]
    fn mesh_arrays<'py>(&self, py: Python<'py>, projection: &str) -> PyResult<Bound<'py, PyDict>> {
        let m = self.get().dim();
        let lines: Vec<u32> = if m == 1 {
            let e = self.get().level(1);
            (0..e.len()).flat_map(|i| e.facets(i).to_vec()).collect()
        } else {
            Vec::new()
        };
        let (xyz, tris, tets) = self.mesh_then(py, projection, |mesh| {
            Ok((
                mesh.xyz.clone(),
                mesh.triangles.concat(),
                mesh.tetrahedra.concat(),
            ))
        })?;
        let out = PyDict::new(py);
        out.set_item("points", array2(py, xyz.len() / 3, 3, xyz)?)?;
        if m == 1 {
            out.set_item("lines", array2(py, lines.len() / 2, 2, lines)?)?;
        }
        if m == 2 {
            out.set_item("triangles", array2(py, tris.len() / 3, 3, tris)?)?;
        }
        if m == 3 {
            out.set_item("tetrahedra", array2(py, tets.len() / 4, 4, tets)?)?;
        }
        Ok(out)
    }

    /// A `meshio.Mesh`: points in R^d for d <= 3 (else seen through `projection`), the
    /// lines, triangles or tetrahedra, and point data `coordinates` (all d) and `boundary`.
    #[pyo3(signature = (projection="auto"))]
    fn to_meshio<'py>(&self, py: Python<'py>, projection: &str) -> PyResult<Bound<'py, PyAny>> {
        let meshio = py.import("meshio")?;
        let (m, d) = (self.get().dim(), self.get().ambient_dim());
        let kind = match m {
            1 => "line",
            2 => "triangle",
            3 => "tetra",
            _ => {
                return Err(PyValueError::new_err(format!(
                    "meshio has no cells for a {m}-manifold: use cells(j), or write(\"x.npz\")"
                )))
            }
        };
        let arrays = self.mesh_arrays(py, projection)?;
        let cells = arrays
            .get_item(["lines", "triangles", "tetrahedra"][m - 1])?
            .ok_or_else(|| PyValueError::new_err("no cells"))?;
        let vertices = self.vertices(py)?;
        let points = if d <= 3 {
            vertices.clone().into_any()
        } else {
            arrays
                .get_item("points")?
                .ok_or_else(|| PyValueError::new_err("no points"))?
        };
        let point_data = PyDict::new(py);
        point_data.set_item("coordinates", vertices)?;
        let boundary = self
            .boundary_vertices(py)
            .call_method1("astype", ("uint8",))?;
        point_data.set_item("boundary", boundary)?;
        let kwargs = PyDict::new(py);
        kwargs.set_item("point_data", point_data)?;
        meshio
            .getattr("Mesh")?
            .call((points, vec![(kind, cells)]), Some(&kwargs))
    }

    /// Writes the mesh (.ply, .obj, .off, .stl, .mesh, .vtu, .npz) or the sample's points
    /// (.csv, .xyz, .txt), like the CLI's --out; `format` overrides the extension and
    /// `projection` chooses how R^d is seen in 3-D; `ascii` writes PLY and VTU as text
    /// (like --ascii) instead of binary.
    #[pyo3(signature = (path, format=None, projection="auto", ascii=false))]
    fn write(
        &self,
        py: Python<'_>,
        path: PathBuf,
        format: Option<&str>,
        projection: &str,
        ascii: bool,
    ) -> PyResult<()> {
        let opts = WriteOptions {
            format: format.map(str::to_string),
            projection: Some(projection.to_string()),
            ascii,
        };
        match &self.inner {
            Source::Run(m) => {
                let m = m.clone();
                released(py, &self.callable, move || m.write_with(&path, &opts))
            }
            Source::Assembled(_) => {
                let (c, f, name) = (self.get(), self.function(), &self.name);
                released(py, &self.callable, move || {
                    write_complex(c, Some(f), name, &path, &opts)
                })
            }
        }
    }

    /// Draws the mesh into a PNG picture of `width` x `height` pixels.
    #[pyo3(signature = (path, width=1200, height=900))]
    fn picture(&self, py: Python<'_>, path: PathBuf, width: usize, height: usize) -> PyResult<()> {
        match &self.inner {
            Source::Run(m) => {
                let m = m.clone();
                released(py, &self.callable, move || m.picture(&path, width, height))
            }
            Source::Assembled(a) => {
                let (c, f, name) = (self.get(), self.function(), &self.name);
                released(py, &self.callable, move || {
                    let (t, _) = a.topology();
                    picture_complex(c, t, Some(f), name, &path, width, height)
                })
            }
        }
    }

    fn __repr__(&self) -> String {
        let c = self.get();
        format!(
            "Complex({}-manifold in R^{}, cells {:?})",
            c.dim(),
            c.ambient_dim(),
            c.counts()
        )
    }
}
