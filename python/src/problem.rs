//! `isomesh.Problem`: f (equations, a preset, a spec file or a Python callable) with its seeds,
//! box and triangulation; `trace()` and `scan()` run it with the GIL released.

use std::collections::BTreeMap;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

use isomesh::expr::{preset_spec, Spec, TriangulationSpec};
use isomesh::gpu::Precision;
use isomesh::{Backend, Error, Manifold, Mesher};
use pyo3::exceptions::{PyRuntimeWarning, PyTypeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::{PyDict, PyString, PyTuple};

use crate::callable::PyFunction;
use crate::interrupt::interruptible;
use crate::result::Sample;
use crate::to_py;

/// An implicit manifold f^-1(0) to mesh: f, seeds near it, a box, a triangulation.
///
/// Problem(equations, *, ambient_dim=None, variables=None, parameters=None, boundary=None,
///         seeds=None, box=None, edge=None, triangulation=None, offset_seed=None,
///         rotation_seed=None, rotate=None, name=None)
/// Problem(function=f, ambient_dim=d, codim=k, ...): f maps an (n, d) float64 array to an
/// (n, k) array (CPU backend only).
#[pyclass(module = "isomesh", frozen)]
pub struct Problem {
    mesher: Mesher,
    name: String,
    seeds: Vec<Vec<f64>>,
    bbox: Option<Vec<[f64; 2]>>,
    equations: Option<Vec<String>>,
    callable: Option<Arc<PyFunction>>,
    /// How to make this problem again, (constructor, keywords): what pickling sends.
    recipe: Py<PyAny>,
}

/// Triangulation settings given as keywords.
struct TriKeywords {
    edge: Option<f64>,
    kind: Option<String>,
    offset_seed: Option<u64>,
    rotation_seed: Option<u64>,
    rotate: Option<bool>,
}

impl TriKeywords {
    fn apply_to(&self, mut m: Mesher) -> PyResult<Mesher> {
        if let Some(e) = self.edge {
            m = m.edge(e);
        }
        if let Some(k) = &self.kind {
            m = m.triangulation(k.parse().map_err(to_py)?);
        }
        if let Some(s) = self.offset_seed {
            m = m.offset_seed(s);
        }
        match (self.rotate, self.rotation_seed) {
            (Some(false), Some(_)) => Err(PyValueError::new_err(
                "rotate=False and a rotation_seed: give one or the other",
            )),
            (Some(false), None) => Ok(m.rotation_seed(None)),
            (_, Some(s)) => Ok(m.rotation_seed(Some(s))),
            (_, None) => Ok(m),
        }
    }

    fn apply(&self, t: &mut TriangulationSpec) -> PyResult<()> {
        if let Some(e) = self.edge {
            t.edge = Some(e);
        }
        if let Some(k) = &self.kind {
            t.kind = Some(k.clone());
        }
        if let Some(s) = self.offset_seed {
            t.offset_seed = Some(s);
            t.offset = None;
        }
        match (self.rotate, self.rotation_seed) {
            (Some(false), Some(_)) => {
                return Err(PyValueError::new_err(
                    "rotate=False and a rotation_seed: give one or the other",
                ))
            }
            (Some(false), None) => {
                t.rotate = Some(false);
                t.rotation_seed = None;
            }
            (_, Some(s)) => {
                t.rotate = Some(true);
                t.rotation_seed = Some(s);
            }
            (Some(true), None) => t.rotate = Some(true),
            (None, None) => {}
        }
        Ok(())
    }
}

fn check_seeds(seeds: &[Vec<f64>], d: usize) -> PyResult<()> {
    for (i, s) in seeds.iter().enumerate() {
        if s.len() != d {
            return Err(PyValueError::new_err(format!(
                "seed {} has {} coordinates, the ambient dimension is {d}",
                i + 1,
                s.len()
            )));
        }
        if s.iter().any(|v| !v.is_finite()) {
            return Err(PyValueError::new_err(format!(
                "seed {} {s:?} has a non-finite coordinate",
                i + 1
            )));
        }
    }
    Ok(())
}

fn check_box(bbox: &[[f64; 2]], d: usize) -> PyResult<()> {
    isomesh::expr::spec::check_box(bbox, d).map_err(to_py)
}

impl Problem {
    fn from_problem(p: isomesh::expr::Problem, equations: Vec<String>, recipe: Py<PyAny>) -> Self {
        Problem {
            recipe,
            name: p.name.clone(),
            seeds: p.seeds.clone(),
            bbox: p.bbox.clone(),
            mesher: Mesher::from_problem(p),
            equations: Some(equations),
            callable: None,
        }
    }

    /// The mesher of one run: this problem's, with the run's seeds, box and settings.
    #[allow(clippy::too_many_arguments)]
    fn mesher(
        &self,
        run: &Run,
        seeds: Option<Vec<Vec<f64>>>,
        bbox: Option<Vec<[f64; 2]>>,
        backend: &str,
        threads: Option<usize>,
        precision: Option<&str>,
        max_memory: Option<u64>,
    ) -> PyResult<Mesher> {
        let d = self.mesher.ambient_dim();
        let mut m = self.mesher.clone();
        if let Some(seeds) = seeds {
            check_seeds(&seeds, d)?;
            m = m.seeds(seeds);
        }
        if let Some(b) = bbox {
            check_box(&b, d)?;
            m = m.bbox(b);
        }
        let precision = match precision.map(str::to_ascii_lowercase).as_deref() {
            None | Some("auto") => None,
            Some("f32") => Some(Precision::F32),
            Some("f64") => Some(Precision::F64),
            Some(p) => {
                return Err(PyValueError::new_err(format!(
                    "precision '{p}': use \"f32\", \"f64\" or \"auto\""
                )))
            }
        };
        if let Some(t) = threads {
            m = m.threads(t);
        }
        if let Some(bytes) = max_memory {
            if bytes == 0 {
                return Err(PyValueError::new_err("max_memory must be positive"));
            }
            m = m.max_memory(bytes);
        }
        // Like the CLI, the pool's threads poll for work while a trace runs, except for a
        // Python function, whose calls wait for the GIL.
        if let Some(c) = &run.callable {
            m = m.replace_function(c.clone()).map_err(to_py)?;
        }
        Ok(m.warm(self.callable.is_none())
            .backend(backend.parse::<Backend>().map_err(to_py)?)
            .precision(precision)
            .cancel(run.stop.clone()))
    }

    /// What one run owns: a stop flag and, for a Python function, a wrapper of its own.
    fn new_run(&self, py: Python<'_>) -> Run {
        let stop = Arc::new(AtomicBool::new(false));
        let callable = self
            .callable
            .as_ref()
            .map(|c| Arc::new(c.for_run(py, stop.clone())));
        Run { stop, callable }
    }

    /// Runs `mesher` in a worker thread; this thread waits with the GIL released, looking for
    /// Ctrl-C, and re-raises what the callable raised.
    fn run(&self, py: Python<'_>, run: Run, mesher: Mesher, exhaustive: bool) -> PyResult<Sample> {
        let manifold: Manifold = interruptible(py, &run.stop, run.callable.as_deref(), || {
            if exhaustive {
                mesher.scan()
            } else {
                mesher.trace()
            }
        })?;
        let calls = run.callable.as_ref().map(|c| c.stats());
        for w in manifold.warnings() {
            warn(py, &w.to_string())?;
        }
        if !manifold.complete() {
            let msg = format!(
                "{}; the {} simplices found so far are returned with complete = False",
                manifold.report().stopped.unwrap_or_default(),
                manifold.len()
            );
            warn(py, &msg)?;
        }
        Ok(Sample::new(
            manifold,
            self.name.clone(),
            run.callable,
            calls,
        ))
    }
}

/// Raises `msg` as a RuntimeWarning.
fn warn(py: Python<'_>, msg: &str) -> PyResult<()> {
    PyErr::warn(
        py,
        &py.get_type::<PyRuntimeWarning>(),
        &std::ffi::CString::new(msg).unwrap_or_default(),
        1,
    )
}

/// What one trace or scan owns, so that runs at once on one problem (from Python threads)
/// keep their stops and errors apart: its stop flag, and for a Python function a wrapper with
/// its own error slot and counters.
struct Run {
    stop: Arc<AtomicBool>,
    callable: Option<Arc<PyFunction>>,
}

#[pymethods]
impl Problem {
    #[new]
    #[pyo3(signature = (equations=None, *, function=None, ambient_dim=None, codim=None,
        variables=None, parameters=None, boundary=None, seeds=None, r#box=None, edge=None,
        triangulation=None, offset_seed=None, rotation_seed=None, rotate=None, name=None))]
    #[allow(clippy::too_many_arguments)]
    fn new(
        py: Python<'_>,
        equations: Option<Bound<'_, PyAny>>,
        function: Option<Bound<'_, PyAny>>,
        ambient_dim: Option<usize>,
        codim: Option<usize>,
        variables: Option<Vec<String>>,
        parameters: Option<BTreeMap<String, f64>>,
        boundary: Option<Vec<String>>,
        seeds: Option<Vec<Vec<f64>>>,
        r#box: Option<Vec<[f64; 2]>>,
        edge: Option<f64>,
        triangulation: Option<String>,
        offset_seed: Option<u64>,
        rotation_seed: Option<u64>,
        rotate: Option<bool>,
        name: Option<String>,
    ) -> PyResult<Self> {
        let keywords = PyDict::new(py);
        keywords.set_item("equations", &equations)?;
        keywords.set_item("function", &function)?;
        keywords.set_item("ambient_dim", ambient_dim)?;
        keywords.set_item("codim", codim)?;
        keywords.set_item("variables", &variables)?;
        keywords.set_item("parameters", &parameters)?;
        keywords.set_item("boundary", &boundary)?;
        keywords.set_item("seeds", &seeds)?;
        keywords.set_item("box", &r#box)?;
        keywords.set_item("edge", edge)?;
        keywords.set_item("triangulation", &triangulation)?;
        keywords.set_item("offset_seed", offset_seed)?;
        keywords.set_item("rotation_seed", rotation_seed)?;
        keywords.set_item("rotate", rotate)?;
        keywords.set_item("name", &name)?;
        let recipe = ("new", keywords).into_pyobject(py)?.into_any().unbind();
        let tri = TriKeywords {
            edge,
            kind: triangulation,
            offset_seed,
            rotation_seed,
            rotate,
        };
        let seeds = seeds.unwrap_or_default();
        match (equations, function) {
            (Some(_), Some(_)) => Err(PyValueError::new_err(
                "give equations or function=, not both",
            )),
            (None, None) => Err(PyValueError::new_err(
                "give equations (a string or a list of strings) or function=",
            )),
            (Some(eqs), None) => {
                let equations: Vec<String> = if let Ok(s) = eqs.cast::<PyString>() {
                    vec![s.to_string()]
                } else {
                    eqs.extract().map_err(|_| {
                        PyTypeError::new_err("equations must be a string or a list of strings")
                    })?
                };
                if codim.is_some_and(|k| k != equations.len()) {
                    return Err(PyValueError::new_err(format!(
                        "codim={} but {} equations are given",
                        codim.unwrap_or(0),
                        equations.len()
                    )));
                }
                let d = ambient_dim
                    .or(variables.as_ref().map(Vec::len))
                    .or(seeds.first().map(Vec::len))
                    .or(r#box.as_ref().map(Vec::len))
                    .ok_or_else(|| {
                        PyValueError::new_err(
                            "the ambient dimension is unknown: give ambient_dim, variables, \
                             seeds or box",
                        )
                    })?;
                check_seeds(&seeds, d)?;
                let mut t = TriangulationSpec::default();
                tri.apply(&mut t)?;
                // Where d was read off the seeds or the box, a name the equations use beyond
                // it is said to be so.
                let inferred = match (ambient_dim, &variables, seeds.first()) {
                    (None, None, Some(_)) => Some("the seeds"),
                    (None, None, None) => Some("the box"),
                    _ => None,
                };
                let spec = Spec {
                    ambient_dim: d,
                    variables,
                    parameters: parameters.unwrap_or_default(),
                    equations: equations.clone(),
                    boundary: boundary.unwrap_or_default(),
                    seeds,
                    bbox: r#box,
                    triangulation: Some(t),
                    ..Spec::default()
                };
                let p = spec
                    .resolve(name.as_deref().unwrap_or("problem"))
                    .map_err(|e| match (inferred, &e) {
                        (Some(from), Error::Parse(_)) => PyValueError::new_err(format!(
                            "{e} (the ambient dimension {d} was taken from {from}: give \
                             ambient_dim, or seeds and box of the equations' dimension)"
                        )),
                        _ => to_py(e),
                    })?;
                Ok(Problem::from_problem(p, equations, recipe))
            }
            (None, Some(f)) => {
                if !f.is_callable() {
                    return Err(PyTypeError::new_err("function must be callable"));
                }
                if variables.is_some() || parameters.is_some() || boundary.is_some() {
                    return Err(PyValueError::new_err(
                        "variables, parameters and boundary go with equations, not function=",
                    ));
                }
                let (d, k) = match (ambient_dim, codim) {
                    (Some(d), Some(k)) => (d, k),
                    _ => {
                        return Err(PyValueError::new_err(
                            "function= needs ambient_dim (d) and codim (k): f maps an (n, d) \
                             array to an (n, k) array",
                        ))
                    }
                };
                if d == 0 || d > isomesh::triangulation::MAX_DIM {
                    return Err(to_py(Error::Dimension(d)));
                }
                if k == 0 || k >= d {
                    return Err(PyValueError::new_err(format!(
                        "codim must be from 1 to ambient_dim - 1 = {}, not {k}",
                        d.saturating_sub(1)
                    )));
                }
                check_seeds(&seeds, d)?;
                if let Some(b) = &r#box {
                    check_box(b, d)?;
                }
                // Each run wraps the function anew with its own stop flag (`Problem::new_run`).
                let stop = Arc::new(AtomicBool::new(false));
                let callable = Arc::new(PyFunction::new(f.unbind(), d, k, stop));
                let name = name.unwrap_or_else(|| "function".into());
                let mut m = tri
                    .apply_to(Mesher::from_function(callable.clone()))?
                    .name(&name)
                    .seeds(seeds.clone());
                if let Some(b) = &r#box {
                    m = m.bbox(b.clone());
                }
                m.build_triangulation().map_err(to_py)?;
                Ok(Problem {
                    mesher: m,
                    name,
                    seeds,
                    bbox: r#box,
                    equations: None,
                    callable: Some(callable),
                    recipe,
                })
            }
        }
    }

    /// A built-in manifold (see `isomesh.presets()`); keywords other than the settings are
    /// the preset's parameters, e.g. `Problem.preset("torus", R=1.0, r=0.4, edge=0.05)`.
    #[staticmethod]
    #[pyo3(signature = (name, *, seeds=None, r#box=None, triangulation=None, offset_seed=None,
        rotation_seed=None, rotate=None, **params))]
    #[allow(clippy::too_many_arguments)]
    fn preset(
        py: Python<'_>,
        name: &str,
        seeds: Option<Vec<Vec<f64>>>,
        r#box: Option<Vec<[f64; 2]>>,
        triangulation: Option<String>,
        offset_seed: Option<u64>,
        rotation_seed: Option<u64>,
        rotate: Option<bool>,
        params: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<Self> {
        let keywords = match params {
            Some(p) => p.copy()?,
            None => PyDict::new(py),
        };
        keywords.set_item("name", name)?;
        keywords.set_item("seeds", &seeds)?;
        keywords.set_item("box", &r#box)?;
        keywords.set_item("triangulation", &triangulation)?;
        keywords.set_item("offset_seed", offset_seed)?;
        keywords.set_item("rotation_seed", rotation_seed)?;
        keywords.set_item("rotate", rotate)?;
        let recipe = ("preset", keywords).into_pyobject(py)?.into_any().unbind();
        let mut overrides = Vec::new();
        if let Some(p) = params {
            for (k, v) in p.iter() {
                let k: String = k.extract()?;
                let v: f64 = v.extract().map_err(|_| {
                    PyTypeError::new_err(format!("preset parameter {k} must be a number"))
                })?;
                overrides.push((k, v));
            }
        }
        let mut spec = preset_spec(name, &overrides).map_err(to_py)?;
        let d = spec.ambient_dim;
        if let Some(s) = seeds {
            check_seeds(&s, d)?;
            spec.seeds = s;
        }
        if let Some(b) = r#box {
            check_box(&b, d)?;
            spec.bbox = Some(b);
        }
        let mut t = spec.triangulation.clone().unwrap_or_default();
        TriKeywords {
            edge: None,
            kind: triangulation,
            offset_seed,
            rotation_seed,
            rotate,
        }
        .apply(&mut t)?;
        spec.triangulation = Some(t);
        let equations = spec.equations.clone();
        let p = spec.resolve(name).map_err(to_py)?;
        Ok(Problem::from_problem(p, equations, recipe))
    }

    /// A spec file in the CLI's TOML format (a path), or its text.
    #[staticmethod]
    #[pyo3(signature = (source, name=None))]
    fn from_toml(
        py: Python<'_>,
        source: &Bound<'_, PyAny>,
        name: Option<String>,
    ) -> PyResult<Self> {
        let text: Option<String> = source
            .cast::<PyString>()
            .ok()
            .map(|s| s.to_string())
            .filter(|s| s.contains('\n') || s.contains('='));
        let (spec, stem, text) = match text {
            Some(t) => (Spec::from_toml(&t).map_err(to_py)?, "spec".to_string(), t),
            None => {
                let path: std::path::PathBuf = source.extract()?;
                let stem = path
                    .file_stem()
                    .map(|s| s.to_string_lossy().into_owned())
                    .unwrap_or_default();
                let spec = Spec::from_file(&path).map_err(to_py)?;
                // The text travels with a pickled problem: the file need not be where it goes.
                let text = std::fs::read_to_string(&path)
                    .map_err(|e| to_py(Error::io(path.display().to_string(), e)))?;
                (spec, stem, text)
            }
        };
        let name = name.unwrap_or(stem);
        let keywords = PyDict::new(py);
        keywords.set_item("source", text)?;
        keywords.set_item("name", &name)?;
        let recipe = ("from_toml", keywords)
            .into_pyobject(py)?
            .into_any()
            .unbind();
        let equations = spec.equations.clone();
        let p = spec.resolve(&name).map_err(to_py)?;
        Ok(Problem::from_problem(p, equations, recipe))
    }

    /// Traces M from the seeds (or from points found in the box) on the given backend
    /// ("cpu", "gpu" or "auto"); `threads=None` uses every core.
    #[pyo3(signature = (*, backend="cpu", threads=None, seeds=None, r#box=None, search=None,
        search_seed=1, precision=None, max_memory=None))]
    #[allow(clippy::too_many_arguments)]
    fn trace(
        &self,
        py: Python<'_>,
        backend: &str,
        threads: Option<usize>,
        seeds: Option<Vec<Vec<f64>>>,
        r#box: Option<Vec<[f64; 2]>>,
        search: Option<usize>,
        search_seed: u64,
        precision: Option<&str>,
        max_memory: Option<u64>,
    ) -> PyResult<Sample> {
        let run = self.new_run(py);
        let mut m = self.mesher(&run, seeds, r#box, backend, threads, precision, max_memory)?;
        if let Some(n) = search {
            m = m.search(n);
        }
        self.run(py, run, m.search_seed(search_seed), false)
    }

    /// Scans every k-simplex of the triangulation in the box (the problem's, or `box`).
    #[pyo3(signature = (r#box=None, *, backend="cpu", threads=None, precision=None,
        max_memory=None))]
    fn scan(
        &self,
        py: Python<'_>,
        r#box: Option<Vec<[f64; 2]>>,
        backend: &str,
        threads: Option<usize>,
        precision: Option<&str>,
        max_memory: Option<u64>,
    ) -> PyResult<Sample> {
        let run = self.new_run(py);
        let m = self.mesher(&run, None, r#box, backend, threads, precision, max_memory)?;
        self.run(py, run, m, true)
    }

    /// The problem's name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// d, the dimension of the ambient space.
    #[getter]
    fn ambient_dim(&self) -> usize {
        self.mesher.ambient_dim()
    }

    /// k, the number of equations.
    #[getter]
    fn codim(&self) -> usize {
        self.mesher.codim()
    }

    /// The equations as given (None for a Python function).
    #[getter]
    fn equations(&self) -> Option<Vec<String>> {
        self.equations.clone()
    }

    /// The seeds (Newton-projected for equations).
    #[getter]
    fn seeds(&self) -> Vec<Vec<f64>> {
        self.seeds.clone()
    }

    /// The box, [[lo, hi], ...] per axis, or None.
    #[getter(r#box)]
    fn bbox(&self) -> Option<Vec<[f64; 2]>> {
        self.bbox.clone()
    }

    /// The longest edge of a d-simplex of the triangulation.
    #[getter]
    fn edge(&self) -> PyResult<f64> {
        Ok(self.mesher.build_triangulation().map_err(to_py)?.edge())
    }

    /// Pickling (for Dask and multiprocessing): the problem is made again from what it was
    /// made from (a Python function travels by reference, as pickle or cloudpickle sends it).
    fn __reduce__<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        let rebuild = py
            .import("isomesh._isomesh")?
            .getattr("_problem_from_recipe")?;
        (rebuild, (self.recipe.clone_ref(py),))
            .into_pyobject(py)
            .map(|t| t.into_any())
    }

    /// One shard of a sharded scan of `box` (see `isomesh.distributed`): the part of the
    /// scan of [lo, hi) widened by `halo` that the shard owns, as a dict of NumPy arrays.
    #[pyo3(signature = (r#box, lo, hi, closed, halo=None, *, backend="cpu", threads=None,
        precision=None, max_memory=None))]
    #[allow(clippy::too_many_arguments)]
    fn _scan_shard<'py>(
        &self,
        py: Python<'py>,
        r#box: Vec<[f64; 2]>,
        lo: Vec<f64>,
        hi: Vec<f64>,
        closed: Vec<bool>,
        halo: Option<f64>,
        backend: &str,
        threads: Option<usize>,
        precision: Option<&str>,
        max_memory: Option<u64>,
    ) -> PyResult<Bound<'py, PyDict>> {
        let run = self.new_run(py);
        let m = self.mesher(
            &run,
            None,
            Some(r#box),
            backend,
            threads,
            precision,
            max_memory,
        )?;
        let shard = isomesh::shard::Shard { lo, hi, closed };
        let part = py.detach(|| -> isomesh::Result<_> {
            let halo = match halo {
                Some(h) => h,
                None => isomesh::shard::default_halo(&m)?,
            };
            isomesh::shard::scan(&m, &shard, halo)
        });
        if let Some(e) = run.callable.as_ref().and_then(|c| c.take_error()) {
            return Err(e);
        }
        crate::shard::part_to_py(py, &part.map_err(to_py)?)
    }

    /// The default halo of a sharded scan: 1.1 times the triangulation's longest edge.
    fn _default_halo(&self) -> PyResult<f64> {
        isomesh::shard::default_halo(&self.mesher).map_err(to_py)
    }

    /// Assembles the parts of every shard of a sharded scan: (keys, points, Complex).
    fn _assemble<'py>(
        &self,
        py: Python<'py>,
        parts: Vec<Bound<'py, PyDict>>,
    ) -> PyResult<Bound<'py, PyAny>> {
        let parts = parts
            .iter()
            .map(crate::shard::part_from_py)
            .collect::<PyResult<Vec<_>>>()?;
        let all = py
            .detach(|| isomesh::shard::assemble(&parts))
            .map_err(to_py)?;
        let n = all.keys.len() / all.key_words.max(1);
        let d = self.mesher.ambient_dim();
        let keys = crate::result::array2(py, n, all.key_words, all.keys)?;
        let points = crate::result::array2(py, n, d, all.points)?;
        let complex = crate::result::Complex::assembled(
            all.complex,
            self.mesher.shared_function(),
            self.name.clone(),
            self.callable.clone(),
        );
        (keys, points, complex)
            .into_pyobject(py)
            .map(|t| t.into_any())
    }

    fn __repr__(&self) -> String {
        let f = self.mesher.function();
        format!(
            "Problem('{}', f: R^{} -> R^{}, {})",
            self.name,
            f.ambient_dim(),
            f.codim(),
            match &self.equations {
                Some(e) => format!("{e:?}"),
                None => "a Python function".into(),
            }
        )
    }
}

/// A pickled problem made again: `recipe` is (constructor, keywords) as `Problem.__reduce__`
/// gives it.
#[pyfunction]
pub(crate) fn _problem_from_recipe<'py>(
    py: Python<'py>,
    recipe: &Bound<'py, PyTuple>,
) -> PyResult<Bound<'py, PyAny>> {
    let (kind, keywords): (String, Bound<'py, PyDict>) = recipe.extract()?;
    let cls = py.get_type::<Problem>();
    match kind.as_str() {
        "new" => cls.call((), Some(&keywords)),
        "preset" => {
            let keywords = keywords.copy()?;
            let name = keywords
                .get_item("name")?
                .ok_or_else(|| PyValueError::new_err("a preset recipe without a name"))?;
            keywords.del_item("name")?;
            cls.getattr("preset")?.call((name,), Some(&keywords))
        }
        "from_toml" => cls.getattr("from_toml")?.call((), Some(&keywords)),
        k => Err(PyValueError::new_err(format!(
            "unknown problem recipe `{k}`"
        ))),
    }
}
