//! Parts of a sharded scan as dicts of NumPy arrays (what Dask sends between processes and
//! `isomesh.distributed` writes as .npz), and the shard grid.

use isomesh::shard::{Part, PartLevel, PartStats};
use numpy::{IntoPyArray, PyReadonlyArrayDyn};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::result::array2;

/// The part as a dict: `meta` (d, id words, key words, defects, m), `vertex_ids` (n, I),
/// `points` (n, d), and per j = 1..m `ids{j}` (n_j, I), `offsets{j}` (n_j + 1,) and
/// `facets{j}` (F_j, I); the counters as numbers.
pub(crate) fn part_to_py<'py>(py: Python<'py>, p: &Part) -> PyResult<Bound<'py, PyDict>> {
    let out = PyDict::new(py);
    let iw = p.id_words;
    let meta = vec![
        p.ambient_dim as i64,
        iw as i64,
        p.key_words as i64,
        p.defects as i64,
        p.levels.len() as i64,
    ];
    out.set_item("meta", meta.into_pyarray(py))?;
    let rows = |v: &[u64]| v.len() / iw.max(1);
    out.set_item(
        "vertex_ids",
        array2(py, rows(&p.vertex_ids), iw, p.vertex_ids.clone())?,
    )?;
    out.set_item(
        "points",
        array2(
            py,
            p.points.len() / p.ambient_dim.max(1),
            p.ambient_dim,
            p.points.clone(),
        )?,
    )?;
    for (j, l) in p.levels.iter().enumerate() {
        let j = j + 1;
        out.set_item(
            format!("ids{j}"),
            array2(py, rows(&l.ids), iw, l.ids.clone())?,
        )?;
        out.set_item(format!("offsets{j}"), l.offsets.clone().into_pyarray(py))?;
        out.set_item(
            format!("facets{j}"),
            array2(py, rows(&l.facets), iw, l.facets.clone())?,
        )?;
    }
    let s = &p.stats;
    out.set_item("scanned", s.scanned)?;
    out.set_item("owned", s.owned)?;
    out.set_item("oracle_calls", s.oracle_calls)?;
    out.set_item("scan_s", s.scan_s)?;
    out.set_item("complex_s", s.complex_s)?;
    Ok(out)
}

/// An array of the dict, flattened, checked for its element type (`dtype`). Arrays that
/// came through pickling or a file may be unaligned or empty: NumPy makes an aligned copy.
fn flat<T: numpy::Element + Copy>(
    d: &Bound<'_, PyDict>,
    key: &str,
    dtype: &str,
) -> PyResult<Vec<T>> {
    let py = d.py();
    let v = d
        .get_item(key)?
        .ok_or_else(|| PyValueError::new_err(format!("a part without `{key}`")))?;
    let v = py
        .import("numpy")?
        .call_method1("require", (v, dtype, "CA"))
        .map_err(|_| PyValueError::new_err(format!("part `{key}`: not an array of {dtype}")))?;
    if v.len()? == 0 {
        return Ok(Vec::new());
    }
    let a: PyReadonlyArrayDyn<'_, T> = v
        .extract()
        .map_err(|_| PyValueError::new_err(format!("part `{key}`: not an array of {dtype}")))?;
    Ok(a.as_array().iter().copied().collect())
}

/// The inverse of [`part_to_py`] (counters are not read back).
pub(crate) fn part_from_py(d: &Bound<'_, PyDict>) -> PyResult<Part> {
    let meta: Vec<i64> = flat(d, "meta", "int64")?;
    let bad = || PyValueError::new_err("a part with malformed `meta`");
    let [dim, iw, kw, defects, m] = <[i64; 5]>::try_from(meta).map_err(|_| bad())?;
    if dim < 1 || iw < 2 || kw < 1 || kw >= iw || defects < 0 || !(1..dim).contains(&m) {
        return Err(bad());
    }
    let (dim, iw) = (dim as usize, iw as usize);
    let ids = |key: &str| -> PyResult<Vec<u64>> {
        let v: Vec<u64> = flat(d, key, "uint64")?;
        if v.len() % iw != 0 {
            return Err(PyValueError::new_err(format!(
                "part `{key}`: not rows of {iw} words"
            )));
        }
        Ok(v)
    };
    let vertex_ids = ids("vertex_ids")?;
    let points: Vec<f64> = flat(d, "points", "float64")?;
    if points.len() != vertex_ids.len() / iw * dim {
        return Err(PyValueError::new_err(
            "part: `points` and `vertex_ids` disagree",
        ));
    }
    let mut levels = Vec::new();
    for j in 1..=m as usize {
        let l = PartLevel {
            ids: ids(&format!("ids{j}"))?,
            offsets: flat(d, &format!("offsets{j}"), "uint64")?,
            facets: ids(&format!("facets{j}"))?,
        };
        let ok = l.offsets.len() == l.ids.len() / iw + 1
            && l.offsets.first() == Some(&0)
            && l.offsets.windows(2).all(|w| w[0] <= w[1])
            && l.offsets.last().copied() == Some((l.facets.len() / iw) as u64);
        if !ok {
            return Err(PyValueError::new_err(format!(
                "part: `offsets{j}` do not index `facets{j}`"
            )));
        }
        levels.push(l);
    }
    Ok(Part {
        ambient_dim: dim,
        id_words: iw,
        key_words: kw as usize,
        vertex_ids,
        points,
        levels,
        defects: defects as usize,
        stats: PartStats::default(),
    })
}

/// Shards per axis for `n` shards in all (see `isomesh::shard::split_count`).
#[pyfunction]
pub(crate) fn _split_count(r#box: Vec<[f64; 2]>, n: usize) -> Vec<usize> {
    isomesh::shard::split_count(&r#box, n)
}

/// The grid of shards of `box` cut at `cuts` (per axis, interior positions): a list of
/// (lo, hi, closed) in row-major order.
#[pyfunction]
#[allow(clippy::type_complexity)]
pub(crate) fn _shard_grid(
    r#box: Vec<[f64; 2]>,
    cuts: Vec<Vec<f64>>,
) -> PyResult<Vec<(Vec<f64>, Vec<f64>, Vec<bool>)>> {
    let shards = isomesh::shard::grid(&r#box, &cuts).map_err(crate::to_py)?;
    Ok(shards.into_iter().map(|s| (s.lo, s.hi, s.closed)).collect())
}

/// Interior cut positions splitting each axis into `counts[a]` equal parts.
#[pyfunction]
pub(crate) fn _uniform_cuts(r#box: Vec<[f64; 2]>, counts: Vec<usize>) -> Vec<Vec<f64>> {
    isomesh::shard::uniform_cuts(&r#box, &counts)
}
