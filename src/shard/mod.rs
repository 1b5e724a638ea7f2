//! Shards of an exhaustive scan: a box cut into a grid of sub-boxes, each scanned on its own
//! (another thread, process or machine), then assembled into exactly the whole box's sample
//! and cell complex, in the same order.
//!
//! Every simplex of T has a global key, so shards need no coordination. A shard scans its
//! sub-box widened by a halo (and clipped to the box), builds that scan's complex, and keeps
//! what it owns:
//! - a point of S (a crossed k-simplex) belongs to the shard whose sub-box holds it, each
//!   sub-box half-open, `[lo, hi)` on every axis, but closed at the box's upper faces;
//! - a cell of M-hat belongs to the owner of its first vertex in S (the smallest key), and a
//!   boundary cell (where a cell leaves the domain) to the owner of the cell it cuts.
//!
//! The vertices of a cell lie in one simplex of T, so within [`Triangulation::edge`] of one
//! another. With a halo at least that wide ([`default_halo`] is 1.1 edges), the owner of a cell sees all of it, as the whole
//! scan does; and a shard that sees only part of a cell sees a first vertex it does not own.
//!
//! Cells are named across shards by ids of `1 + W` words: a tag, then a key of W words. Tag 0
//! is a simplex of T (a vertex of S, or the (k+j)-simplex of a j-cell), tag 1 the cut of one
//! (the boundary vertex on a mixed edge, or the boundary (j-1)-cell of a mixed j-cell).
//! Sorting ids sorts cells as the whole scan orders them, so [`assemble`] rebuilds its
//! complex exactly.
//!
//! ```
//! use isomesh::{shard, Mesher};
//!
//! let whole = vec![[-1.5, 1.5]; 3];
//! let m = Mesher::preset("sphere", &[])?.edge(0.3).bbox(whole.clone());
//! let shards = shard::grid(&whole, &shard::uniform_cuts(&whole, &[2, 1, 1]))?;
//! let halo = shard::default_halo(&m)?;
//! let parts = shards
//!     .iter()
//!     .map(|s| shard::scan(&m, s, halo))
//!     .collect::<Result<Vec<_>, _>>()?;
//! let all = shard::assemble(&parts)?;
//! let single = m.scan()?;
//! assert_eq!(all.keys.len(), single.len() * all.key_words);
//! assert_eq!(all.complex.counts(), single.complex()?.counts());
//! # Ok::<(), isomesh::Error>(())
//! ```
//!
//! [`Triangulation::edge`]: crate::triangulation::Triangulation::edge

mod assemble;

use std::time::Instant;

use crate::complex::{CellKeys, Complex};
use crate::error::{Error, Result};
use crate::mesher::Mesher;

pub use assemble::{assemble, Assembled};

/// The part of the box one shard owns: `[lo, hi)` per axis, closed at `hi` where `closed`.
#[derive(Clone, Debug, PartialEq)]
pub struct Shard {
    /// Lower corner.
    pub lo: Vec<f64>,
    /// Upper corner.
    pub hi: Vec<f64>,
    /// Per axis: whether `hi` itself is owned (the box's upper face).
    pub closed: Vec<bool>,
}

impl Shard {
    /// Whether the shard owns the point `x`.
    pub fn owns(&self, x: &[f64]) -> bool {
        (0..self.lo.len()).all(|a| {
            let v = x[a];
            self.lo[a] <= v && (v < self.hi[a] || (self.closed[a] && v == self.hi[a]))
        })
    }

    /// The shard's box widened by `halo` on every side, clipped to the box `whole`.
    pub fn halo_box(&self, whole: &[[f64; 2]], halo: f64) -> Vec<[f64; 2]> {
        (0..self.lo.len())
            .map(|a| {
                [
                    (self.lo[a] - halo).max(whole[a][0]),
                    (self.hi[a] + halo).min(whole[a][1]),
                ]
            })
            .collect()
    }
}

/// Interior cut positions that split each axis of `whole` into `counts[a]` equal parts.
pub fn uniform_cuts(whole: &[[f64; 2]], counts: &[usize]) -> Vec<Vec<f64>> {
    whole
        .iter()
        .zip(counts)
        .map(|(&[lo, hi], &n)| {
            (1..n)
                .map(|i| lo + (hi - lo) * (i as f64 / n as f64))
                .collect()
        })
        .collect()
}

/// Shards per axis for `n` shards in all: each prime factor of n, largest first, splits the
/// axis whose parts are longest so far.
pub fn split_count(whole: &[[f64; 2]], n: usize) -> Vec<usize> {
    let mut counts = vec![1; whole.len()];
    let mut factors = Vec::new();
    let mut rest = n.max(1);
    let mut p = 2;
    while p * p <= rest {
        while rest % p == 0 {
            factors.push(p);
            rest /= p;
        }
        p += 1;
    }
    if rest > 1 {
        factors.push(rest);
    }
    for &p in factors.iter().rev() {
        let axis = (0..whole.len())
            .max_by(|&a, &b| {
                let (la, lb) = (
                    (whole[a][1] - whole[a][0]) / counts[a] as f64,
                    (whole[b][1] - whole[b][0]) / counts[b] as f64,
                );
                // Longest part first; the lower axis on ties.
                la.total_cmp(&lb).then(b.cmp(&a))
            })
            .unwrap_or(0);
        counts[axis] *= p;
    }
    counts
}

/// The grid of shards of `whole` cut at `cuts` (per axis, increasing positions strictly
/// inside the box), in row-major order (the last axis fastest).
pub fn grid(whole: &[[f64; 2]], cuts: &[Vec<f64>]) -> Result<Vec<Shard>> {
    crate::expr::spec::check_box(whole, whole.len())?;
    if cuts.len() != whole.len() {
        return Err(Error::DimensionMismatch(format!(
            "cuts for {} axes, the box has {}",
            cuts.len(),
            whole.len()
        )));
    }
    let mut bounds = Vec::with_capacity(whole.len());
    for (a, (c, &[lo, hi])) in cuts.iter().zip(whole).enumerate() {
        let mut b = vec![lo];
        for &x in c {
            if !(x.is_finite() && x > *b.last().unwrap_or(&lo) && x < hi) {
                return Err(Error::Spec(format!(
                    "cut {x} on axis {}: cuts must increase strictly inside ({lo}, {hi})",
                    a + 1
                )));
            }
            b.push(x);
        }
        b.push(hi);
        bounds.push(b);
    }
    let mut shards = vec![Shard {
        lo: Vec::new(),
        hi: Vec::new(),
        closed: Vec::new(),
    }];
    for b in &bounds {
        let mut next = Vec::with_capacity(shards.len() * (b.len() - 1));
        for s in &shards {
            for i in 0..b.len() - 1 {
                let mut t = s.clone();
                t.lo.push(b[i]);
                t.hi.push(b[i + 1]);
                t.closed.push(i + 2 == b.len());
                next.push(t);
            }
        }
        shards = next;
    }
    Ok(shards)
}

/// What one shard found and owns: its vertices (ids and points) and cells (ids and the ids
/// of their facets), ready to [`assemble`] with the other shards' parts.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Part {
    /// d.
    pub ambient_dim: usize,
    /// Words per id: 1 + the words of a cell's key.
    pub id_words: usize,
    /// Words of a key of S (a prefix of the key in an id).
    pub key_words: usize,
    /// Owned vertices' ids, `id_words` each: S (tag 0) and boundary vertices (tag 1).
    pub vertex_ids: Vec<u64>,
    /// Owned vertices' coordinates, d each.
    pub points: Vec<f64>,
    /// Owned cells of dimension j = 1..=m.
    pub levels: Vec<PartLevel>,
    /// Edges the complex left out (see [`crate::complex::ComplexStats::defects`]) whose
    /// first vertex the shard owns.
    pub defects: usize,
    /// Counters.
    pub stats: PartStats,
}

/// The owned j-cells of a part.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PartLevel {
    /// Cell ids, `id_words` each.
    pub ids: Vec<u64>,
    /// Cell i's facets are `facets[offsets[i] * id_words..offsets[i + 1] * id_words]`.
    pub offsets: Vec<u64>,
    /// The facets' ids (cells of dimension j - 1, or vertices for j = 1).
    pub facets: Vec<u64>,
}

/// What a shard took.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PartStats {
    /// Crossed simplices the shard's scan found, halo included.
    pub scanned: usize,
    /// Those the shard owns.
    pub owned: usize,
    /// Oracle calls of the scan.
    pub oracle_calls: u64,
    /// Seconds scanning, and building the complex.
    pub scan_s: f64,
    /// Seconds building the complex and picking what the shard owns.
    pub complex_s: f64,
}

/// The default halo, in edges of the triangulation: a cell's vertices lie within one edge of
/// one another, and the tenth more keeps rounding at the halo's faces out of the way.
pub const HALO_EDGES: f64 = 1.1;

/// The default halo for `mesher`'s triangulation: [`HALO_EDGES`] times its longest edge.
pub fn default_halo(mesher: &Mesher) -> Result<f64> {
    Ok(HALO_EDGES * mesher.build_triangulation()?.edge())
}

/// Scans the shard of `mesher`'s box (which must be set: it is the whole box) widened by
/// `halo`, and keeps what the shard owns. `halo` must be at least the triangulation's
/// longest edge (see [`default_halo`]).
pub fn scan(mesher: &Mesher, shard: &Shard, halo: f64) -> Result<Part> {
    let whole = mesher
        .domain_box()
        .ok_or_else(|| Error::Trace("a sharded scan needs the whole box (spec `box`)".into()))?
        .to_vec();
    let d = whole.len();
    if shard.lo.len() != d || shard.hi.len() != d || shard.closed.len() != d {
        return Err(Error::DimensionMismatch(format!(
            "a shard of R^{} in a box of R^{d}",
            shard.lo.len()
        )));
    }
    let edge = mesher.build_triangulation()?.edge();
    if !(halo.is_finite() && halo >= edge) {
        return Err(Error::Spec(format!(
            "halo {halo}: must be at least the triangulation's edge {edge}"
        )));
    }
    let within = shard.halo_box(&whole, halo);
    crate::expr::spec::check_box(&within, d)
        .map_err(|_| Error::Spec(format!("the shard {shard:?} lies outside the box")))?;
    let start = Instant::now();
    let run = mesher
        .clone()
        .key_box(whole)
        .bbox(within.clone())
        .run(crate::mesher::Job::Scan)?;
    if let Some(why) = run.report().stopped {
        return Err(Error::Trace(format!(
            "the shard's scan stopped early: {why}"
        )));
    }
    let scan_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let s = run.sample();
    let (c, keys) = Complex::build_keyed(s, run.function(), Some(&within), mesher.memory_limit())?;
    let mut part = owned_part(&c, &keys, s, shard);
    part.stats.scan_s = scan_s;
    part.stats.complex_s = start.elapsed().as_secs_f64();
    part.stats.scanned = s.len();
    part.stats.oracle_calls = s.stats.oracle_calls;
    Ok(part)
}

/// The cells of `c` that `shard` owns, named by their ids.
fn owned_part(c: &Complex, keys: &CellKeys, s: &crate::trace::Sample, shard: &Shard) -> Part {
    let (d, m, n) = (c.ambient_dim(), c.dim(), s.len());
    let w = keys.words;
    let iw = w + 1;
    let owns_vertex: Vec<bool> = (0..n).map(|i| shard.owns(c.point(i))).collect();
    // first[j][i]: the first vertex in S of interior j-cell i (facet lists are sorted, and
    // the interior facets come first).
    let mut first: Vec<Vec<u32>> = vec![(0..n as u32).collect()];
    for j in 1..=m {
        let level = c.level(j);
        let below = &first[j - 1];
        let bound = if j == 1 { n } else { c.level(j - 1).interior() };
        let f: Vec<u32> = (0..level.interior())
            .map(|i| {
                level
                    .facets(i)
                    .iter()
                    .filter(|&&x| (x as usize) < bound)
                    .map(|&x| below[x as usize])
                    .min()
                    .expect("an interior cell has an interior facet")
            })
            .collect();
        first.push(f);
    }
    let owned_interior: Vec<Vec<bool>> = first
        .iter()
        .map(|f| f.iter().map(|&v| owns_vertex[v as usize]).collect())
        .collect();
    // The ids of every cell of every level 0..=m, and which the shard owns. Level j's
    // boundary cells are the cuts of the mixed (j+1)-cells, in order.
    let mut ids: Vec<Vec<u64>> = Vec::with_capacity(m + 1);
    let mut owned: Vec<Vec<bool>> = Vec::with_capacity(m + 1);
    for j in 0..=m {
        let interior = if j == 0 { n } else { c.level(j).interior() };
        let total = if j == 0 {
            c.vertex_count()
        } else {
            c.level(j).len()
        };
        let mut id = Vec::with_capacity(total * iw);
        let mut own = owned_interior[j].clone();
        for i in 0..interior {
            id.push(0);
            let key = if j == 0 {
                s.key(i)
            } else {
                &keys.keys[j - 1][i * w..(i + 1) * w]
            };
            id.extend_from_slice(key);
            id.resize(id.len() + w - key.len(), 0);
        }
        if j < m {
            for (t, &mixed) in keys.mixed[j].iter().enumerate() {
                if mixed {
                    id.push(1);
                    id.extend_from_slice(&keys.keys[j][t * w..(t + 1) * w]);
                    own.push(owned_interior[j + 1][t]);
                }
            }
        }
        debug_assert_eq!(id.len(), total * iw);
        ids.push(id);
        owned.push(own);
    }
    let mut part = Part {
        ambient_dim: d,
        id_words: iw,
        key_words: s.codec().words(),
        defects: keys
            .defects
            .iter()
            .filter(|&&v| owns_vertex[v as usize])
            .count(),
        ..Part::default()
    };
    for (i, &own) in owned[0].iter().enumerate() {
        if own {
            part.vertex_ids
                .extend_from_slice(&ids[0][i * iw..(i + 1) * iw]);
            part.points.extend_from_slice(c.point(i));
        }
    }
    part.stats.owned = owns_vertex.iter().filter(|&&o| o).count();
    for j in 1..=m {
        let level = c.level(j);
        let mut out = PartLevel {
            offsets: vec![0],
            ..PartLevel::default()
        };
        for (i, &own) in owned[j].iter().enumerate() {
            if own {
                out.ids.extend_from_slice(&ids[j][i * iw..(i + 1) * iw]);
                for &f in level.facets(i) {
                    let f = f as usize;
                    out.facets
                        .extend_from_slice(&ids[j - 1][f * iw..(f + 1) * iw]);
                }
                out.offsets.push((out.facets.len() / iw) as u64);
            }
        }
        part.levels.push(out);
    }
    part
}
