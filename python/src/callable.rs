//! f as a vectorised Python callable: an (n, d) float64 array in, an (n, k) array out.

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Instant;

use isomesh::expr::ImplicitFunction;
use numpy::ndarray::ArrayView2;
use numpy::{PyArrayDyn, PyArrayMethods, PyUntypedArrayMethods, ToPyArray};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

/// A Python callable seen as f: R^d -> R^k. The trace calls it from its worker threads, each
/// call holding the GIL for one batch. The first error it raises (or the first NaN or wrong
/// shape) is kept, the run's stop flag is raised, and the caller re-raises it when the run
/// has stopped.
pub struct PyFunction {
    f: Py<PyAny>,
    d: usize,
    k: usize,
    /// The stop flag of the run in progress.
    stop: Arc<AtomicBool>,
    error: Mutex<Option<PyErr>>,
    calls: AtomicU64,
    points: AtomicU64,
    nanos: AtomicU64,
}

/// Counters of the callable over one run.
#[derive(Clone, Copy, Debug, Default)]
pub struct CallStats {
    pub calls: u64,
    pub points: u64,
    pub seconds: f64,
}

impl PyFunction {
    /// Wraps `f`, which maps an (n, d) array to an (n, k) one; `stop` is raised on error.
    pub fn new(f: Py<PyAny>, d: usize, k: usize, stop: Arc<AtomicBool>) -> Self {
        PyFunction {
            f,
            d,
            k,
            stop,
            error: Mutex::new(None),
            calls: AtomicU64::new(0),
            points: AtomicU64::new(0),
            nanos: AtomicU64::new(0),
        }
    }

    /// A wrapper of the same function for one run: its own stop flag, error slot and
    /// counters, so that runs at once on one problem keep their errors and stops apart.
    pub fn for_run(&self, py: Python<'_>, stop: Arc<AtomicBool>) -> Self {
        PyFunction::new(self.f.clone_ref(py), self.d, self.k, stop)
    }

    /// Clears the kept error and the counters before a run.
    pub fn reset(&self) {
        *self.error.lock().unwrap_or_else(|e| e.into_inner()) = None;
        self.calls.store(0, Ordering::Relaxed);
        self.points.store(0, Ordering::Relaxed);
        self.nanos.store(0, Ordering::Relaxed);
    }

    /// The error the callable raised during the run, if any.
    pub fn take_error(&self) -> Option<PyErr> {
        self.error.lock().unwrap_or_else(|e| e.into_inner()).take()
    }

    /// What the run cost in calls of the callable.
    pub fn stats(&self) -> CallStats {
        CallStats {
            calls: self.calls.load(Ordering::Relaxed),
            points: self.points.load(Ordering::Relaxed),
            seconds: self.nanos.load(Ordering::Relaxed) as f64 * 1e-9,
        }
    }

    fn failed(&self) -> bool {
        self.error
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .is_some()
    }

    fn call(&self, py: Python<'_>, points: &[f64], out: &mut [f64]) -> PyResult<()> {
        let n = points.len() / self.d;
        let x = ArrayView2::from_shape((n, self.d), points)
            .map_err(|e| PyValueError::new_err(e.to_string()))?
            .to_pyarray(py);
        let result = self.f.bind(py).call1((x,))?;
        let np = py.import("numpy")?;
        // Complex values have no sign: refused, not cast with a warning.
        let complex = np
            .call_method1("iscomplexobj", (&result,))?
            .extract::<bool>()?;
        if complex {
            return Err(PyValueError::new_err(format!(
                "function returned complex numbers: it must return real floats of shape \
                 ({n}, {})",
                self.k
            )));
        }
        let arr = np
            .call_method1("asarray", (result, np.getattr("float64")?))
            .map_err(|e| {
                let err = PyValueError::new_err(format!(
                    "function must return an array of floats of shape ({n}, {}): {e}",
                    self.k
                ));
                err.set_cause(py, Some(e));
                err
            })?;
        let arr = arr.cast_into::<PyArrayDyn<f64>>().map_err(|e| {
            PyValueError::new_err(format!("function returned no float64 array: {e}"))
        })?;
        let shape = arr.shape().to_vec();
        let fits = shape == [n, self.k] || (self.k == 1 && shape == [n]);
        if !fits {
            let shape: Vec<String> = shape.iter().map(usize::to_string).collect();
            let shape = match shape.len() {
                1 => format!("({},)", shape[0]),
                _ => format!("({})", shape.join(", ")),
            };
            return Err(PyValueError::new_err(format!(
                "function returned an array of shape {shape} for {n} points of R^{}: expected \
                 ({n}, {}){}",
                self.d,
                self.k,
                if self.k == 1 {
                    format!(" or ({n},)")
                } else {
                    String::new()
                }
            )));
        }
        let ro = arr.readonly();
        let view = ro.as_array();
        for (o, v) in out.iter_mut().zip(view.iter()) {
            *o = *v;
        }
        if let Some(i) = out.iter().position(|v| v.is_nan()) {
            let row = i / self.k;
            return Err(PyValueError::new_err(format!(
                "function returned NaN at the point {:?} (row {row} of the batch, component {})",
                &points[row * self.d..(row + 1) * self.d],
                i % self.k
            )));
        }
        Ok(())
    }
}

impl ImplicitFunction for PyFunction {
    fn ambient_dim(&self) -> usize {
        self.d
    }
    fn codim(&self) -> usize {
        self.k
    }
    fn serial(&self) -> bool {
        true
    }
    fn eval_batch(&self, points: &[f64], out: &mut [f64]) {
        if points.is_empty() {
            return;
        }
        if self.failed() {
            out.fill(f64::NAN);
            return;
        }
        let t0 = Instant::now();
        let result = Python::attach(|py| self.call(py, points, out));
        self.calls.fetch_add(1, Ordering::Relaxed);
        self.points
            .fetch_add((points.len() / self.d) as u64, Ordering::Relaxed);
        self.nanos
            .fetch_add(t0.elapsed().as_nanos() as u64, Ordering::Relaxed);
        if let Err(e) = result {
            out.fill(f64::NAN);
            let mut slot = self.error.lock().unwrap_or_else(|e| e.into_inner());
            if slot.is_none() {
                *slot = Some(e);
            }
            self.stop.store(true, Ordering::Relaxed);
        }
    }
}
