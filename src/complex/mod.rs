//! The cell complex M-hat built from a traced sample S (Boissonnat, Kachanovich and Wintraecken, "Tracing isomanifolds in R^d in time
//! polynomial in d using Coxeter-Freudenthal-Kuhn triangulations", sections 3.2 and 5.1).
//!
//! Its j-cells (j = 0..m) are the (k+j)-simplices of T with a crossed k-face: the cell is
//! where the piecewise-linear f-hat vanishes inside that simplex, and its facets are the cells
//! of the simplex's facets. Every decision of the oracle is the exact one for a symbolic
//! perturbation, so this structure is that of a generic M-hat, with no geometric test.
//!
//! A domain (box, boundary inequalities g >= 0) clips the cells: S holds the crossings inside
//! it, the rim those just outside. A cell with both kinds of vertex is cut, and the cut is a
//! boundary cell one dimension lower, whose vertices lie on the edges from an inside to an
//! outside crossing, where the edge leaves the domain.
//!
//! The complex is built level by level: the cofacets of the (j-1)-cells, sorted, are the
//! j-cells, and each group of equal cofacets lists the j-cell's facets. All orders are sorted
//! orders, so the result does not depend on the thread count.

mod build;
mod packed;
pub mod surface;
pub mod topology;

use std::sync::{Arc, OnceLock};

use serde::Serialize;

use crate::error::Result;
use crate::expr::ImplicitFunction;
use crate::trace::{Domain, Sample};

pub(crate) use build::CellKeys;
pub use surface::Surface;
pub use topology::Topology;

/// The j-cells of one dimension j >= 1 and their facets (cells of dimension j - 1).
#[derive(Clone, Debug, Default)]
pub struct Level {
    offsets: Vec<u32>,
    facets: Vec<u32>,
    interior: usize,
}

impl Level {
    /// Number of cells.
    pub fn len(&self) -> usize {
        self.offsets.len().saturating_sub(1)
    }
    /// Whether there is no cell.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// The facets of cell `i` (indices of cells one dimension lower).
    pub fn facets(&self, i: usize) -> &[u32] {
        &self.facets[self.offsets[i] as usize..self.offsets[i + 1] as usize]
    }
    /// Cells `interior()..len()` lie on the boundary of M-hat (cuts of the domain); the
    /// others are (clipped) cells of simplices of T.
    pub fn interior(&self) -> usize {
        self.interior
    }
    /// Whether cell `i` lies on the boundary.
    pub fn on_boundary(&self, i: usize) -> bool {
        i >= self.interior
    }
    /// The level of cells with these facet lists (`offsets`: one more than cells, from 0),
    /// the first `interior` of them interior.
    pub(crate) fn from_lists(offsets: Vec<u32>, facets: Vec<u32>, interior: usize) -> Self {
        Level {
            offsets,
            facets,
            interior,
        }
    }
    fn push(&mut self, facets: impl IntoIterator<Item = u32>) {
        if self.offsets.is_empty() {
            self.offsets.push(0);
        }
        self.facets.extend(facets);
        self.offsets.push(self.facets.len() as u32);
    }
}

/// Counters of a construction.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ComplexStats {
    /// Edges of M-hat (1-cells) whose (k+1)-simplex does not have exactly two crossed
    /// k-faces among S and the rim (degenerate or non-finite values, or a trace stopped
    /// early): left out, and their cofaces flagged by the manifold check.
    pub defects: usize,
    /// Wall time, seconds.
    pub elapsed_s: f64,
}

/// The polytopal cell complex M-hat: vertices with coordinates in R^d, and j-cells for
/// j = 1..m, each listing its facets (the Hasse diagram).
///
/// ```
/// let sphere = isomesh::Mesher::preset("sphere", &[])?.edge(0.2).trace()?;
/// let c = sphere.complex()?;
/// assert_eq!((c.ambient_dim(), c.dim()), (3, 2));
/// // Every edge has two vertices; cells of a closed surface have no boundary.
/// let edges = c.level(1);
/// assert!((0..edges.len()).all(|i| edges.facets(i).len() == 2));
/// assert_eq!(c.boundary_counts(), vec![0, 0]);
/// let n = c.counts();
/// assert_eq!(n[0] as i64 - n[1] as i64 + n[2] as i64, 2);
/// # Ok::<(), isomesh::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Complex {
    d: usize,
    m: usize,
    /// d per vertex: S's points (shared with the sample where no boundary vertex is
    /// added), then the boundary vertices.
    points: Arc<Vec<f64>>,
    interior_vertices: usize,
    levels: Vec<Level>,
    /// The 2-cells as polygons, oriented consistently where they can be, once asked for
    /// (the topology and a mesh's export both need them).
    polygons: OnceLock<surface::Polygons>,
    /// What it took.
    pub stats: ComplexStats,
}

impl Complex {
    /// Builds M-hat from the sample `s` of `f`, clipped by the box `bbox` and `f`'s boundary
    /// inequalities (the domain the sample was traced in), within the default memory limit.
    pub fn build(s: &Sample, f: &dyn ImplicitFunction, bbox: Option<&[[f64; 2]]>) -> Result<Self> {
        Self::build_within(s, f, bbox, crate::memory::default_limit())
    }

    /// [`Complex::build`], refusing with an error (before allocating) a construction whose
    /// working memory would pass `max_memory` bytes.
    pub fn build_within(
        s: &Sample,
        f: &dyn ImplicitFunction,
        bbox: Option<&[[f64; 2]]>,
        max_memory: u64,
    ) -> Result<Self> {
        build::build(s, &Domain::new(f, bbox), max_memory, None, false).map(|(c, _)| c)
    }

    /// [`Complex::build_within`], with the keys that name its cells globally.
    pub(crate) fn build_keyed(
        s: &Sample,
        f: &dyn ImplicitFunction,
        bbox: Option<&[[f64; 2]]>,
        max_memory: u64,
    ) -> Result<(Self, CellKeys)> {
        let (c, keys) = build::build(s, &Domain::new(f, bbox), max_memory, None, true)?;
        Ok((c, keys.expect("asked for")))
    }

    /// A complex from its parts: `points` (d per vertex, the first `interior_vertices` of
    /// them in S) and the levels 1..=m.
    pub(crate) fn from_parts(
        d: usize,
        points: Vec<f64>,
        interior_vertices: usize,
        levels: Vec<Level>,
        stats: ComplexStats,
    ) -> Self {
        Complex {
            d,
            m: levels.len(),
            points: Arc::new(points),
            interior_vertices,
            levels,
            polygons: OnceLock::new(),
            stats,
        }
    }

    /// The 2-cells as polygons, built on first use.
    pub(crate) fn polygons(&self) -> &surface::Polygons {
        self.polygons.get_or_init(|| surface::Polygons::of(self))
    }

    /// [`Complex::build_within`], stopping with an error between levels once `cancel` is set.
    pub fn build_cancellable(
        s: &Sample,
        f: &dyn ImplicitFunction,
        bbox: Option<&[[f64; 2]]>,
        max_memory: u64,
        cancel: &std::sync::atomic::AtomicBool,
    ) -> Result<Self> {
        build::build(s, &Domain::new(f, bbox), max_memory, Some(cancel), false).map(|(c, _)| c)
    }

    /// Ambient dimension d.
    pub fn ambient_dim(&self) -> usize {
        self.d
    }
    /// Dimension m of M-hat.
    pub fn dim(&self) -> usize {
        self.m
    }
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.points.len() / self.d.max(1)
    }
    /// Vertex `i` (d coordinates).
    pub fn point(&self, i: usize) -> &[f64] {
        &self.points[i * self.d..(i + 1) * self.d]
    }
    /// All vertex coordinates, d per vertex.
    pub fn points(&self) -> &[f64] {
        &self.points
    }
    /// Vertices `interior_vertex_count()..` lie on the boundary; the others are the points of
    /// S, in the sample's order.
    pub fn interior_vertex_count(&self) -> usize {
        self.interior_vertices
    }
    /// The j-cells for 1 <= j <= m.
    pub fn level(&self, j: usize) -> &Level {
        &self.levels[j - 1]
    }
    /// Cells per dimension 0..=m.
    pub fn counts(&self) -> Vec<usize> {
        std::iter::once(self.vertex_count())
            .chain(self.levels.iter().map(Level::len))
            .collect()
    }
    /// Boundary cells per dimension 0..m (the boundary is (m-1)-dimensional).
    pub fn boundary_counts(&self) -> Vec<usize> {
        std::iter::once(self.vertex_count() - self.interior_vertices)
            .chain(self.levels.iter().map(|l| l.len() - l.interior))
            .take(self.m)
            .collect()
    }
    /// The topology report (counts, Euler characteristic, manifoldness, components,
    /// orientability and Betti numbers mod 2 where defined).
    pub fn topology(&self) -> Topology {
        topology::analyse(self, &std::sync::atomic::AtomicBool::new(false))
            .expect("never cancelled")
    }

    /// [`Complex::topology`], or `None` once `cancel` is set (Ctrl-C).
    pub fn topology_cancellable(&self, cancel: &std::sync::atomic::AtomicBool) -> Option<Topology> {
        topology::analyse(self, cancel)
    }
}
