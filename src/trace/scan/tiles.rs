// Index loops over lattice axes read as the coordinates they are.
#![allow(clippy::needless_range_loop)]
//! The exhaustive scan resident on a device: the box is cut into tiles of lattice cubes
//! ([`TilePlan`]). Per tile the device evaluates f with certified bounds at the tile's
//! vertices, keeps the values and sign codes in its own memory, generates the candidate
//! k-simplices, decides them with the certified solve and sends back only those it could not
//! prove outside ([`TileFound`]: a few words each). The CPU then evaluates f at the vertices
//! of those candidates alone, keeps exactly its own candidates among them and decides them
//! from its own values, so S, its order and its points are the CPU backend's whatever the
//! device's rounding; the CPU's work follows the output, not the lattice.
//!
//! The device's part is [`DeviceValues::scan_tiles`]; its CPU twin is [`twin_tile`].

use rayon::prelude::*;

use super::candidates::{chains, pass_mask, sign_code, Candidates, BASE};
use super::device_values::bounded_sign_code;
use super::{Found, Hit, Scanned};
use crate::cpu::batch;
use crate::cpu::certificate::{CROSSED, OUTSIDE};
use crate::cpu::solve::Status;
use crate::error::{Error, Result};
use std::collections::BTreeMap;

use super::grid::row_spans;
use crate::trace::region::{in_box, lattice_bounds};
use crate::trace::{DeviceValues, StopReason, TraceContext, TraceStats};
use crate::triangulation::{Triangulation, MAX_DIM};

/// The bit of a sign code whose vertex's value the device does not know (bounds too wide
/// or not finite): both sign bits are then set, and no certified verdict uses the vertex.
pub const UNKNOWN: u32 = 1 << 30;
/// Lattice vertices per tile the planner aims at in R^2 and R^3.
pub const TILE_VERTICES: usize = 1 << 15;
/// Lattice vertices per tile above R^3, where the layer of corners a tile shares with its
/// neighbours costs more.
pub const TILE_VERTICES_HIGH: usize = 1 << 14;
/// Fewest cubes per axis of a tile.
const MIN_SIDE: u128 = 4;
/// Most tiles a scan may take.
const MAX_TILES: u128 = 1 << 24;

/// The tiles of a device-resident scan, and the boxes its bases are tested against.
#[derive(Clone, Debug)]
pub struct TilePlan {
    /// The ambient dimension d.
    pub d: usize,
    /// The codimension k.
    pub k: usize,
    /// The box the device scans the cubes based in: the scan's box grown by one edge, then
    /// padded outward, so that it holds every base the CPU scans whatever the rounding.
    pub near: Vec<[f64; 2]>,
    /// `near` grown by one more edge, padded: every corner of a scanned cube lies in it, so
    /// f is not evaluated at the vertices outside (their sign code is 0).
    pub far: Vec<[f64; 2]>,
    /// The scan's box grown by one edge, as the CPU's grid tests its bases.
    base_box: Vec<[f64; 2]>,
    /// The tiles, in order.
    pub tiles: Vec<Tile>,
}

/// A block of lattice vertices: `counts[j]` along axis j from `origin`; the cubes based at
/// its vertices off the top layers are its own.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Tile {
    /// The lattice vertex with the lowest coordinates.
    pub origin: Vec<i32>,
    /// Vertices per axis (cubes per axis plus one).
    pub counts: Vec<u32>,
}

impl Tile {
    /// The vertices of the block.
    pub fn vertices(&self) -> usize {
        self.counts.iter().map(|&n| n as usize).product()
    }

    /// The cubes the tile scans.
    pub fn cubes(&self) -> usize {
        self.counts.iter().map(|&n| n as usize - 1).product()
    }

    /// The step of vertex indices along axis j.
    pub fn stride(&self, j: usize) -> u32 {
        self.counts[..j].iter().product()
    }

    /// The lattice coordinates of vertex `i` (digits in the radix `counts`, axis 0 first).
    pub fn coords(&self, mut i: u32, out: &mut [i32]) {
        for (j, &n) in self.counts.iter().enumerate() {
            out[j] = self.origin[j] + (i % n) as i32;
            i /= n;
        }
    }

    /// The vertex index of the corner with set `s` (bit j: +1 on axis j) of the cube based
    /// at vertex `base`.
    pub fn corner(&self, base: u32, s: u32) -> u32 {
        (0..self.counts.len())
            .filter(|&j| s >> j & 1 == 1)
            .map(|j| self.stride(j))
            .sum::<u32>()
            + base
    }
}

/// What a device sends back for one tile.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct TileFound {
    /// Per candidate the device could not prove outside, k + 2 words: the vertex index of
    /// its cube's base, its corner sets S_1 < .. < S_k, and the verdict
    /// ([`CROSSED`] or [`UNCERTAIN`](crate::cpu::certificate::UNCERTAIN)); in any order.
    pub records: Vec<u32>,
    /// Candidates the tile held (those whose vertices' sign codes admit a zero).
    pub candidates: u64,
    /// Vertices whose value the device did not know.
    pub unknown: u64,
    /// Vertices where the device evaluated f (those within two edges of the box, padded).
    pub evaluated: u64,
}

impl TilePlan {
    /// The tiles of the exhaustive scan of `bbox` on `tri`, of about [`TILE_VERTICES`]
    /// vertices each ([`TILE_VERTICES_HIGH`] above R^3), leaving out those whose bases lie
    /// wholly outside the box grown by an edge (a zonotope separation test).
    pub fn new(tri: &Triangulation, k: usize, bbox: &[[f64; 2]], max_memory: u64) -> Result<Self> {
        let d = tri.dim();
        let edge = tri.edge();
        let base_box: Vec<[f64; 2]> = bbox.iter().map(|[l, h]| [l - edge, h + edge]).collect();
        let near: Vec<[f64; 2]> = base_box
            .iter()
            .map(|&[l, h]| {
                let pad = 1e-7 * (l.abs().max(h.abs()) + edge);
                [l - pad, h + pad]
            })
            .collect();
        let far: Vec<[f64; 2]> = near
            .iter()
            .map(|&[l, h]| {
                let pad = 1e-7 * (l.abs().max(h.abs()) + edge);
                [l - edge - pad, h + edge + pad]
            })
            .collect();
        let (lo, hi) = lattice_bounds(tri, &near);
        // Cubes per axis, and per tile along each axis.
        let span: Vec<u128> = lo
            .iter()
            .zip(&hi)
            .map(|(l, h)| (h.saturating_sub(*l) as u128).saturating_add(1))
            .collect();
        let target = if d <= 3 {
            TILE_VERTICES
        } else {
            TILE_VERTICES_HIGH
        };
        let side = ((target as f64).powf(1.0 / d as f64).floor() as u128)
            .saturating_sub(1)
            .max(MIN_SIDE);
        let reach = lo
            .iter()
            .zip(&hi)
            .all(|(l, h)| l.unsigned_abs() < 1 << 30 && h.unsigned_abs() < 1 << 30);
        // Rows along axis 0 (ids in the mixed radix n[1..]), as the CPU's grid walks them.
        let n: Vec<usize> = span
            .iter()
            .map(|&s| (s + 1).min(1 << 40) as usize)
            .collect();
        let rows = n[1..]
            .iter()
            .try_fold(1u128, |a, &b| a.checked_mul(b as u128));
        let too_many = |what: String| {
            Error::Trace(format!(
                "the exhaustive scan of this box needs {what}, over what a scan takes: use a                  smaller box or a larger edge"
            ))
        };
        // The rows held take 24 bytes each; there are at most the rows of the bounding box
        // and about as many as the vertices (the box's volume over |det A|), twice for the
        // rows a box cuts short.
        let log_volume: f64 = near.iter().map(|[l, h]| (h - l).log10()).sum();
        let vertices = crate::linalg::Lu::new(&tri.matrix(), d).map_or(f64::INFINITY, |lu| {
            10f64.powf(log_volume - lu.abs_det().log10())
        });
        let held = rows.map_or(f64::INFINITY, |r| (r as f64).min(2.0 * vertices + 1.0));
        // NaN (a degenerate box) is refused too.
        if !reach || rows.is_none() || held * 24.0 > max_memory as f64 || held.is_nan() {
            let vertices: f64 = span.iter().map(|&s| s as f64).product();
            return Err(too_many(format!("about {vertices:.3e} lattice vertices")));
        }
        // The bases' rows, gathered into blocks of `side` cubes along axes 1..d-1; per block
        // the range of u_0 its rows cover, cut into tiles of `side` cubes.
        let mut blocks: BTreeMap<Vec<u64>, (i64, i64)> = BTreeMap::new();
        for (id, start, len) in row_spans(tri, &near, &lo, &hi, &n) {
            let mut rest = id;
            let key: Vec<u64> = (1..d)
                .map(|j| {
                    let digit = rest % n[j];
                    rest /= n[j];
                    (digit as u128 / side) as u64
                })
                .collect();
            let end = start + len as i64 - 1;
            let e = blocks.entry(key).or_insert((start, end));
            *e = (e.0.min(start), e.1.max(end));
        }
        let separation = Separation::new(tri, &near);
        let mut tiles = Vec::new();
        for (key, (first, last)) in blocks {
            let mut origin = vec![0i64; d];
            let mut counts = vec![0u32; d];
            for j in 1..d {
                origin[j] = lo[j] + (key[j - 1] as u128 * side) as i64;
                // The rows' digits reach n[j] - 1.
                let end = lo[j] + n[j] as i64 - 1;
                counts[j] = ((end - origin[j] + 1).min(side as i64) + 1) as u32;
            }
            let mut at = first;
            while at <= last {
                origin[0] = at;
                counts[0] = ((last - at + 1).min(side as i64) + 1) as u32;
                at += side as i64;
                // The tile's bases, a parallelepiped in R^d, against the box of scanned bases.
                let top: Vec<i64> = (0..d).map(|j| origin[j] + counts[j] as i64 - 2).collect();
                if separation.apart(&origin, &top) {
                    continue;
                }
                if tiles.len() as u128 >= MAX_TILES {
                    return Err(too_many(format!("more than {MAX_TILES} tiles")));
                }
                tiles.push(Tile {
                    origin: origin.iter().map(|&o| o as i32).collect(),
                    counts: counts.clone(),
                });
            }
        }
        Ok(TilePlan {
            d,
            k,
            near,
            far,
            base_box,
            tiles,
        })
    }
}

/// Where a tile's vertex lies, as the device tests it from its coordinates (and their
/// bounds): in `near` (the cube based there is scanned, off the top layers), in `far` (f is
/// evaluated there), or neither.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Place {
    /// A scanned base.
    Near,
    /// A possible corner of a scanned cube.
    Far,
    /// Neither: no candidate reads it.
    Out,
}

/// The test of whether a block of lattice vertices lies wholly outside a box in R^d: both
/// are zonotopes (the block's generators the columns of A, the box's the axes), so they are
/// disjoint exactly when some facet normal of their Minkowski difference separates them.
/// Those normals are orthogonal to d - 1 of the 2d generators.
struct Separation {
    d: usize,
    a: Vec<f64>,
    b: Vec<f64>,
    near: Vec<[f64; 2]>,
    normals: Vec<[f64; MAX_DIM]>,
    /// Per normal, n . A_c for each column c.
    along: Vec<[f64; MAX_DIM]>,
}

impl Separation {
    fn new(tri: &Triangulation, near: &[[f64; 2]]) -> Self {
        let d = tri.dim();
        let (a, b) = tri.affine_map();
        let mut gens: Vec<Vec<f64>> = (0..d)
            .map(|c| (0..d).map(|r| a[r * d + c]).collect())
            .collect();
        gens.extend((0..d).map(|r| (0..d).map(|t| f64::from(u8::from(t == r))).collect()));
        let mut normals = Vec::new();
        for mask in 0u32..1 << (2 * d) {
            if mask.count_ones() as usize + 1 != d {
                continue;
            }
            let span: Vec<&Vec<f64>> = (0..2 * d)
                .filter(|&g| mask >> g & 1 == 1)
                .map(|g| &gens[g])
                .collect();
            if let Some(n) = orthogonal(&span, d) {
                normals.push(n);
            }
        }
        let along = normals
            .iter()
            .map(|n| {
                let mut out = [0.0; MAX_DIM];
                for c in 0..d {
                    out[c] = (0..d).map(|r| n[r] * a[r * d + c]).sum();
                }
                out
            })
            .collect();
        Separation {
            d,
            a,
            b,
            near: near.to_vec(),
            normals,
            along,
        }
    }

    /// Whether the lattice block `lo..=hi` maps wholly outside the box, with a margin for
    /// rounding (never true of a block that meets it).
    fn apart(&self, lo: &[i64], hi: &[i64]) -> bool {
        let d = self.d;
        let mut center = [0.0; MAX_DIM];
        let mut half = [0.0; MAX_DIM];
        for c in 0..d {
            half[c] = 0.5 * (hi[c] - lo[c]) as f64;
        }
        for r in 0..d {
            center[r] = self.b[r]
                + (0..d)
                    .map(|c| self.a[r * d + c] * 0.5 * (lo[c] + hi[c]) as f64)
                    .sum::<f64>()
                - 0.5 * (self.near[r][0] + self.near[r][1]);
        }
        self.normals.iter().zip(&self.along).any(|(n, along)| {
            let gap: f64 = (0..d).map(|r| n[r] * center[r]).sum();
            let reach: f64 = (0..d)
                .map(|c| {
                    along[c].abs() * half[c]
                        + n[c].abs() * 0.5 * (self.near[c][1] - self.near[c][0])
                })
                .sum();
            gap.abs() > reach * (1.0 + 1e-9) + 1e-9
        })
    }
}

/// A unit vector orthogonal to the d - 1 vectors `span` of R^d, or None when they are
/// dependent.
fn orthogonal(span: &[&Vec<f64>], d: usize) -> Option<[f64; MAX_DIM]> {
    let norm = |w: &[f64]| w.iter().map(|x| x * x).sum::<f64>().sqrt();
    let project = |w: &mut Vec<f64>, basis: &[Vec<f64>]| {
        for _ in 0..2 {
            for q in basis {
                let dot: f64 = w.iter().zip(q).map(|(x, y)| x * y).sum();
                w.iter_mut().zip(q).for_each(|(x, y)| *x -= dot * y);
            }
        }
    };
    let mut basis: Vec<Vec<f64>> = Vec::with_capacity(d);
    for v in span {
        let mut w = v.to_vec();
        let before = norm(&w);
        project(&mut w, &basis);
        let after = norm(&w);
        if after <= 1e-9 * before.max(f64::MIN_POSITIVE) {
            return None;
        }
        basis.push(w.iter().map(|x| x / after).collect());
    }
    let (size, w) = (0..d)
        .map(|t| {
            let mut w = vec![0.0; d];
            w[t] = 1.0;
            project(&mut w, &basis);
            (norm(&w), w)
        })
        .fold(
            (0.0, Vec::new()),
            |best, c| if c.0 > best.0 { c } else { best },
        );
    if size <= 1e-9 {
        return None;
    }
    let mut n = [0.0; MAX_DIM];
    for (o, x) in n.iter_mut().zip(&w) {
        *o = x / size;
    }
    Some(n)
}

/// The CPU twin of the device's tile stages (`shaders/tile_values.wgsl`,
/// `shaders/tile_scan.wgsl`): the place of each vertex from `place` (lattice coordinates),
/// certified values from `eval` (as [`DeviceValues::eval_certified`]) at the vertices in
/// place, candidates as the CPU generates them, and verdicts from `verdicts` (as
/// [`DeviceValues::decide_certified`]); the records in order of base, then chain.
pub fn twin_tile_with(
    plan: &TilePlan,
    tile: &Tile,
    place: impl Fn(&[i32]) -> Place + Sync,
    eval: impl FnOnce(&[i32], &mut [f64]) -> Result<()>,
    verdicts: impl FnOnce(&[f64], &[f64], &[u32], &mut [u32]) -> Result<()>,
) -> Result<TileFound> {
    let (d, k) = (plan.d, plan.k);
    let count = tile.vertices();
    let mut lattice = vec![0i32; count * d];
    lattice
        .par_chunks_mut(d)
        .enumerate()
        .for_each(|(i, u)| tile.coords(i as u32, u));
    let places: Vec<Place> = lattice.par_chunks(d).map(&place).collect();
    let inside: Vec<usize> = (0..count).filter(|&i| places[i] != Place::Out).collect();
    let sub: Vec<i32> = inside
        .iter()
        .flat_map(|&i| lattice[i * d..(i + 1) * d].iter().copied())
        .collect();
    let mut pairs = vec![0.0; inside.len() * k * 2];
    eval(&sub, &mut pairs)?;
    let (mut values, mut bounds) = (vec![0.0; count * k], vec![0.0; count * k]);
    for (j, &i) in inside.iter().enumerate() {
        for c in 0..k {
            values[i * k + c] = pairs[(j * k + c) * 2];
            bounds[i * k + c] = pairs[(j * k + c) * 2 + 1];
        }
    }
    let codes: Vec<u32> = (0..count)
        .into_par_iter()
        .map(|i| {
            if places[i] == Place::Out {
                return 0;
            }
            let (f, e) = (&values[i * k..(i + 1) * k], &bounds[i * k..(i + 1) * k]);
            let known = f.iter().zip(e).all(|(v, e)| v.is_finite() && e.is_finite());
            let mut code = bounded_sign_code(f, e);
            if !known {
                code |= UNKNOWN | pass_mask(k);
            }
            let mut top = false;
            let mut rest = i as u32;
            for &n in &tile.counts {
                top |= rest % n + 1 == n;
                rest /= n;
            }
            if !top && places[i] == Place::Near {
                code |= BASE;
            }
            code
        })
        .collect();
    let mut cands = Candidates::default();
    let mut corner = vec![0u32; 1 << d];
    let mut sup = vec![0u32; 1 << d];
    let mut bases = Vec::new();
    for i in 0..count as u32 {
        if codes[i as usize] & BASE == 0 {
            continue;
        }
        for (s, c) in corner.iter_mut().enumerate() {
            *c = tile.corner(i, s as u32);
        }
        let before = cands.chains.len();
        chains(&codes, k, &corner, &mut sup, &mut cands);
        bases.extend(std::iter::repeat_n(i, (cands.chains.len() - before) / k));
    }
    let m = bases.len();
    let mut verdict = vec![OUTSIDE; m];
    verdicts(&values, &bounds, &cands.rows, &mut verdict)?;
    let mut records = Vec::new();
    for i in 0..m {
        let row = &cands.rows[i * (k + 1)..(i + 1) * (k + 1)];
        // As the shader: a vertex of unknown value makes the candidate uncertain.
        let v = if row.iter().any(|&v| codes[v as usize] & UNKNOWN != 0) {
            crate::cpu::certificate::UNCERTAIN
        } else if verdict[i] == OUTSIDE {
            continue;
        } else {
            verdict[i]
        };
        records.push(bases[i]);
        records.extend_from_slice(&cands.chains[i * k..(i + 1) * k]);
        records.push(v);
    }
    Ok(TileFound {
        records,
        candidates: m as u64,
        unknown: codes.iter().filter(|&&c| c & UNKNOWN != 0).count() as u64,
        evaluated: inside.len() as u64,
    })
}

/// [`twin_tile_with`] on `device`'s certified values and verdicts, with the places tested in
/// f64 against the plan's padded boxes: what [`DeviceValues::scan_tiles`] does by default.
pub fn twin_tile<D: DeviceValues + ?Sized>(
    device: &D,
    tri: &Triangulation,
    plan: &TilePlan,
    tile: &Tile,
) -> Result<TileFound> {
    twin_tile_with(
        plan,
        tile,
        |u| {
            let mut x = [0.0; MAX_DIM];
            tri.vertex_coords(u, &mut x[..plan.d]);
            if in_box(&plan.near, &x[..plan.d]) {
                Place::Near
            } else if in_box(&plan.far, &x[..plan.d]) {
                Place::Far
            } else {
                Place::Out
            }
        },
        |lattice, out| device.eval_certified(tri, lattice, out),
        |values, bounds, rows, out| device.decide_certified(values, bounds, rows, out),
    )
}

/// The tiles of `plan` through the twin on `device`, in order, handed to `each` until it
/// returns false: [`DeviceValues::scan_tiles`] by default.
pub fn twin_scan<D: DeviceValues + ?Sized>(
    device: &D,
    tri: &Triangulation,
    plan: &TilePlan,
    each: &mut dyn FnMut(usize, TileFound) -> Result<bool>,
) -> Result<()> {
    for (t, tile) in plan.tiles.iter().enumerate() {
        if !each(t, twin_tile(device, tri, plan, tile)?)? {
            break;
        }
    }
    Ok(())
}

/// The vertices the CPU evaluated f at, and their values, gathered over the tiles.
#[derive(Default)]
struct Evaluated {
    lattice: Vec<i32>,
    values: Vec<f64>,
}

/// The exhaustive scan of `bbox` resident on `device`: the tiles' records decided on the
/// CPU. Interrupted (Ctrl-C) between tiles, it returns what it found so far.
pub(crate) fn scan<const W: usize>(
    ctx: &TraceContext,
    bbox: &[[f64; 2]],
    device: &dyn DeviceValues,
) -> Result<Scanned<W>> {
    let plan = TilePlan::new(ctx.tri, ctx.k, bbox, ctx.max_memory)?;
    let mut stats = TraceStats::default();
    let mut found = Found::new(ctx);
    let mut evaluated = Evaluated::default();
    let mut unknown = 0;
    device.scan_tiles(ctx.tri, &plan, &mut |t, got| {
        if ctx.interrupted() {
            stats.stopped = Some(StopReason::Interrupted);
            return Ok(false);
        }
        let tile = &plan.tiles[t];
        stats.vertices += got.evaluated;
        stats.device_vertex_evaluations += got.evaluated;
        unknown += got.unknown;
        settle(
            ctx,
            &plan,
            tile,
            &got,
            &mut stats,
            &mut found,
            &mut evaluated,
        )?;
        Ok(true)
    })?;
    if found.is_empty() && stats.non_finite == 0 && unknown > 0 && stats.stopped.is_none() {
        // Nothing found and the device did not know f somewhere: count where the CPU's f
        // is NaN or infinite, as the CPU's scan reports it.
        let grid = super::grid::build_on_cpu(ctx, bbox)?;
        stats.non_finite = grid.values().par_iter().filter(|v| !v.is_finite()).count() as u64;
    }
    let cpu_values = evaluated.into_unique(ctx.d, ctx.k);
    found.into_scanned(stats, Some(cpu_values))
}

impl Evaluated {
    /// The vertices once each (tiles share their borders), sorted by coordinates.
    fn into_unique(self, d: usize, k: usize) -> (Vec<i32>, Vec<f64>) {
        let n = self.lattice.len() / d.max(1);
        let mut order: Vec<usize> = (0..n).collect();
        let row = |i: usize| &self.lattice[i * d..(i + 1) * d];
        order.par_sort_unstable_by(|&a, &b| row(a).cmp(row(b)));
        order.dedup_by(|a, b| row(*a) == row(*b));
        let lattice = order.iter().flat_map(|&i| row(i).iter().copied()).collect();
        let values = order
            .iter()
            .flat_map(|&i| self.values[i * k..(i + 1) * k].iter().copied())
            .collect();
        (lattice, values)
    }
}

/// Decides one tile's records on the CPU: f at their vertices, the CPU's own candidates
/// among them (those its sign codes pass, based in its box), their exact verdicts, and the
/// keys of the crossed ones whose point lies in the domain, appended to `found`.
fn settle<const W: usize>(
    ctx: &TraceContext,
    plan: &TilePlan,
    tile: &Tile,
    got: &TileFound,
    stats: &mut TraceStats,
    found: &mut Found<W>,
    evaluated: &mut Evaluated,
) -> Result<()> {
    let (d, k, n) = (ctx.d, ctx.k, ctx.k + 1);
    let mut records: Vec<&[u32]> = got.records.chunks_exact(k + 2).collect();
    records.par_sort_unstable();
    let rows: Vec<u32> = records
        .iter()
        .flat_map(|r| std::iter::once(r[0]).chain(r[1..=k].iter().map(|&s| tile.corner(r[0], s))))
        .collect();
    // f on the CPU at each vertex once.
    let mut uniq = rows.clone();
    uniq.par_sort_unstable();
    uniq.dedup();
    let mut lattice = vec![0i32; uniq.len() * d];
    lattice
        .par_chunks_mut(d)
        .zip(&uniq)
        .for_each(|(u, &v)| tile.coords(v, u));
    let mut values = vec![0.0; uniq.len() * k];
    ctx.oracle
        .values()
        .eval_vertices(ctx.tri, &lattice, &mut values)?;
    stats.cpu_vertex_evaluations += uniq.len() as u64;
    // Each record's vertices as rows of `values`, and the CPU's sign code of each vertex.
    let rows: Vec<u32> = rows
        .par_iter()
        .map(|v| uniq.binary_search(v).expect("a record's vertex") as u32)
        .collect();
    let codes: Vec<u32> = values.par_chunks(k).map(sign_code).collect();
    // The CPU's own candidates among the records.
    let mask = pass_mask(k);
    let mut kept = Vec::with_capacity(records.len());
    let mut sub = Vec::with_capacity(rows.len());
    for (i, r) in records.iter().enumerate() {
        let row = &rows[i * n..(i + 1) * n];
        let passes = row.iter().fold(0, |c, &s| c | codes[s as usize]) & mask == mask;
        let mut x = [0.0; MAX_DIM];
        ctx.tri
            .vertex_coords(&lattice[row[0] as usize * d..][..d], &mut x[..d]);
        if passes && in_box(&plan.base_box, &x[..d]) {
            kept.push(i);
            sub.extend_from_slice(row);
        } else if !passes && r[k + 1] == CROSSED {
            return Err(contradiction("not a candidate of the CPU"));
        }
    }
    let mut status = vec![Status::Outside; kept.len()];
    let mut lambda = vec![0.0; kept.len() * n];
    let exact = batch::decide(k, &values, &sub, &mut status, &mut lambda);
    for (&i, s) in kept.iter().zip(&status) {
        if records[i][k + 1] == CROSSED && !s.crossed() {
            return Err(contradiction(&format!("{s:?}")));
        }
    }
    // Every candidate the device ruled out, and every record the CPU did not keep, is
    // outside; the kept ones were decided on the CPU.
    stats.count_decisions(
        &status,
        crate::trace::Decisions {
            exact,
            on_device: 0,
        },
    );
    let dropped = got.candidates - kept.len() as u64;
    stats.oracle_calls += dropped;
    stats.device_decisions += dropped;
    if stats.zero_region.is_none() && status.contains(&Status::Degenerate) {
        stats.zero_region = crate::trace::checks::zero_region(
            ctx.f,
            &status,
            &sub,
            &values,
            ctx.tri.edge(),
            |s, x| ctx.tri.vertex_coords(&lattice[s * d..(s + 1) * d], x),
        );
    }
    let hits: Vec<Result<Option<Hit<W>>>> = (0..kept.len())
        .into_par_iter()
        .filter(|&j| status[j].crossed())
        .map(|j| {
            let row = &sub[j * n..(j + 1) * n];
            let lam = &lambda[j * n..(j + 1) * n];
            let mut point = [0.0; MAX_DIM];
            ctx.tri.barycentric_point(
                lam,
                |c, out| out.copy_from_slice(&lattice[row[c] as usize * d..][..d]),
                &mut point[..d],
            );
            if !ctx.domain.contains(&point[..d]) {
                return Ok(None);
            }
            let chain = &records[kept[j]][1..=k];
            let v0 = &lattice[row[0] as usize * d..][..d];
            super::chain_key(ctx, v0, chain).map(|key| Some(found.hit(key, &point[..d])))
        })
        .collect();
    for h in hits {
        if let Some(hit) = h? {
            found.push(hit);
        }
    }
    evaluated.lattice.extend_from_slice(&lattice);
    evaluated.values.extend_from_slice(&values);
    Ok(())
}

/// The error when the CPU contradicts a crossing the device certified: a value bound did
/// not hold, so the device's other verdicts cannot be trusted either.
fn contradiction(cpu: &str) -> Error {
    Error::DeviceBound(format!(
        "the device certified a candidate of a scan tile as crossed, but the CPU's values \
         make it {cpu}: a bound of the device's values of f does not hold (rerun without \
         device values, and report this as a bug)"
    ))
}
