//! The native module `isomesh._isomesh`: problems, traces and scans, samples and complexes as
//! NumPy arrays. The Python package `isomesh` re-exports it.

mod callable;
mod interrupt;
mod problem;
mod result;
mod shard;

use pyo3::exceptions::{
    PyFileNotFoundError, PyOSError, PyPermissionError, PyRuntimeError, PyValueError,
};
use pyo3::prelude::*;
use pyo3::types::PyDict;
use std::io::ErrorKind;

/// Rust's heap in this module is counted, as in the `isomesh` binary: the memory limit holds
/// against it and the report's `peak_memory_bytes` is measured.
#[global_allocator]
static ALLOC: isomesh::memory::CountingAlloc = isomesh::memory::CountingAlloc;

/// An isomesh error as the Python exception a caller expects, with the CLI's message.
pub(crate) fn to_py(e: isomesh::Error) -> PyErr {
    use isomesh::error::shown;
    use isomesh::Error as E;
    match e {
        E::Io { ref source, .. } => {
            let message = shown(&e.to_string());
            match source.kind() {
                ErrorKind::NotFound => PyFileNotFoundError::new_err(message),
                ErrorKind::PermissionDenied => PyPermissionError::new_err(message),
                _ => PyOSError::new_err(message),
            }
        }
        E::Output(m) => PyOSError::new_err(shown(&m)),
        e @ (E::Gpu(_) | E::Wgsl(_) | E::DeviceBound(_) | E::Interrupted(_)) => {
            PyRuntimeError::new_err(shown(&e.to_string()))
        }
        e => PyValueError::new_err(shown(&e.to_string())),
    }
}

/// Parses a JSON text into Python objects.
pub(crate) fn json_to_py<'py>(
    py: Python<'py>,
    v: &serde_json::Value,
) -> PyResult<Bound<'py, PyAny>> {
    py.import("json")?.call_method1("loads", (v.to_string(),))
}

/// The built-in manifolds: name -> {"about": str, "params": {name: default}}.
#[pyfunction]
fn presets(py: Python<'_>) -> PyResult<Bound<'_, PyDict>> {
    let out = PyDict::new(py);
    for p in isomesh::expr::PRESETS {
        let info = PyDict::new(py);
        info.set_item("about", p.about)?;
        let params = PyDict::new(py);
        for (n, v) in p.params {
            params.set_item(*n, *v)?;
        }
        info.set_item("params", params)?;
        out.set_item(p.name, info)?;
    }
    Ok(out)
}

#[pymodule]
fn _isomesh(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<problem::Problem>()?;
    m.add_class::<result::Sample>()?;
    m.add_class::<result::Complex>()?;
    m.add_function(wrap_pyfunction!(presets, m)?)?;
    m.add_function(wrap_pyfunction!(problem::_problem_from_recipe, m)?)?;
    m.add_function(wrap_pyfunction!(shard::_split_count, m)?)?;
    m.add_function(wrap_pyfunction!(shard::_shard_grid, m)?)?;
    m.add_function(wrap_pyfunction!(shard::_uniform_cuts, m)?)?;
    m.add("__version__", env!("CARGO_PKG_VERSION"))?;
    Ok(())
}
