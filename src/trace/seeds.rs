//! Starting traces: from a point near M (Newton-projected, then the crossed k-faces of the
//! d-simplices around it), or from points found by sampling a box.

use foldhash::fast::FixedState;
use hashbrown::HashSet;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use super::engine::Engine;
use super::table::Key;
use crate::error::{Error, Result};
use crate::expr::{newton_project, ImplicitFunction};
use crate::triangulation::Simplex;

/// How many rings of d-simplices around a seed are searched for a crossed k-face.
const SEED_RINGS: usize = 2;
/// Newton tolerance for seeds.
pub const SEED_TOLERANCE: f64 = 1e-10;

/// A d-simplex having `s` as a face: every part split into singletons in element order (the
/// last one keeps d+1 last, so the result is canonical).
fn full_coface(s: &Simplex) -> Simplex {
    let mut parts = Vec::with_capacity(s.ambient_dim() + 1);
    for &p in s.parts() {
        let mut m = p;
        while m != 0 {
            parts.push(m & m.wrapping_neg());
            m &= m - 1;
        }
    }
    Simplex::from_masks(s.base(), &parts).expect("a refinement of a valid simplex")
}

impl<const W: usize> Engine<'_, W> {
    /// Traces the component(s) of M next to the point `x` (on M or close to it) that S does
    /// not hold yet; returns how many new components were traced. Errors if no crossed
    /// k-simplex lies within two rings of d-simplices around `x`.
    pub fn trace_from_point(&mut self, x: &[f64]) -> Result<usize> {
        let (d, k) = (self.ctx.d, self.ctx.k);
        let first = full_coface(&self.ctx.tri.locate(x)?);
        if self.ctx.domain.bbox.is_none() {
            self.origins.extend_from_slice(first.base());
        }
        let mut seen: HashSet<Simplex, FixedState> = HashSet::with_hasher(FixedState::default());
        seen.insert(first.clone());
        let mut ring = vec![first];
        for _ in 0..=SEED_RINGS {
            let mut faces: Vec<Key<W>> = Vec::new();
            let mut key = [0u64; W];
            for s in &ring {
                let mut err = None;
                s.for_each_face(k, |f| match self.ctx.codec.encode(f, &mut key) {
                    Ok(()) => faces.push(key),
                    Err(e) => err = Some(e),
                })?;
                if let Some(e) = err {
                    return Err(e);
                }
            }
            faces.sort_unstable();
            faces.dedup();
            let verdicts = self.evaluate(&faces)?;
            let (crossed, points) = self.crossed_points(&faces, &verdicts);
            let mut hits: Vec<(f64, Key<W>, &[f64])> = crossed
                .iter()
                .zip(points.chunks_exact(d))
                .filter(|(_, p)| self.ctx.domain.contains(p))
                .map(|(&i, p)| {
                    let dist = p.iter().zip(x).map(|(a, b)| (a - b) * (a - b)).sum();
                    (dist, faces[i], p)
                })
                .collect();
            if !hits.is_empty() {
                hits.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
                let mut traced = 0;
                for (_, key, _) in hits {
                    if self.stats.stopped.is_some() {
                        break;
                    }
                    if !self.s_holds(&key) {
                        let i = self.s.push_unindexed(&key)?.start;
                        self.run(i..i + 1)?;
                        traced += 1;
                    }
                }
                self.stats.components += traced;
                return Ok(traced);
            }
            // Next ring: d-simplices sharing a facet with this one.
            let mut next = Vec::new();
            for s in &ring {
                s.for_each_facet(|f| {
                    f.for_each_cofacet(|c| {
                        if seen.insert(c.clone()) {
                            next.push(c.clone());
                        }
                    })
                });
            }
            ring = next;
        }
        Err(Error::Trace(format!(
            "no k-simplex near {x:?}, where a seed projected, is crossed by M (the seed is off \
             the manifold, or \
             M is too small for edge = {}); d = {d}",
            self.ctx.tri.edge()
        )))
    }

    /// Traces every component met by Newton projections of `samples` random points of the
    /// box (seeded, so the same each run). The points are drawn, projected and traced from
    /// in batches, so that memory does not grow with `samples`; before each batch the trace
    /// stops if the batch would pass the memory limit, or on Ctrl-C.
    pub fn trace_from_box(
        &mut self,
        f: &dyn ImplicitFunction,
        bbox: &[[f64; 2]],
        samples: usize,
        seed: u64,
    ) -> Result<()> {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let d = bbox.len();
        let mut left = samples;
        while left > 0 && self.stats.stopped.is_none() {
            let batch = left.min(SEARCH_BATCH);
            left -= batch;
            // The batch's points, twice over (drawn and projected), and Newton's work.
            let batch_bytes = batch * 2 * (d * 8 + 3 * size_of::<usize>());
            if self.must_stop(batch_bytes) {
                break;
            }
            let starts: Vec<Vec<f64>> = (0..batch)
                .map(|_| {
                    bbox.iter()
                        .map(|[lo, hi]| rng.random_range(*lo..=*hi))
                        .collect()
                })
                .collect();
            let projected: Vec<Vec<f64>> = starts
                .par_iter()
                .filter(|_| !self.ctx.interrupted())
                .filter_map(|x| newton_project(f, x, SEED_TOLERANCE).ok())
                .filter(|p| self.ctx.domain.contains(p))
                .collect();
            // Box points where f is NaN or infinite count as non-finite: f may be so
            // everywhere, and that must show.
            let k = f.codim();
            self.stats.non_finite += starts
                .par_iter()
                .filter(|x| {
                    let mut v = vec![0.0; k];
                    f.eval_batch(x, &mut v);
                    v.iter().any(|v| !v.is_finite())
                })
                .count() as u64;
            drop(starts);
            self.stats.seed_points += projected.len() as u64;
            for p in projected {
                if self.ctx.interrupted() && self.stats.stopped.is_none() {
                    self.stats.stopped = Some(super::StopReason::Interrupted);
                }
                if self.stats.stopped.is_some() {
                    break;
                }
                // A projected point whose neighbourhood has no crossing (M clipped by the box,
                // or a feature below the resolution) starts nothing.
                match self.trace_from_point(&p) {
                    Ok(_) | Err(Error::Trace(_)) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        Ok(())
    }
}

/// Box points drawn and projected at once by the seed search.
const SEARCH_BATCH: usize = 1 << 16;
