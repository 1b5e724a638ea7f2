//! The sample S of a trace or scan: the crossed simplices as compact keys, the values of f at
//! their lattice vertices, and the points computed from them on demand (and kept once the
//! crossing checks have computed them all).

use std::sync::{Arc, OnceLock};

use rayon::prelude::*;

use super::engine::Engine;
use super::TraceStats;
use crate::cpu::solve::Decider;
use crate::error::Result;
use crate::expr::ImplicitFunction;
use crate::triangulation::{KeyCodec, KeySet, Simplex, Triangulation};

/// The sample S: crossed k-simplices (as compact keys) with their points, in a deterministic
/// order (trace: level by level, sorted within a level; scan: sorted keys).
///
/// S stores keys, not points: it keeps the values of f at the lattice vertices of its
/// simplices, and a point is the intersection test run again on them (the same f64
/// arithmetic as the trace, so the same bits, whichever backend traced). That is 8 d bytes
/// per simplex less to hold during the trace; [`Sample::points`] computes them all when
/// needed. [`Sample::check_crossings`], which needs them all, keeps them: the cell complex
/// and the exports then copy them instead of computing them again.
///
/// ```
/// use isomesh::Mesher;
///
/// let circle = Mesher::preset("circle", &[])?.trace()?;
/// let s = circle.sample();
/// assert_eq!((s.ambient_dim(), s.codim()), (2, 1));
/// // Each entry is a crossed 1-simplex, named by its key, and the point where M crosses it.
/// let (simplex, point) = s.iter().next().unwrap();
/// assert_eq!(simplex.dim(), 1);
/// assert!((point[0].hypot(point[1]) - 1.0).abs() < 1e-2);
/// assert_eq!(s.key(0).len(), s.codec().words());
/// # Ok::<(), isomesh::Error>(())
/// ```
#[derive(Clone, Debug)]
pub struct Sample {
    codec: KeyCodec,
    stride: usize,
    keys: Vec<u64>,
    vertices: KeySet,
    values: Vec<f64>,
    tri: Triangulation,
    rim_keys: Vec<u64>,
    rim_points: Vec<f64>,
    /// The points, d per simplex, once [`Sample::check_crossings`] has computed them;
    /// shared with the complexes built on the sample.
    points: OnceLock<Arc<Vec<f64>>>,
    /// What it took.
    pub stats: TraceStats,
}

/// Work space for computing points of a sample.
struct PointWork {
    decider: Decider,
    values: Vec<f64>,
    lambda: Vec<f64>,
    vkey: Vec<u64>,
    /// The simplex whose point is computed (decoded into, not built anew each time).
    simplex: Simplex,
}

impl Sample {
    /// Number of crossed k-simplices.
    pub fn len(&self) -> usize {
        self.keys.len() / self.stride
    }
    /// Whether S is empty.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }
    /// d.
    pub fn ambient_dim(&self) -> usize {
        self.codec.ambient_dim()
    }
    /// k.
    pub fn codim(&self) -> usize {
        self.codec.simplex_dim()
    }
    /// The codec of the keys.
    pub fn codec(&self) -> &KeyCodec {
        &self.codec
    }
    /// The triangulation the simplices belong to.
    pub fn triangulation(&self) -> &Triangulation {
        &self.tri
    }
    /// Key `i` (`codec().words()` words).
    pub fn key(&self, i: usize) -> &[u64] {
        &self.keys[i * self.stride..i * self.stride + self.codec.words()]
    }
    /// Simplex `i`.
    pub fn simplex(&self, i: usize) -> Simplex {
        self.codec.decode(self.key(i))
    }

    fn point_work(&self) -> PointWork {
        let k = self.codim();
        PointWork {
            decider: Decider::new(k),
            values: vec![0.0; (k + 1) * k],
            lambda: vec![0.0; k + 1],
            // The vertex set's width: the codec's words, then zeros.
            vkey: vec![0; self.vertices.words()],
            simplex: self.codec.scratch(),
        }
    }

    /// Point `i` into `out` (d coordinates).
    fn point_into(&self, i: usize, w: &mut PointWork, out: &mut [f64]) {
        // Keys of one or two words, as wide as the vertex set's, take the codec's
        // fixed-width paths.
        match (self.codec.words(), self.vertices.words()) {
            (1, 1) => self.point_into_w::<1>(i, w, out),
            (2, 2) => self.point_into_w::<2>(i, w, out),
            _ => self.point_into_w::<0>(i, w, out),
        }
    }

    /// [`Sample::point_into`] for keys of `W` words (0: any width, the general paths).
    #[inline(always)]
    fn point_into_w<const W: usize>(&self, i: usize, w: &mut PointWork, out: &mut [f64]) {
        let k = self.codim();
        match <&[u64; W]>::try_from(self.key(i)) {
            Ok(key) if W > 0 => self.codec.decode_into_w(key, &mut w.simplex),
            _ => self.codec.decode_into(self.key(i), &mut w.simplex),
        }
        let s = &w.simplex;
        let mut found = true;
        s.for_each_vertex(|j, v| {
            let encoded = match <&mut [u64; W]>::try_from(&mut w.vkey[..]) {
                Ok(vkey) if W > 0 => self.codec.encode_vertex_w(v, vkey),
                _ => self.codec.encode_vertex(v, &mut w.vkey),
            };
            let at = match encoded {
                Ok(()) => self.vertices.find(&w.vkey),
                Err(_) => None,
            };
            match at {
                Some(a) => {
                    w.values[j * k..(j + 1) * k].copy_from_slice(&self.values[a * k..(a + 1) * k])
                }
                None => found = false,
            }
        });
        if !found || !w.decider.decide(&w.values, &mut w.lambda).status.crossed() {
            // Not reachable for a sample built by a trace or a scan.
            out.fill(f64::NAN);
            return;
        }
        self.tri
            .barycentric_point(&w.lambda, |j, v| s.vertex_into(j, v), out);
    }

    /// Point `i` as kept by [`Sample::check_crossings`], if it ran.
    fn kept_point(&self, i: usize) -> Option<&[f64]> {
        let d = self.ambient_dim();
        self.points.get().map(|all| &all[i * d..(i + 1) * d])
    }

    /// Point `i` (d coordinates): where M-hat crosses simplex `i`.
    pub fn point(&self, i: usize) -> Vec<f64> {
        if let Some(p) = self.kept_point(i) {
            return p.to_vec();
        }
        let mut out = vec![0.0; self.ambient_dim()];
        self.point_into(i, &mut self.point_work(), &mut out);
        out
    }

    /// All points, d per simplex: a copy of those [`Sample::check_crossings`] kept, else
    /// computed in parallel.
    pub fn points(&self) -> Vec<f64> {
        if let Some(points) = self.points.get() {
            return points.to_vec();
        }
        let d = self.ambient_dim();
        let mut out = vec![0.0; self.len() * d];
        out.par_chunks_mut(256 * d).enumerate().for_each_init(
            || self.point_work(),
            |w, (c, chunk)| {
                for (j, p) in chunk.chunks_exact_mut(d).enumerate() {
                    self.point_into(c * 256 + j, w, p);
                }
            },
        );
        out
    }

    /// The points kept by [`Sample::check_crossings`], shared rather than copied; computed
    /// (and not kept) where it has not run.
    pub(crate) fn shared_points(&self) -> Arc<Vec<f64>> {
        match self.points.get() {
            Some(points) => Arc::clone(points),
            None => Arc::new(self.points()),
        }
    }

    /// How many crossings look like a jump of f rather than a zero: for some component c,
    /// |f_c| at the crossing point is more than half the spread of f_c's values at the
    /// simplex's vertices (max - min), or is not finite, while that spread is not small (at
    /// least its median over S).
    ///
    /// Where f is smooth and the edge fine, |f| at the point is second order in the edge and
    /// the spread first order: on the presets at their default edges the ratio stays under
    /// 0.25. Simplices lying almost within M have a second-order spread too: the median test
    /// leaves them out. Across a pole (1/x) or a jump (sign(x)) f is large on both sides,
    /// and S then holds a sheet where f changes sign without a zero. `f` is the function the
    /// sample was traced for.
    pub fn suspect_crossings(&self, f: &dyn ImplicitFunction) -> usize {
        self.check_crossings(f).suspect
    }

    /// [`Sample::suspect_crossings`], and the crossings where f's Jacobian is
    /// rank-deficient ([`CrossingChecks::singular`]), in one pass over S.
    ///
    /// A crossing where some component's spread is under 1/16 of its median is a candidate
    /// (f_c's gradient is small there, or the simplex lies almost within M); the candidates,
    /// smallest ratio first and at most 256 + |S| / 16 of them, are kept where a Newton step
    /// from their point moves it less than an edge and [`rank_ratio`](crate::expr::rank_ratio)
    /// there, against f's slope 2 edges about it, is under 1/4: within about an edge of a
    /// point where branches of M cross.
    ///
    /// The sample keeps the points computed here (8 d bytes per simplex, counted in
    /// [`Sample::memory_bytes`]).
    pub fn check_crossings(&self, f: &dyn ImplicitFunction) -> CrossingChecks {
        const CHUNK: usize = 256;
        let (d, k) = (self.ambient_dim(), self.codim());
        let n = self.len();
        let mut all = vec![0.0; n * d];
        // Per crossing and component: the spread of the vertex values, negated where |f| at
        // the point exceeds half of it, NaN where the point is unknown.
        let marked: Vec<f64> = all
            .par_chunks_mut(CHUNK * d)
            .enumerate()
            .map_init(
                || self.point_work(),
                |w, (c, points)| {
                    let range = c * CHUNK..((c + 1) * CHUNK).min(n);
                    let mut spread = vec![0.0f64; range.len() * k];
                    let mut low = vec![f64::INFINITY; k];
                    for (i, (p, m)) in range
                        .clone()
                        .zip(points.chunks_exact_mut(d).zip(spread.chunks_exact_mut(k)))
                    {
                        self.point_into(i, w, p);
                        low.fill(f64::INFINITY);
                        m.fill(f64::NEG_INFINITY);
                        for row in w.values.chunks_exact(k) {
                            for ((l, h), v) in low.iter_mut().zip(m.iter_mut()).zip(row) {
                                *l = l.min(*v);
                                *h = h.max(*v);
                            }
                        }
                        m.iter_mut().zip(&low).for_each(|(h, l)| *h -= l);
                    }
                    let mut at = vec![0.0; range.len() * k];
                    f.eval_batch(points, &mut at);
                    for ((m, a), p) in spread
                        .chunks_exact_mut(k)
                        .zip(at.chunks_exact(k))
                        .zip(points.chunks_exact(d))
                    {
                        for (m, a) in m.iter_mut().zip(a) {
                            if !p[0].is_finite() {
                                *m = f64::NAN;
                            } else if a.is_nan() || a.abs() > 0.5 * *m {
                                *m = -*m;
                            }
                        }
                    }
                    spread
                },
            )
            .flatten_iter()
            .collect();
        // Kept, unless an earlier check kept the same points already.
        let points = self.points.get_or_init(|| Arc::new(all));
        let medians: Vec<f64> = (0..k)
            .map(|c| {
                let mut v: Vec<f64> = marked
                    .iter()
                    .skip(c)
                    .step_by(k)
                    .filter(|x| !x.is_nan())
                    .map(|x| x.abs())
                    .collect();
                if v.is_empty() {
                    return 0.0;
                }
                let mid = v.len() / 2;
                *v.select_nth_unstable_by(mid, f64::total_cmp).1
            })
            .collect();
        let suspect = marked
            .chunks_exact(k)
            .filter(|m| {
                m.iter()
                    .zip(&medians)
                    .any(|(x, med)| x.is_sign_negative() && -x >= *med)
            })
            .count();
        // Candidates for a singular point: (smallest spread / median, crossing).
        let mut low: Vec<(f64, usize)> = marked
            .par_chunks_exact(k)
            .enumerate()
            .filter_map(|(i, m)| {
                let r = m
                    .iter()
                    .zip(&medians)
                    .filter(|(x, med)| !x.is_nan() && !x.is_sign_negative() && **med > 0.0)
                    .map(|(x, med)| x / med)
                    .fold(f64::INFINITY, f64::min);
                (r < 1.0 / 16.0).then_some((r, i))
            })
            .collect();
        low.par_sort_unstable_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
        low.truncate(256 + n / 16);
        let edge = self.tri.edge();
        let singular: Vec<Vec<f64>> = low
            .par_iter()
            .map(|&(_, i)| {
                let p = points[i * d..(i + 1) * d].to_vec();
                let near = p.iter().all(|v| v.is_finite())
                    && crate::expr::system::newton_step_within(f, &p, edge)
                    && crate::expr::rank_ratio(f, &p, 2.0 * edge).is_some_and(|r| r < 0.25);
                near.then_some(p)
            })
            .flatten()
            .collect();
        CrossingChecks {
            suspect,
            singular: singular.into_iter().take(MAX_SINGULAR).collect(),
        }
    }

    /// (simplex, point) pairs in order.
    pub fn iter(&self) -> impl Iterator<Item = (Simplex, Vec<f64>)> + '_ {
        let mut w = self.point_work();
        (0..self.len()).map(move |i| {
            let p = self.kept_point(i).map_or_else(
                || {
                    let mut p = vec![0.0; self.ambient_dim()];
                    self.point_into(i, &mut w, &mut p);
                    p
                },
                <[f64]>::to_vec,
            );
            (self.simplex(i), p)
        })
    }
    /// Number of rim simplices: crossed k-simplices next to S whose points lie outside the
    /// domain (box, boundary inequalities). The cell complex clips its cells with them.
    pub fn rim_len(&self) -> usize {
        self.rim_points.len() / self.ambient_dim()
    }
    /// Rim key `i`.
    pub fn rim_key(&self, i: usize) -> &[u64] {
        &self.rim_keys[i * self.stride..i * self.stride + self.codec.words()]
    }
    /// Rim point `i`.
    pub fn rim_point(&self, i: usize) -> &[f64] {
        let d = self.ambient_dim();
        &self.rim_points[i * d..(i + 1) * d]
    }
    /// The keys in sorted order (to compare samples as sets).
    pub fn sorted_keys(&self) -> Vec<&[u64]> {
        let mut v: Vec<&[u64]> = (0..self.len()).map(|i| self.key(i)).collect();
        v.sort_unstable();
        v
    }
    /// Bytes held: keys, vertex keys and values, rim, and the points once kept.
    pub fn memory_bytes(&self) -> usize {
        (self.keys.capacity() + self.rim_keys.capacity()) * 8
            + self.vertices.memory_bytes()
            + (self.values.capacity() + self.rim_points.capacity()) * 8
            + self.points.get().map_or(0, |p| p.capacity() * 8)
    }
}

/// Most singular crossings [`Sample::check_crossings`] returns.
pub const MAX_SINGULAR: usize = 8;

/// What [`Sample::check_crossings`] finds.
#[derive(Clone, Debug, Default)]
pub struct CrossingChecks {
    /// [`Sample::suspect_crossings`].
    pub suspect: usize,
    /// Crossing points where f's Jacobian is rank-deficient (at most [`MAX_SINGULAR`], the
    /// most degenerate first): branches of M may cross there, and a trace follows only the
    /// ones it reaches.
    pub singular: Vec<Vec<f64>>,
}

/// The sample of a finished trace or scan: its keys, vertices and values, moved from the
/// engine.
pub(super) fn sample_from<const W: usize>(
    codec: KeyCodec,
    tri: &Triangulation,
    engine: Engine<W>,
    stats: TraceStats,
) -> Result<Sample> {
    // The trace's vertex set as it is (no key hashed again), its keys W words wide.
    let vertices = engine.verts.into_dynamic();
    let mut keys = engine.s.into_words();
    keys.shrink_to_fit();
    Ok(Sample {
        codec,
        stride: W,
        keys,
        vertices,
        values: engine.values,
        tri: tri.clone(),
        rim_keys: engine.rim.into_words(),
        rim_points: engine.rim_points,
        points: OnceLock::new(),
        stats,
    })
}
