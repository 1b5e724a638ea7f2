//! Surfaces in R^3 against a grid mesher: isomesh (trace + complex + triangles) and
//! `fast-surface-nets` (f sampled on its grid + naive surface nets) on the sphere, the torus
//! and the chair at matched vertex counts, both on every thread of the pool.
//!
//! The grid mesher runs as its documentation suggests for large grids: in cubic chunks of
//! [`CHUNK`] cells with a one-sample border, each sampled and meshed on its own, in parallel;
//! the chunks fit together into the mesh of the whole grid (the same quads; a vertex of a
//! cube on a chunk's far face is made by both chunks and counted once). f is sampled in f32
//! by hand-written closures, the fastest a grid user would write. isomesh meshes the preset
//! at the edge length whose vertex count (|S|) is within 1% of the grid's.

use std::time::Instant;

use fast_surface_nets::ndshape::{RuntimeShape, Shape};
use fast_surface_nets::{surface_nets, SurfaceNetsBuffer};
use rayon::prelude::*;

use super::{median, trace_case};
use crate::complex::{Complex, Surface};
use crate::error::{Error, Result};
use crate::expr::{preset, Problem};
use crate::trace::CpuOracle;

/// Cells per chunk edge of the grid mesher.
pub const CHUNK: u32 = 64;

/// The largest grid size: 8192^3 samples (about 2 x 10^8 vertices on the sphere).
pub const MAX_GRID: u32 = 8192;

/// Checks a grid size: a positive multiple of [`CHUNK`], at most [`MAX_GRID`].
pub fn check_grid(n: u32) -> Result<()> {
    if n == 0 || n % CHUNK != 0 || n > MAX_GRID {
        return Err(Error::Spec(format!(
            "grid size {n}: must be a positive multiple of {CHUNK}, at most {MAX_GRID}"
        )));
    }
    Ok(())
}

/// A surface of the comparison: a preset and its hand-written f32 twin on a cube.
#[derive(Clone, Copy, Debug)]
pub struct GridSurface {
    /// The preset's name (default parameters).
    pub preset: &'static str,
    /// The grid covers [-half_width, half_width]^3.
    pub half_width: f64,
    /// The preset's function in f32.
    pub f: fn(f32, f32, f32) -> f32,
}

/// The sphere (r = 1), the torus (R = 1, r = 0.4) and the chair (a = 0.8, b = 0.4).
pub const SURFACES: [GridSurface; 3] = [
    GridSurface {
        preset: "sphere",
        half_width: 1.5,
        f: |x, y, z| x * x + y * y + z * z - 1.0,
    },
    GridSurface {
        preset: "torus",
        half_width: 1.5,
        f: |x, y, z| {
            let q = (x * x + y * y).sqrt() - 1.0;
            q * q + z * z - 0.16
        },
    },
    GridSurface {
        preset: "chair",
        half_width: 1.6,
        f: |x, y, z| {
            let s = x * x + y * y + z * z - 0.8;
            s * s
                - 0.4
                    * ((z - 1.0) * (z - 1.0) - 2.0 * x * x)
                    * ((z + 1.0) * (z + 1.0) - 2.0 * y * y)
        },
    },
];

impl GridSurface {
    /// Grid spacing for `n` interior samples per axis (n + 2 samples across the cube).
    pub fn spacing(&self, n: u32) -> f64 {
        2.0 * self.half_width / f64::from(n + 1)
    }
}

/// What the grid mesher made of a grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GridMesh {
    /// Distinct vertices (one per cube the surface crosses).
    pub vertices: usize,
    /// Triangles (two per quad).
    pub triangles: usize,
}

/// Samples f on the grid of `n` interior samples per axis (see [`check_grid`]) and meshes
/// it with surface nets, chunk by chunk in parallel.
pub fn surface_nets_mesh(s: &GridSurface, n: u32) -> Result<GridMesh> {
    check_grid(n)?;
    let per_axis = n / CHUNK;
    let h = s.spacing(n) as f32;
    let a = s.half_width as f32;
    let side = CHUNK + 2;
    let shape = RuntimeShape::<u32, 3>::new([side; 3]);
    let chunks = per_axis * per_axis * per_axis;
    let (vertices, triangles) = (0..chunks)
        .into_par_iter()
        .map_init(
            || (vec![0f32; shape.usize()], SurfaceNetsBuffer::default()),
            |(sdf, buf), c| {
                let j = [
                    c % per_axis,
                    (c / per_axis) % per_axis,
                    c / (per_axis * per_axis),
                ];
                let o = j.map(|j| j * CHUNK);
                for z in 0..side {
                    let wz = -a + (o[2] + z) as f32 * h;
                    for y in 0..side {
                        let wy = -a + (o[1] + y) as f32 * h;
                        let row = shape.linearize([0, y, z]) as usize;
                        for (x, v) in sdf[row..row + side as usize].iter_mut().enumerate() {
                            *v = (s.f)(-a + (o[0] + x as u32) as f32 * h, wy, wz);
                        }
                    }
                }
                surface_nets(sdf, &shape, [0; 3], [side - 1; 3], buf);
                // The far layer of cubes belongs to the next chunk, where there is one.
                let last = j.map(|j| j + 1 == per_axis);
                let owned = buf
                    .surface_points
                    .iter()
                    .filter(|p| (0..3).all(|i| p[i] < CHUNK || last[i]))
                    .count();
                (owned, buf.indices.len() / 3)
            },
        )
        .reduce(|| (0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    Ok(GridMesh {
        vertices,
        triangles,
    })
}

/// What isomesh made of a surface at one edge length.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IsomeshMesh {
    /// |S|: one vertex per crossed edge.
    pub vertices: usize,
    /// Triangles of the polygons.
    pub triangles: usize,
}

/// Seconds of each stage of one isomesh run.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Stages {
    /// The trace.
    pub trace_s: f64,
    /// The cell complex.
    pub complex_s: f64,
    /// Polygons (oriented) and their triangles.
    pub triangles_s: f64,
}

impl Stages {
    /// The three together.
    pub fn total(&self) -> f64 {
        self.trace_s + self.complex_s + self.triangles_s
    }
}

/// The preset of `s` at edge length `edge`.
pub fn problem(s: &GridSurface, edge: f64) -> Result<Problem> {
    let mut p = preset(s.preset, &[])?;
    p.triangulation.edge = Some(edge);
    Ok(p)
}

/// Traces `p`, builds its complex and triangulates its polygons, timing each stage.
pub fn isomesh_mesh(p: &Problem) -> Result<(IsomeshMesh, Stages)> {
    let t = Instant::now();
    let sample = trace_case(p, &CpuOracle::new(&p.system))?;
    let trace_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let complex = Complex::build(&sample, &p.system, None)?;
    let complex_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    let triangles = Surface::new(&complex, Some(&p.system)).triangles().len();
    let triangles_s = t.elapsed().as_secs_f64();
    Ok((
        IsomeshMesh {
            vertices: sample.len(),
            triangles,
        },
        Stages {
            trace_s,
            complex_s,
            triangles_s,
        },
    ))
}

/// The edge length at which isomesh's vertex count is within 1% of `vertices`, starting
/// from `edge` (vertex counts go as edge^-2); at most six traces.
pub fn matching_edge(s: &GridSurface, vertices: usize, mut edge: f64) -> Result<f64> {
    for _ in 0..6 {
        let p = problem(s, edge)?;
        let n = trace_case(&p, &CpuOracle::new(&p.system))?.len();
        let ratio = n as f64 / vertices as f64;
        if (ratio - 1.0).abs() <= 0.01 {
            return Ok(edge);
        }
        edge *= ratio.sqrt();
    }
    Err(Error::Spec(format!(
        "{}: no edge length gives {vertices} vertices within 1%",
        s.preset
    )))
}

/// One size of the comparison, timed.
#[derive(Clone, Debug, PartialEq)]
pub struct SurfaceRow {
    /// The preset.
    pub surface: &'static str,
    /// Interior grid samples per axis.
    pub n: u32,
    /// The grid mesher's output.
    pub grid: GridMesh,
    /// Its median seconds (sampling and meshing).
    pub grid_s: f64,
    /// isomesh's edge length.
    pub edge: f64,
    /// isomesh's output.
    pub isomesh: IsomeshMesh,
    /// isomesh's stages in its median run.
    pub stages: Stages,
}

impl SurfaceRow {
    /// isomesh's time over the grid mesher's (below 1: isomesh is faster).
    pub fn ratio(&self) -> f64 {
        self.stages.total() / self.grid_s
    }
}

/// Measures surface `s` at grid size `n`, each side `repeats` times (medians); `edge_per_h`
/// is the first guess of isomesh's edge over the grid spacing.
pub fn measure(s: &GridSurface, n: u32, repeats: usize, edge_per_h: f64) -> Result<SurfaceRow> {
    let repeats = repeats.max(1);
    let mut grid = None;
    let mut grid_times = Vec::new();
    for _ in 0..repeats {
        let t = Instant::now();
        grid = Some(surface_nets_mesh(s, n)?);
        grid_times.push(t.elapsed().as_secs_f64());
    }
    let grid = grid.expect("at least one run");
    let edge = matching_edge(s, grid.vertices, edge_per_h * s.spacing(n))?;
    let p = problem(s, edge)?;
    let mut runs = Vec::new();
    for _ in 0..repeats {
        runs.push(isomesh_mesh(&p)?);
    }
    runs.sort_by(|a, b| a.1.total().total_cmp(&b.1.total()));
    let (isomesh, stages) = runs[runs.len() / 2];
    Ok(SurfaceRow {
        surface: s.preset,
        n,
        grid,
        grid_s: median(grid_times),
        edge,
        isomesh,
        stages,
    })
}

/// [`measure`] at each of the grid sizes `sizes` (ascending), calling `each` on every row
/// as it is measured; the first guess of the edge at a size comes from the size before.
pub fn measure_sizes(
    s: &GridSurface,
    sizes: &[u32],
    repeats: usize,
    mut each: impl FnMut(&SurfaceRow),
) -> Result<Vec<SurfaceRow>> {
    // Edge over grid spacing at matched vertex counts: about 2.07 for these surfaces.
    let mut edge_per_h = 2.07;
    let mut rows = Vec::new();
    for &n in sizes {
        let r = measure(s, n, repeats, edge_per_h)?;
        edge_per_h = r.edge / s.spacing(n);
        each(&r);
        rows.push(r);
    }
    Ok(rows)
}

/// The vertex count from which isomesh is faster than the grid mesher on the rows of one
/// surface (sorted by size): interpolated in log-log between the last size where it is
/// slower and the next; `None` when it is slower at the largest size, the smallest size's
/// count when it is faster everywhere.
pub fn crossover(rows: &[SurfaceRow]) -> Option<f64> {
    let last = rows.last()?;
    if last.ratio() >= 1.0 {
        return None;
    }
    let Some(i) = rows.iter().rposition(|r| r.ratio() >= 1.0) else {
        return Some(rows[0].grid.vertices as f64);
    };
    let (a, b) = (&rows[i], &rows[i + 1]);
    let (la, lb) = (a.ratio().ln(), b.ratio().ln());
    let (va, vb) = ((a.grid.vertices as f64).ln(), (b.grid.vertices as f64).ln());
    Some((va + (vb - va) * la / (la - lb)).exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The chunked mesh is the mesh of the whole grid: the same distinct vertices and the
    /// same triangles as one call of surface nets on the (n + 2)^3 samples.
    #[test]
    fn chunks_mesh_exactly_the_whole_grid() {
        for s in &SURFACES {
            let n = 2 * CHUNK;
            let side = n + 2;
            let h = s.spacing(n) as f32;
            let a = s.half_width as f32;
            let shape = RuntimeShape::<u32, 3>::new([side; 3]);
            let sdf: Vec<f32> = (0..shape.size())
                .map(|i| {
                    let [x, y, z] = shape.delinearize(i).map(|c| -a + c as f32 * h);
                    (s.f)(x, y, z)
                })
                .collect();
            let mut whole = SurfaceNetsBuffer::default();
            surface_nets(&sdf, &shape, [0; 3], [side - 1; 3], &mut whole);
            let chunked = surface_nets_mesh(s, n).unwrap();
            assert!(whole.positions.len() > 1000, "{}", s.preset);
            assert_eq!(chunked.vertices, whole.positions.len(), "{}", s.preset);
            assert_eq!(chunked.triangles, whole.indices.len() / 3, "{}", s.preset);
        }
    }

    fn isomesh_eval(p: &Problem, x: &[f64], out: &mut [f64]) {
        use crate::expr::ImplicitFunction;
        p.system.eval_batch(x, out);
    }

    #[test]
    fn grid_surfaces_are_their_presets() {
        for s in &SURFACES {
            let p = preset(s.preset, &[]).unwrap();
            let mut v = [0.0];
            for x in [[0.3, -0.2, 0.7], [1.1, 0.4, -0.5], [0.0, 0.9, 0.1]] {
                isomesh_eval(&p, &x, &mut v);
                let g = (s.f)(x[0] as f32, x[1] as f32, x[2] as f32);
                assert!(
                    (f64::from(g) - v[0]).abs() < 1e-5,
                    "{}: {g} vs {}",
                    s.preset,
                    v[0]
                );
            }
        }
    }

    #[test]
    fn the_crossover_is_where_the_ratio_passes_one() {
        let row = |vertices: usize, ratio: f64| SurfaceRow {
            surface: "sphere",
            n: 64,
            grid: GridMesh {
                vertices,
                triangles: 0,
            },
            grid_s: 1.0,
            edge: 0.1,
            isomesh: IsomeshMesh {
                vertices,
                triangles: 0,
            },
            stages: Stages {
                trace_s: ratio,
                ..Stages::default()
            },
        };
        // ln 2 and ln 0.5 either side: halfway in log-vertices.
        let c = crossover(&[row(1_000, 4.0), row(10_000, 2.0), row(100_000, 0.5)]).unwrap();
        assert!((c - 31_622.8).abs() < 1.0, "{c}");
        assert_eq!(
            crossover(&[row(1_000, 0.5), row(10_000, 0.2)]),
            Some(1_000.0)
        );
        assert_eq!(crossover(&[row(1_000, 0.5), row(10_000, 1.2)]), None);
        assert_eq!(crossover(&[]), None);
    }
}
