//! Construction of the cell complex: cofacets sorted into levels, then clipping.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::{Complex, ComplexStats, Level};
use crate::error::{Error, Result};
use crate::trace::{with_width, Domain, Sample};
use crate::triangulation::KeyCodec;

/// The cells of one dimension before clipping: their facets (indices one level lower),
/// whether they have both an inside and an outside crossing, and (when kept) their keys.
struct RawLevel {
    cells: Level,
    mixed: Vec<bool>,
    keys: Vec<u64>,
}

/// What names the cells of a complex globally: for each level j = 1..m, the keys of its
/// interior cells (their (k+j)-simplices of T, `words` u64 each) and which of them are
/// mixed (cut by the domain's boundary, in order: the boundary cells one level lower, or for
/// j = 1 the boundary vertices, are their cuts in this order).
pub(crate) struct CellKeys {
    pub words: usize,
    pub keys: Vec<Vec<u64>>,
    pub mixed: Vec<Vec<bool>>,
    /// For each edge left out (see [`ComplexStats::defects`]), its first vertex in S.
    pub defects: Vec<u32>,
}

pub(super) fn build(
    s: &Sample,
    domain: &Domain,
    max_memory: u64,
    cancel: Option<&AtomicBool>,
    keep_keys: bool,
) -> Result<(Complex, Option<CellKeys>)> {
    let start = Instant::now();
    let codec = s.codec();
    let (d, k) = (codec.ambient_dim(), codec.simplex_dim());
    // Cofaces reach one lattice step beyond their faces: one more bit keeps them encodable.
    let bits = (codec.coord_bits() + 1).min(32);
    let words = KeyCodec::new(d, d, bits)?.words().max(codec.words());
    let (mut raw, defects) =
        with_width!(words, raw_levels(s, bits, max_memory, cancel, keep_keys))?;
    let keys = keep_keys.then(|| CellKeys {
        words,
        keys: raw
            .iter_mut()
            .map(|l| std::mem::take(&mut l.keys))
            .collect(),
        mixed: raw.iter().map(|l| l.mixed.clone()).collect(),
        defects: defects.clone(),
    });
    let mut c = clip(s, domain, raw, d, d - k);
    c.stats = ComplexStats {
        defects: defects.len(),
        elapsed_s: start.elapsed().as_secs_f64(),
    };
    Ok((c, keys))
}

/// The unclipped levels 1..=m: level j holds the cofacets of level j - 1 (level 0: S, then
/// the rim), grouped. A 1-cell needs a vertex in S, and exactly two crossed facets; the
/// edges left out are returned as their first vertex in S.
fn raw_levels<const W: usize>(
    s: &Sample,
    bits: u32,
    max_memory: u64,
    cancel: Option<&AtomicBool>,
    keep_keys: bool,
) -> Result<(Vec<RawLevel>, Vec<u32>)> {
    let codec = *s.codec();
    let (d, k) = (codec.ambient_dim(), codec.simplex_dim());
    let (n, r) = (s.len(), s.rim_len());
    let mut prev: Vec<[u64; W]> = (0..n + r)
        .map(|i| {
            let src = if i < n { s.key(i) } else { s.rim_key(i - n) };
            let mut key = [0u64; W];
            key[..src.len()].copy_from_slice(src);
            key
        })
        .collect();
    let mut prev_codec = codec;
    let mut prev_mixed: Vec<bool> = (0..n + r).map(|i| i >= n).collect();
    let mut levels = Vec::with_capacity(d - k);
    let mut defects = Vec::new();
    for j in 1..=d - k {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(Error::Trace("interrupted".into()));
        }
        let cj = KeyCodec::new(d, k + j, bits)?;
        // The pairs are the peak: refuse up front rather than exhaust memory.
        let count: u64 = prev
            .par_iter()
            .map(|key| prev_codec.decode(key).cofacet_count())
            .sum();
        let held: usize = levels
            .iter()
            .map(|l: &RawLevel| l.cells.facets.len() * 4 + l.cells.offsets.len() * 5)
            .sum::<usize>()
            + prev.len() * (W * 8 + 1);
        // On top of the heap in use (the sample, the levels so far, `prev`): the pairs, and
        // the next level's keys.
        let need = crate::memory::in_use(held + s.memory_bytes())
            + count * (std::mem::size_of::<([u64; W], u32)>() + W * 8 + 5) as u64;
        if need > max_memory {
            return Err(Error::Trace(format!(
                "the cell complex needs about {} for its {j}-cells, over the memory limit of {} \
                 (raise --max-memory, use a larger edge, or --no-complex)",
                crate::memory::human_bytes(need),
                crate::memory::human_bytes(max_memory)
            )));
        }
        let mut pairs = cofacet_pairs::<W>(&prev, &prev_codec, &cj)?;
        pairs.par_sort_unstable();
        let mut keys = Vec::new();
        let mut cells = Level::default();
        let mut mixed = Vec::new();
        for group in pairs.chunk_by(|a, b| a.0 == b.0) {
            if j == 1 {
                if group.iter().all(|p| p.1 as usize >= n) {
                    continue;
                }
                if group.len() != 2 {
                    defects.push(group[0].1);
                    continue;
                }
            }
            keys.push(group[0].0);
            cells.push(group.iter().map(|p| p.1));
            mixed.push(group.iter().any(|p| prev_mixed[p.1 as usize]));
        }
        if cells.offsets.is_empty() {
            cells.offsets.push(0);
        }
        cells.interior = cells.len();
        if j == 1 {
            // Vertices of the complex: S only (the rim's crossings lie outside).
            prev_mixed.truncate(n);
        }
        let kept = if keep_keys {
            keys.iter().flatten().copied().collect()
        } else {
            Vec::new()
        };
        prev = keys;
        prev_codec = cj;
        prev_mixed.clone_from(&mixed);
        levels.push(RawLevel {
            cells,
            mixed,
            keys: kept,
        });
    }
    Ok((levels, defects))
}

/// (cofacet key, index) for every cofacet of every simplex in `keys`.
fn cofacet_pairs<const W: usize>(
    keys: &[[u64; W]],
    codec: &KeyCodec,
    cofacet_codec: &KeyCodec,
) -> Result<Vec<([u64; W], u32)>> {
    if keys.len() > u32::MAX as usize {
        return Err(Error::Trace("too many cells for 32-bit indices".into()));
    }
    keys.par_iter()
        .enumerate()
        .with_min_len(256)
        .try_fold(Vec::new, |mut acc, (i, key)| -> Result<Vec<_>> {
            let mut out = [0u64; W];
            let mut err = None;
            codec.decode(key).for_each_cofacet(|tau| {
                if err.is_none() {
                    match cofacet_codec.encode(tau, &mut out) {
                        Ok(()) => acc.push((out, i as u32)),
                        Err(e) => err = Some(e),
                    }
                }
            });
            err.map_or(Ok(acc), Err)
        })
        .try_reduce(Vec::new, |mut a, mut b| {
            a.append(&mut b);
            Ok(a)
        })
}

/// Cuts the mixed cells at the domain's boundary: each mixed j-cell keeps its facets and
/// gains a boundary facet, the (j-1)-cell where it leaves the domain, whose facets are the
/// boundary cells of the cell's mixed facets.
fn clip(s: &Sample, domain: &Domain, raw: Vec<RawLevel>, d: usize, m: usize) -> Complex {
    let n = s.len();
    // Boundary vertices, one per mixed edge, where the edge leaves the domain.
    let mut points = s.points();
    let edges = raw.first();
    if let Some(e) = edges {
        let cut: Vec<f64> = (0..e.cells.len())
            .into_par_iter()
            .filter(|&i| e.mixed[i])
            .flat_map_iter(|i| {
                let f = e.cells.facets(i);
                let (a, b) = (f[0] as usize, f[1] as usize);
                let (a, b) = if a < n { (a, b) } else { (b, a) };
                let (pa, pb) = (&points[a * d..(a + 1) * d], s.rim_point(b - n));
                let t = domain.exit(pa, pb);
                pa.iter()
                    .zip(pb)
                    .map(|(x, y)| x + t * (y - x))
                    .collect::<Vec<_>>()
            })
            .collect();
        points.extend(cut);
    }
    // boundary_index[j][i]: for mixed j-cell i (j >= 1), its boundary (j-1)-cell.
    let boundary_index: Vec<Vec<u32>> = raw
        .iter()
        .enumerate()
        .map(|(l, level)| {
            let base = if l == 0 { n } else { raw[l - 1].cells.len() };
            let mut next = base as u32;
            level
                .mixed
                .iter()
                .map(|&x| {
                    let v = next;
                    next += x as u32;
                    v
                })
                .collect()
        })
        .collect();
    let mut levels = Vec::with_capacity(m);
    for j in 1..=m {
        let level = &raw[j - 1];
        let bi = &boundary_index[j - 1];
        let mut out = Level::default();
        for (i, (&mixed, &b)) in level.mixed.iter().zip(bi).enumerate() {
            let own = level.cells.facets(i).iter().copied();
            let cut = mixed.then_some(b);
            if j == 1 {
                out.push(own.filter(|&v| (v as usize) < n).chain(cut));
            } else {
                out.push(own.chain(cut));
            }
        }
        out.interior = level.cells.len();
        if j < m {
            // The boundary j-cells: cuts of the mixed (j+1)-cells.
            let up = &raw[j];
            for t in 0..up.cells.len() {
                if up.mixed[t] {
                    out.push(
                        up.cells
                            .facets(t)
                            .iter()
                            .filter(|&&f| level.mixed[f as usize])
                            .map(|&f| bi[f as usize]),
                    );
                }
            }
        }
        if out.offsets.is_empty() {
            out.offsets.push(0);
        }
        levels.push(out);
    }
    Complex {
        d,
        m,
        points,
        interior_vertices: n,
        levels,
        stats: ComplexStats::default(),
    }
}
