//! The whole scan from its shards' parts: ids sorted, facets found by id.

use std::cmp::Ordering;

use rayon::prelude::*;

use super::Part;
use crate::complex::{Complex, ComplexStats, Level};
use crate::error::{Error, Result};

/// The assembled scan: S (keys and points, sorted by key, as the whole box's scan) and its
/// cell complex.
#[derive(Clone, Debug)]
pub struct Assembled {
    /// Words per key.
    pub key_words: usize,
    /// The keys of S, `key_words` each, sorted.
    pub keys: Vec<u64>,
    /// The points of S, d each.
    pub points: Vec<f64>,
    /// M-hat, with the vertices and cells in the whole scan's order.
    pub complex: Complex,
}

/// Rows of `w` words sorted, each with its origin.
struct Sorted {
    w: usize,
    ids: Vec<u64>,
}

impl Sorted {
    /// Sorts the rows of the parts' `get` arrays; each row's (part, index) is returned in the
    /// same order. Fails on an id held twice (overlapping shards).
    fn new<'a>(
        w: usize,
        parts: &'a [Part],
        get: impl Fn(&'a Part) -> &'a [u64] + Sync,
        what: &str,
    ) -> Result<(Self, Vec<(u32, u32)>)> {
        let mut order: Vec<(u32, u32)> = parts
            .iter()
            .enumerate()
            .flat_map(|(p, part)| (0..get(part).len() / w).map(move |i| (p as u32, i as u32)))
            .collect();
        let row = |&(p, i): &(u32, u32)| {
            let a = get(&parts[p as usize]);
            &a[i as usize * w..(i as usize + 1) * w]
        };
        order.par_sort_unstable_by(|a, b| row(a).cmp(row(b)));
        let mut ids = Vec::with_capacity(order.len() * w);
        for (n, o) in order.iter().enumerate() {
            if n > 0 && row(&order[n - 1]) == row(o) {
                return Err(Error::Trace(format!(
                    "two shards own the same {what}: the shards overlap"
                )));
            }
            ids.extend_from_slice(row(o));
        }
        Ok((Sorted { w, ids }, order))
    }

    fn len(&self) -> usize {
        self.ids.len() / self.w
    }

    fn row(&self, i: usize) -> &[u64] {
        &self.ids[i * self.w..(i + 1) * self.w]
    }

    /// Rows with tag 0 (simplices of T) come first: how many.
    fn tagged_zero(&self) -> usize {
        (0..self.len()).take_while(|&i| self.row(i)[0] == 0).count()
    }

    fn find(&self, id: &[u64]) -> Option<u32> {
        let (mut lo, mut hi) = (0, self.len());
        while lo < hi {
            let mid = (lo + hi) / 2;
            match self.row(mid).cmp(id) {
                Ordering::Less => lo = mid + 1,
                Ordering::Greater => hi = mid,
                Ordering::Equal => return Some(mid as u32),
            }
        }
        None
    }
}

/// Merges the parts of every shard of one box (see [`super::scan`]) into the whole scan's
/// sample and complex. Fails if the parts disagree on the problem, overlap, or leave a
/// cell's facet to no shard (a halo narrower than the triangulation's edge).
pub fn assemble(parts: &[Part]) -> Result<Assembled> {
    let first = parts
        .first()
        .ok_or_else(|| Error::Trace("no part to assemble".into()))?;
    let (d, iw, kw, m) = (
        first.ambient_dim,
        first.id_words,
        first.key_words,
        first.levels.len(),
    );
    if parts
        .iter()
        .any(|p| (p.ambient_dim, p.id_words, p.key_words, p.levels.len()) != (d, iw, kw, m))
    {
        return Err(Error::Trace(
            "the parts come from different problems or boxes".into(),
        ));
    }
    let (vertices, order) = Sorted::new(iw, parts, |p| &p.vertex_ids, "vertex")?;
    let n = vertices.tagged_zero();
    let mut points = Vec::with_capacity(order.len() * d);
    for &(p, i) in &order {
        let i = i as usize;
        points.extend_from_slice(&parts[p as usize].points[i * d..(i + 1) * d]);
    }
    let mut keys = Vec::with_capacity(n * kw);
    for i in 0..n {
        keys.extend_from_slice(&vertices.row(i)[1..1 + kw]);
    }
    let mut below = vertices;
    let mut levels = Vec::with_capacity(m);
    for j in 0..m {
        let (cells, order) = Sorted::new(iw, parts, |p| &p.levels[j].ids, "cell")?;
        let lists: Vec<Result<Vec<u32>>> = order
            .par_iter()
            .map(|&(p, i)| {
                let level = &parts[p as usize].levels[j];
                let (a, b) = (
                    level.offsets[i as usize] as usize,
                    level.offsets[i as usize + 1] as usize,
                );
                let mut f = (a..b)
                    .map(|x| {
                        below
                            .find(&level.facets[x * iw..(x + 1) * iw])
                            .ok_or_else(|| {
                                Error::Trace(format!(
                                    "a facet of a {}-cell is owned by no shard: the halo is \
                                 narrower than the triangulation's edge",
                                    j + 1
                                ))
                            })
                    })
                    .collect::<Result<Vec<u32>>>()?;
                f.sort_unstable();
                Ok(f)
            })
            .collect();
        let mut offsets = Vec::with_capacity(order.len() + 1);
        let mut facets = Vec::new();
        offsets.push(0u32);
        for l in lists {
            facets.extend(l?);
            offsets.push(
                u32::try_from(facets.len())
                    .map_err(|_| Error::Trace("too many cells for 32-bit indices".into()))?,
            );
        }
        let interior = cells.tagged_zero();
        levels.push(Level::from_lists(offsets, facets, interior));
        below = cells;
    }
    let stats = ComplexStats {
        defects: parts.iter().map(|p| p.defects).sum(),
        elapsed_s: 0.0,
    };
    let own_points: Vec<f64> = points[..n * d].to_vec();
    Ok(Assembled {
        key_words: kw,
        keys,
        points: own_points,
        complex: Complex::from_parts(d, points, n, levels, stats),
    })
}
