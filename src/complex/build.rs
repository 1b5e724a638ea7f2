//! Construction of the cell complex: cofacets sorted into levels, then clipping.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

use rayon::prelude::*;

use super::packed::{par_sort_distinct, Packer, Word};
use super::{Complex, ComplexStats, Level};
use crate::error::{Error, Result};
use crate::trace::{with_width, Domain, Sample};
use crate::triangulation::{KeyCodec, Simplex, MAX_DIM};

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
    let (mut raw, defects) = with_width!(
        words,
        raw_levels(s, bits, max_memory, cancel, keep_keys, true)
    )?;
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
/// edges left out are returned as their first vertex in S. With `packing`, a level's pairs
/// are packed into a u64 each where they fit, else into a u128 ([`Packer`]); the cells are
/// the same either way.
fn raw_levels<const W: usize>(
    s: &Sample,
    bits: u32,
    max_memory: u64,
    cancel: Option<&AtomicBool>,
    keep_keys: bool,
    packing: bool,
) -> Result<(Vec<RawLevel>, Vec<u32>)> {
    let codec = *s.codec();
    let (d, k) = (codec.ambient_dim(), codec.simplex_dim());
    let (n, r) = (s.len(), s.rim_len());
    let mut prev: Vec<[u64; W]> = (0..n + r)
        .into_par_iter()
        .with_min_len(CHUNK)
        .map(|i| {
            let src = if i < n { s.key(i) } else { s.rim_key(i - n) };
            let mut key = [0u64; W];
            key[..src.len()].copy_from_slice(src);
            key
        })
        .collect();
    let mut prev_codec = codec;
    let mut prev_mixed: Vec<bool> = (0..n + r).into_par_iter().map(|i| i >= n).collect();
    let mut levels = Vec::with_capacity(d - k);
    let mut defects = Vec::new();
    for j in 1..=d - k {
        if cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(Error::Interrupted(
                "the cell complex was interrupted".into(),
            ));
        }
        let cj = KeyCodec::new(d, k + j, bits)?;
        let Survey { counts, lo, hi } = survey(&prev, &prev_codec);
        let in_u64 = Packer::<W, u64>::new(&cj, &lo, &hi, prev.len()).filter(|_| packing);
        let in_u128 = match in_u64 {
            None if packing => Packer::<W, u128>::new(&cj, &lo, &hi, prev.len()),
            _ => None,
        };
        let packed_bytes = match (&in_u64, &in_u128) {
            (Some(_), _) => Some(8),
            (None, Some(_)) => Some(16),
            (None, None) => None,
        };
        // The pairs are the peak: refuse up front rather than exhaust memory.
        let count: u64 = counts.iter().sum();
        let need = crate::memory::in_use(held_bytes::<W>(&levels, prev.len()) + s.memory_bytes())
            + peak_bytes::<W>(count, packed_bytes);
        if need > max_memory {
            return Err(Error::Trace(format!(
                "the cell complex needs about {} for its {j}-cells, over the memory limit of {} \
                 (raise --max-memory, use a larger edge, or --no-complex)",
                crate::memory::human_bytes(need),
                crate::memory::human_bytes(max_memory)
            )));
        }
        let run = run_len(count as usize);
        let level = Below {
            keys: &prev,
            codec: &prev_codec,
            counts: &counts,
            mixed: &prev_mixed,
            jn: (j, n),
            run,
        };
        // All interior: clipping adds the boundary cells.
        let packed = match (&in_u64, &in_u128) {
            (Some(p), _) => packed_level(p, &level, &mut defects)?,
            (None, Some(p)) => packed_level(p, &level, &mut defects)?,
            (None, None) => None,
        };
        let (keys, cells, mixed) = match packed {
            Some(level) => level,
            None => {
                let mut pairs = wide_pairs(&prev, &prev_codec, &cj, &counts)?;
                pairs.par_sort_unstable();
                group_cofacets(&pairs, &Wide, &prev_mixed, (j, n), run, &mut defects)
            }
        };
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

/// Bytes held while level j is built: the levels 1..j-1 (facet indices, offsets and mixed
/// flags) and level j - 1's `prev` keys of `W` words with their mixed flags.
fn held_bytes<const W: usize>(levels: &[RawLevel], prev: usize) -> usize {
    levels
        .iter()
        .map(|l| l.cells.facets.len() * 4 + l.cells.offsets.len() * 5)
        .sum::<usize>()
        + prev * (W * 8 + 1)
}

/// Bytes that building a level from `cofacets` cofacets adds at its peak: the (key, index)
/// pairs (packed: `packed` bytes each, and as much again to sort them), and for the new
/// level at most as many keys, facet indices and mixed flags.
fn peak_bytes<const W: usize>(cofacets: u64, packed: Option<usize>) -> u64 {
    let pair = match packed {
        Some(bytes) => 2 * bytes,
        None => std::mem::size_of::<([u64; W], u32)>(),
    };
    cofacets * (pair + W * 8 + 5) as u64
}

/// How a sorted list of (cofacet key, facet index) pairs of type `P` is read.
trait ReadPairs<P, const W: usize>: Sync {
    /// What equal cofacets share.
    type Group: PartialEq;
    fn group(&self, pair: &P) -> Self::Group;
    fn index(&self, pair: &P) -> u32;
    fn key(&self, pair: &P) -> [u64; W];
}

/// Pairs as they are.
struct Wide;

impl<const W: usize> ReadPairs<([u64; W], u32), W> for Wide {
    type Group = [u64; W];
    fn group(&self, pair: &([u64; W], u32)) -> [u64; W] {
        pair.0
    }
    fn index(&self, pair: &([u64; W], u32)) -> u32 {
        pair.1
    }
    fn key(&self, pair: &([u64; W], u32)) -> [u64; W] {
        pair.0
    }
}

impl<const W: usize, P: Word> ReadPairs<P, W> for Packer<W, P> {
    type Group = P;
    fn group(&self, pair: &P) -> P {
        *pair >> self.index_bits()
    }
    fn index(&self, pair: &P) -> u32 {
        Packer::index(self, *pair)
    }
    fn key(&self, pair: &P) -> [u64; W] {
        Packer::key(self, *pair)
    }
}

/// Simplices per parallel work item when listing cofacets.
const CHUNK: usize = 256;
/// Fewest cofacet pairs per parallel work item when grouping them into cells.
const GROUP_CHUNK: usize = 1 << 14;

/// What listing the cofacets of some simplices needs: how many cofacets each [`CHUNK`] of
/// them has, and the box of the cofacets' base vertices (a cofacet's base vertex is its
/// face's or one step below it, so the faces' box widened by one step).
struct Survey {
    counts: Vec<u64>,
    lo: Vec<i32>,
    hi: Vec<i32>,
}

/// The [`Survey`] of the simplices `keys`.
fn survey<const W: usize>(keys: &[[u64; W]], codec: &KeyCodec) -> Survey {
    let d = codec.ambient_dim();
    let chunks: Vec<(u64, [i32; MAX_DIM], [i32; MAX_DIM])> = keys
        .par_chunks(CHUNK)
        .map_init(
            || codec.scratch(),
            |sigma, keys| {
                let (mut count, mut lo, mut hi) = (0, [i32::MAX; MAX_DIM], [i32::MIN; MAX_DIM]);
                for key in keys {
                    decode(codec, key, sigma);
                    count += sigma.cofacet_count();
                    for (i, &c) in sigma.base().iter().enumerate() {
                        lo[i] = lo[i].min(c);
                        hi[i] = hi[i].max(c);
                    }
                }
                (count, lo, hi)
            },
        )
        .collect();
    let (mut lo, mut hi) = (vec![i32::MAX; d], vec![i32::MIN; d]);
    for (_, a, b) in &chunks {
        for i in 0..d {
            lo[i] = lo[i].min(a[i]);
            hi[i] = hi[i].max(b[i]);
        }
    }
    Survey {
        counts: chunks.iter().map(|c| c.0).collect(),
        lo: lo.iter().map(|x| x.saturating_sub(1)).collect(),
        hi: hi.iter().map(|x| x.saturating_add(1)).collect(),
    }
}

/// Decodes `key` (a key of `codec`, padded to `W` words) into `out`: keys of exactly `W`
/// words take the 128-bit path.
#[inline]
fn decode<const W: usize>(codec: &KeyCodec, key: &[u64; W], out: &mut Simplex) {
    if codec.words() == W {
        codec.decode_into_w(key, out);
    } else {
        codec.decode_into(key, out);
    }
}

/// The (cofacet key, index) pairs of every simplex in `keys`, as `fill(simplex, index,
/// out)` writes those of one (false: it could not); `counts` holds how many cofacets each
/// [`CHUNK`] of them has. Written in place, chunk by chunk in parallel, so that no thread
/// copies or first touches the whole list alone. `None` where `fill` could not.
fn cofacet_pairs<const W: usize, P: Copy + Send + Sync>(
    keys: &[[u64; W]],
    codec: &KeyCodec,
    counts: &[u64],
    zero: P,
    fill: impl Fn(&Simplex, u32, &mut [P]) -> Result<bool> + Sync,
) -> Result<Option<Vec<P>>> {
    if keys.len() > u32::MAX as usize {
        return Err(Error::Trace("too many cells for 32-bit indices".into()));
    }
    let total = usize::try_from(counts.iter().sum::<u64>())
        .map_err(|_| Error::Trace("too many cofacets for this machine".into()))?;
    let mut pairs = zeroed(total, zero);
    let mut outs = Vec::with_capacity(counts.len());
    let mut rest = &mut pairs[..];
    for &c in counts {
        let (out, tail) = rest.split_at_mut(c as usize);
        outs.push(out);
        rest = tail;
    }
    let all = keys.par_chunks(CHUNK).zip(outs).enumerate().try_fold(
        || true,
        |all, (c, (chunk, out))| -> Result<bool> {
            if !all {
                return Ok(false);
            }
            let mut sigma = codec.scratch();
            let mut at = 0;
            for (j, k) in chunk.iter().enumerate() {
                decode(codec, k, &mut sigma);
                let n = sigma.cofacet_count() as usize;
                if !fill(&sigma, (c * CHUNK + j) as u32, &mut out[at..at + n])? {
                    return Ok(false);
                }
                at += n;
            }
            debug_assert_eq!(at, out.len());
            Ok(true)
        },
    );
    let all = all.try_reduce(|| true, |a, b| Ok(a && b))?;
    Ok(all.then_some(pairs))
}

/// [`cofacet_pairs`] packed by `packer`.
fn packed_pairs<const W: usize, P: Word>(
    keys: &[[u64; W]],
    codec: &KeyCodec,
    counts: &[u64],
    packer: &Packer<W, P>,
) -> Result<Option<Vec<P>>> {
    cofacet_pairs(keys, codec, counts, P::default(), |sigma, i, out| {
        Ok(packer.cofacets(sigma, i, out))
    })
}

/// What level j is built from: the level below.
struct Below<'a, const W: usize> {
    keys: &'a [[u64; W]],
    codec: &'a KeyCodec,
    /// How many cofacets each [`CHUNK`] of `keys` has.
    counts: &'a [u64],
    mixed: &'a [bool],
    /// (j, |S|).
    jn: (usize, usize),
    /// Pairs per parallel work item when grouping.
    run: usize,
}

/// A level's cells: their keys, facet lists and mixed flags.
type Cells<const W: usize> = (Vec<[u64; W]>, Level, Vec<bool>);

/// The cells of a level from its pairs packed by `packer`, sorted and grouped; `None`
/// where a face lies outside the packer's box.
fn packed_level<const W: usize, P: Word>(
    packer: &Packer<W, P>,
    below: &Below<'_, W>,
    defects: &mut Vec<u32>,
) -> Result<Option<Cells<W>>> {
    let Some(pairs) = packed_pairs(below.keys, below.codec, below.counts, packer)? else {
        return Ok(None);
    };
    let pairs = par_sort_distinct(pairs);
    Ok(Some(group_cofacets(
        &pairs,
        packer,
        below.mixed,
        below.jn,
        below.run,
        defects,
    )))
}

/// [`cofacet_pairs`] as they are.
fn wide_pairs<const W: usize>(
    keys: &[[u64; W]],
    codec: &KeyCodec,
    cofacet_codec: &KeyCodec,
    counts: &[u64],
) -> Result<Vec<([u64; W], u32)>> {
    let pairs = cofacet_pairs(keys, codec, counts, ([0; W], 0), |sigma, i, out| {
        let (mut at, mut err) = (0, None);
        sigma.for_each_cofacet(|tau| {
            if err.is_none() {
                match cofacet_codec.encode(tau, &mut out[at].0) {
                    Ok(()) => {
                        out[at].1 = i;
                        at += 1;
                    }
                    Err(e) => err = Some(e),
                }
            }
        });
        err.map_or(Ok(true), Err)
    })?;
    Ok(pairs.expect("wide pairs take every key"))
}

/// The cells of level `j` from its sorted (cofacet key, facet index) `pairs`: their keys,
/// their facet lists and whether any facet is mixed (`prev_mixed`). For j = 1, edges with
/// no vertex among the first `n` (S) are dropped and those without exactly two vertices are
/// appended to `defects`. Grouped in parallel over runs of about `run` pairs that start at
/// a new key, counted first and then written in place; the result does not depend on `run`.
fn group_cofacets<P: Sync, const W: usize>(
    pairs: &[P],
    read: &impl ReadPairs<P, W>,
    prev_mixed: &[bool],
    (j, n): (usize, usize),
    run: usize,
    defects: &mut Vec<u32>,
) -> Cells<W> {
    // A group is a cell, or dropped, or a defect.
    let kind = |group: &[P]| {
        if j == 1 && group.iter().all(|p| read.index(p) as usize >= n) {
            None
        } else {
            Some(j != 1 || group.len() == 2)
        }
    };
    let same = |a: &P, b: &P| read.group(a) == read.group(b);
    // With no mixed cell below (no box cuts M), none here is mixed.
    let any_mixed = prev_mixed.contains(&true);
    let runs = runs_of(pairs, run, same);
    // (cells, facets) of each run.
    let sizes: Vec<(usize, usize)> = runs
        .par_iter()
        .map(|run| {
            run.chunk_by(same)
                .filter(|g| kind(g) == Some(true))
                .fold((0, 0), |(c, f), g| (c + 1, f + g.len()))
        })
        .collect();
    let (cells, facets) = sizes.iter().fold((0, 0), |(c, f), s| (c + s.0, f + s.1));
    let mut keys = zeroed(cells, [0u64; W]);
    let mut mixed = zeroed(cells, false);
    let mut offsets = zeroed(cells + 1, 0u32);
    let mut lists = zeroed(facets, 0u32);
    let mut outs = Vec::with_capacity(runs.len());
    let (mut k, mut m, mut o, mut l) = (
        &mut keys[..],
        &mut mixed[..],
        &mut offsets[1..],
        &mut lists[..],
    );
    let mut base = 0u32;
    for &(c, f) in &sizes {
        let (k0, k1) = k.split_at_mut(c);
        let (m0, m1) = m.split_at_mut(c);
        let (o0, o1) = o.split_at_mut(c);
        let (l0, l1) = l.split_at_mut(f);
        outs.push((k0, m0, o0, l0, base));
        (k, m, o, l) = (k1, m1, o1, l1);
        base += f as u32;
    }
    let found: Vec<Vec<u32>> = runs
        .into_par_iter()
        .zip(outs)
        .map(|(run, (k, m, o, l, base))| {
            let (mut c, mut f) = (0, 0);
            let mut defects = Vec::new();
            for group in run.chunk_by(same) {
                match kind(group) {
                    None => {}
                    Some(false) => defects.push(read.index(&group[0])),
                    Some(true) => {
                        k[c] = read.key(&group[0]);
                        m[c] =
                            any_mixed && group.iter().any(|p| prev_mixed[read.index(p) as usize]);
                        for (slot, p) in l[f..f + group.len()].iter_mut().zip(group) {
                            *slot = read.index(p);
                        }
                        f += group.len();
                        o[c] = base + f as u32;
                        c += 1;
                    }
                }
            }
            defects
        })
        .collect();
    defects.extend(found.into_iter().flatten());
    (keys, Level::from_lists(offsets, lists, cells), mixed)
}

/// A vector of `len` copies of `value`, written in parallel (the pages are first touched
/// by every thread, not one).
fn zeroed<T: Clone + Send + Sync>(len: usize, value: T) -> Vec<T> {
    let mut v = Vec::with_capacity(len);
    v.par_extend(rayon::iter::repeat_n(value, len));
    v
}

/// How many of `len` sorted pairs a parallel work item groups: about four items per
/// thread, at least [`GROUP_CHUNK`].
fn run_len(len: usize) -> usize {
    len.div_ceil(4 * rayon::current_num_threads())
        .max(GROUP_CHUNK)
}

/// `sorted` cut into consecutive runs of at least `want` (at least 1) items but the last,
/// each cut where the key changes (`same` tells items of one key), so that no key spans two
/// runs; none when `sorted` is empty.
fn runs_of<T>(sorted: &[T], want: usize, same: impl Fn(&T, &T) -> bool) -> Vec<&[T]> {
    let want = want.max(1);
    let mut runs = Vec::new();
    let mut rest = sorted;
    while !rest.is_empty() {
        let mut cut = want.min(rest.len());
        while cut < rest.len() && same(&rest[cut], &rest[cut - 1]) {
            cut += 1;
        }
        let (run, tail) = rest.split_at(cut);
        runs.push(run);
        rest = tail;
    }
    runs
}

/// Cuts the mixed cells at the domain's boundary: each mixed j-cell keeps its facets and
/// gains a boundary facet, the (j-1)-cell where it leaves the domain, whose facets are the
/// boundary cells of the cell's mixed facets.
fn clip(s: &Sample, domain: &Domain, mut raw: Vec<RawLevel>, d: usize, m: usize) -> Complex {
    let n = s.len();
    // Boundary vertices, one per mixed edge, where the edge leaves the domain. S's points
    // are shared with the sample, and copied only where boundary vertices follow them.
    let mut points = s.shared_points();
    let edges = raw.first();
    if let Some(e) = edges.filter(|e| e.mixed.contains(&true)) {
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
        match Arc::get_mut(&mut points) {
            // Computed for this complex alone (the sample kept none).
            Some(own) => own.extend(cut),
            None => {
                let mut all = Vec::with_capacity(points.len() + cut.len());
                all.extend_from_slice(&points);
                all.extend(cut);
                points = Arc::new(all);
            }
        }
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
        if !raw[j - 1].mixed.contains(&true) {
            // No cell here meets the boundary, so none above does: the level as built.
            levels.push(std::mem::take(&mut raw[j - 1].cells));
            continue;
        }
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
        polygons: Default::default(),
        stats: ComplexStats::default(),
    }
}

#[cfg(test)]
mod tests {
    use std::collections::HashMap;

    use super::*;
    use crate::expr::{preset, Problem};
    use crate::trace::{trace, CpuOracle, TraceOptions};
    use crate::triangulation::Simplex;

    /// The sphere of radius 1 in R^3 at a coarse edge (a few hundred crossed edges), traced
    /// inside `bbox`.
    fn sphere(bbox: Option<Vec<[f64; 2]>>) -> (Problem, Sample) {
        let mut p = preset("sphere", &[]).unwrap();
        p.triangulation.edge = Some(0.35);
        let tri = p.triangulation.build(3).unwrap();
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            bbox,
            ..TraceOptions::default()
        };
        let s = trace(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap();
        (p, s)
    }

    fn keyed(p: &Problem, s: &Sample, bbox: Option<&[[f64; 2]]>) -> (Complex, CellKeys) {
        let (c, keys) = build(s, &Domain::new(&p.system, bbox), u64::MAX, None, true).unwrap();
        (c, keys.unwrap())
    }

    /// The cells of level j decoded from their keys.
    fn cells(s: &Sample, keys: &CellKeys, j: usize) -> Vec<Simplex> {
        let codec = s.codec();
        let bits = (codec.coord_bits() + 1).min(32);
        let cj = KeyCodec::new(codec.ambient_dim(), codec.simplex_dim() + j, bits).unwrap();
        keys.keys[j - 1]
            .chunks_exact(keys.words)
            .map(|k| cj.decode(&k[..cj.words()]))
            .collect()
    }

    /// Sorted facet lists of the cofacets of `lower` (simplex -> its index), found by brute
    /// force: every cofacet of every simplex, with the indices of its faces among `lower`.
    fn cofaces_of(lower: &[Simplex]) -> Vec<(Simplex, Vec<u32>)> {
        let index: HashMap<&Simplex, u32> = lower
            .iter()
            .enumerate()
            .map(|(i, x)| (x, i as u32))
            .collect();
        let mut up: HashMap<Simplex, Vec<u32>> = HashMap::new();
        for x in lower {
            for tau in x.cofacets() {
                let mut faces: Vec<u32> = tau
                    .facets()
                    .iter()
                    .filter_map(|f| index.get(f).copied())
                    .collect();
                faces.sort_unstable();
                up.insert(tau, faces);
            }
        }
        let mut v: Vec<_> = up.into_iter().collect();
        v.sort_by(|a, b| a.1.cmp(&b.1));
        v
    }

    fn sorted(f: &[u32]) -> Vec<u32> {
        let mut f = f.to_vec();
        f.sort_unstable();
        f
    }

    #[test]
    fn runs_cover_the_pairs_in_order_and_never_split_a_key() {
        let keys = [1, 1, 2, 3, 3, 3, 4, 6, 6, 7];
        let pairs: Vec<(u32, usize)> = keys.iter().copied().zip(0..).collect();
        for want in 0..=pairs.len() + 1 {
            let runs = runs_of(&pairs, want, |a, b| a.0 == b.0);
            assert_eq!(runs.concat(), pairs, "run length {want}");
            for (i, r) in runs.iter().enumerate() {
                assert!(!r.is_empty(), "run length {want}");
                if i + 1 < runs.len() {
                    assert!(r.len() >= want, "run length {want}: {r:?}");
                    assert_ne!(r.last().unwrap().0, runs[i + 1][0].0, "run length {want}");
                }
            }
        }
        let same = |a: &(u32, usize), b: &(u32, usize)| a.0 == b.0;
        assert!(runs_of(&pairs[..0], 3, same).is_empty());
        assert_eq!(runs_of(&pairs, 4, same).len(), 2);
    }

    #[test]
    fn grouping_in_runs_of_any_length_gives_the_same_cells() {
        // Keys with groups of 1, 2 and 3 pairs; facets 0..6, of which 4.. are not in S (n = 4)
        // and mixed, and so is 1.
        let raw = [
            (1, 0),
            (1, 4),
            (2, 5),
            (3, 1),
            (3, 2),
            (3, 6),
            (5, 2),
            (5, 3),
            (7, 4),
            (7, 5),
        ];
        let pairs: Vec<([u64; 1], u32)> = raw.iter().map(|&(k, f)| ([k], f)).collect();
        let prev_mixed = [false, true, false, false, true, true, true];
        for j in [1, 2] {
            let mut defects = Vec::new();
            let whole =
                group_cofacets(&pairs, &Wide, &prev_mixed, (j, 4), usize::MAX, &mut defects);
            let lists = |l: &Level| {
                (0..l.len())
                    .map(|i| l.facets(i).to_vec())
                    .collect::<Vec<_>>()
            };
            if j == 1 {
                // Keys 2 and 7 lie outside S; key 3 has three vertices: a defect.
                assert_eq!(whole.0, [[1], [5]]);
                assert_eq!(lists(&whole.1), [vec![0, 4], vec![2, 3]]);
                assert_eq!(whole.2, [true, false]);
                assert_eq!(defects, [1]);
            } else {
                assert_eq!(whole.0.len(), 5);
                assert_eq!(lists(&whole.1)[2], [1, 2, 6]);
                assert_eq!(whole.2, [true, true, true, false, true]);
            }
            for run in 0..=pairs.len() {
                let mut d = Vec::new();
                let part = group_cofacets(&pairs, &Wide, &prev_mixed, (j, 4), run, &mut d);
                assert_eq!(part.0, whole.0, "j {j}, run {run}");
                assert_eq!(lists(&part.1), lists(&whole.1), "j {j}, run {run}");
                assert_eq!(part.1.interior(), whole.1.interior(), "j {j}, run {run}");
                assert_eq!(part.2, whole.2, "j {j}, run {run}");
                assert_eq!(d, defects, "j {j}, run {run}");
            }
        }
    }

    #[test]
    fn each_level_is_the_cofacets_of_the_one_below_with_their_faces() {
        let (p, s) = sphere(None);
        assert!(s.len() > 300 && s.rim_len() == 0, "{}", s.len());
        let (c, keys) = keyed(&p, &s, None);
        let mut lower: Vec<Simplex> = (0..s.len()).map(|i| s.simplex(i)).collect();
        for j in 1..=2 {
            let got = cells(&s, &keys, j);
            let level = c.level(j);
            assert_eq!(got.len(), level.len(), "level {j}");
            let mut mine: Vec<(Simplex, Vec<u32>)> = got
                .iter()
                .enumerate()
                .map(|(i, x)| (x.clone(), sorted(level.facets(i))))
                .collect();
            mine.sort_by(|a, b| a.1.cmp(&b.1));
            let want = cofaces_of(&lower);
            assert_eq!(mine.len(), want.len(), "level {j}");
            for (a, b) in mine.iter().zip(&want) {
                assert_eq!(a, b, "level {j}");
            }
            // Closed: no boundary, nothing mixed, every edge has two ends.
            assert_eq!(level.interior(), level.len());
            assert!(keys.mixed[j - 1].iter().all(|m| !m));
            if j == 1 {
                assert!((0..level.len()).all(|i| level.facets(i).len() == 2));
            }
            lower = got;
        }
        assert_eq!(c.vertex_count(), s.len());
        assert_eq!(c.points(), &s.points()[..]);
        let n = c.counts();
        assert_eq!(n[0] as i64 - n[1] as i64 + n[2] as i64, 2, "{n:?}");
        assert!(keys.defects.is_empty() && c.stats.defects == 0);
    }

    #[test]
    fn the_complex_shares_the_points_the_sample_kept() {
        // Closed: the complex's vertices are S's points, held once.
        let (p, s) = sphere(None);
        s.check_crossings(&p.system);
        let (c, _) = build(&s, &Domain::new(&p.system, None), u64::MAX, None, false).unwrap();
        assert!(std::ptr::eq(c.points(), &s.shared_points()[..]));
        // Cut by a box: S's points and the boundary vertices after them, in a copy.
        let bbox = vec![[-2.0, 2.0], [-2.0, 2.0], [-2.0, 0.3]];
        let (p, s) = sphere(Some(bbox.clone()));
        s.check_crossings(&p.system);
        let domain = Domain::new(&p.system, Some(&bbox));
        let (c, _) = build(&s, &domain, u64::MAX, None, false).unwrap();
        let kept = s.shared_points();
        assert!(c.vertex_count() > s.len());
        assert_eq!(&c.points()[..kept.len()], &kept[..]);
    }

    #[test]
    fn a_box_cuts_the_mixed_cells_where_they_leave_it() {
        let top = 0.3;
        let bbox = vec![[-2.0, 2.0], [-2.0, 2.0], [-2.0, top]];
        let (p, s) = sphere(Some(bbox.clone()));
        assert!(s.rim_len() > 10, "{}", s.rim_len());
        let (c, keys) = keyed(&p, &s, Some(&bbox));
        let n = s.len();
        let (edges, faces) = (c.level(1), c.level(2));
        let mixed_edges = keys.mixed[0].iter().filter(|&&m| m).count();
        assert!(mixed_edges > 10);
        // One boundary vertex per mixed edge, on the box's top face, between the edge's
        // ends.
        assert_eq!(c.vertex_count(), n + mixed_edges);
        for b in n..c.vertex_count() {
            assert!((c.point(b)[2] - top).abs() < 1e-12, "{:?}", c.point(b));
            let r: f64 = c.point(b).iter().map(|x| x * x).sum::<f64>().sqrt();
            assert!((r - 1.0).abs() < 0.1, "{r}");
        }
        // Interior edges: two vertices of S; mixed ones: one of S and its boundary vertex,
        // in order.
        let mut next = n as u32;
        for i in 0..edges.interior() {
            let f = edges.facets(i);
            assert_eq!(f.len(), 2);
            if keys.mixed[0][i] {
                assert_eq!(f.iter().filter(|&&v| (v as usize) < n).count(), 1, "{f:?}");
                assert_eq!(f[1], next, "{f:?}");
                next += 1;
            } else {
                assert!(f.iter().all(|&v| (v as usize) < n), "{f:?}");
            }
        }
        // Boundary edges: the cuts of the mixed polygons, each joining the boundary
        // vertices of two of its mixed edges.
        let mixed_faces: Vec<usize> = (0..faces.interior())
            .filter(|&i| keys.mixed[1][i])
            .collect();
        assert_eq!(edges.len() - edges.interior(), mixed_faces.len());
        for (t, &i) in mixed_faces.iter().enumerate() {
            let cut = edges.facets(edges.interior() + t);
            assert_eq!(cut.len(), 2, "{cut:?}");
            assert!(cut.iter().all(|&v| v as usize >= n));
            let f = faces.facets(i);
            assert_eq!(*f.last().unwrap() as usize, edges.interior() + t, "{f:?}");
            for &v in cut {
                let e = (0..edges.interior())
                    .find(|&e| edges.facets(e)[1] == v)
                    .unwrap();
                assert!(f.contains(&(e as u32)), "{f:?} lacks edge {e}");
            }
        }
        assert_eq!(faces.interior(), faces.len());
        // A sphere cut below its north cap: a disk, bounded by one circle.
        let n = c.counts();
        assert_eq!(n[0] as i64 - n[1] as i64 + n[2] as i64, 1, "{n:?}");
        assert_eq!(c.boundary_counts()[0], c.boundary_counts()[1]);
        let t = c.topology();
        assert!(t.manifold && !t.closed, "{t:?}");
        assert_eq!(t.betti_mod2, Some(vec![1, 0, 0]), "{t:?}");
        assert_eq!(t.boundary_euler_characteristic, 0, "{t:?}");
    }

    #[test]
    fn the_memory_estimate_covers_what_a_level_holds() {
        let (p, s) = sphere(None);
        let codec = s.codec();
        let bits = (codec.coord_bits() + 1).min(32);
        let words = KeyCodec::new(3, 3, bits)
            .unwrap()
            .words()
            .max(codec.words());
        const W: usize = 2;
        assert_eq!(words, W);
        let (levels, _) = raw_levels::<W>(&s, bits, u64::MAX, None, true, true).unwrap();
        // Level 1, built from S: its pairs (as many as counted) and its own arrays.
        let prev: Vec<[u64; W]> = (0..s.len())
            .map(|i| {
                let mut key = [0; W];
                key[..s.key(i).len()].copy_from_slice(s.key(i));
                key
            })
            .collect();
        let cj = KeyCodec::new(3, 2, bits).unwrap();
        let Survey { counts, lo, hi } = survey(&prev, codec);
        let packer = Packer::<W>::new(&cj, &lo, &hi, prev.len()).unwrap();
        let pairs = packed_pairs(&prev, codec, &counts, &packer)
            .unwrap()
            .unwrap();
        // Counted by listing them.
        let mut count = 0u64;
        for k in &prev {
            codec.decode(k).for_each_cofacet(|_| count += 1);
        }
        assert_eq!(pairs.len() as u64, count);
        let l = &levels[0];
        // The packed pairs, and as much again to sort them.
        let peak = 2 * size_of_val(&pairs[..])
            + size_of_val(&l.keys[..])
            + size_of_val(&l.cells.facets[..])
            + size_of_val(&l.mixed[..]);
        let estimate = peak_bytes::<W>(count, Some(size_of_val(&pairs[0]))) as usize;
        assert!(
            peak <= estimate && estimate <= 2 * peak,
            "{peak} {estimate}"
        );
        // The estimate holds the worst case: as many cells as cofacets, each with a key, a
        // flag and one facet index per pair.
        assert_eq!(l.cells.facets.len() as u64, count);
        let worst = 2 * size_of_val(&pairs[..])
            + count as usize * (size_of::<[u64; W]>() + size_of_val(&l.mixed[0]))
            + size_of_val(&l.cells.facets[..]);
        assert!(worst <= estimate, "{worst} {estimate}");
        // What is held while level 2 is built: level 1, and its keys with their flags.
        let held = size_of_val(&l.cells.facets[..])
            + size_of_val(&l.cells.offsets[..])
            + size_of_val(&l.mixed[..])
            + l.cells.len() * (W * 8 + 1);
        let estimate = held_bytes::<W>(&levels[..1], l.cells.len());
        assert!(
            held <= estimate && estimate <= held + 16,
            "{held} {estimate}"
        );
        // The check refuses exactly past its estimate (no counting allocator here: the
        // heap in use is the estimate).
        let need = (held_bytes::<W>(&[], s.len()) + s.memory_bytes()) as u64
            + peak_bytes::<W>(count, Some(8));
        let domain = Domain::new(&p.system, None);
        let e = build(&s, &domain, need - 1, None, false).err().unwrap();
        assert!(e.to_string().contains("for its 1-cells"), "{e}");
        if let Err(e) = build(&s, &domain, need, None, false) {
            assert!(e.to_string().contains("for its 2-cells"), "{e}");
        }
    }

    #[test]
    fn a_cancelled_or_too_large_construction_is_refused() {
        let (p, s) = sphere(None);
        let domain = Domain::new(&p.system, None);
        let e = build(&s, &domain, 1 << 10, None, false).err().unwrap();
        assert!(e.to_string().contains("over the memory limit"), "{e}");
        let cancel = AtomicBool::new(true);
        let e = build(&s, &domain, u64::MAX, Some(&cancel), false)
            .err()
            .unwrap();
        assert!(e.to_string().contains("interrupted"), "{e}");
        let ok = build(&s, &domain, u64::MAX, Some(&AtomicBool::new(false)), false).unwrap();
        assert!(ok.1.is_none());
        assert_eq!(
            ok.0.counts(),
            Complex::build(&s, &p.system, None).unwrap().counts()
        );
    }

    /// A raw level's facet lists, keys and mixed flags.
    type Raw = (Vec<Vec<u32>>, Vec<u64>, Vec<bool>);

    /// The raw levels' cells, keys, mixed flags and defects, to compare two constructions.
    fn raw_of<const W: usize>(s: &Sample, packing: bool) -> Vec<Raw> {
        let bits = (s.codec().coord_bits() + 1).min(32);
        let (levels, defects) = raw_levels::<W>(s, bits, u64::MAX, None, true, packing).unwrap();
        let mut out: Vec<_> = levels
            .iter()
            .map(|l| {
                let lists = (0..l.cells.len())
                    .map(|i| l.cells.facets(i).to_vec())
                    .collect();
                (lists, l.keys.clone(), l.mixed.clone())
            })
            .collect();
        out.push((vec![defects], Vec::new(), Vec::new()));
        out
    }

    /// Whether the 1-cells of `s` are built from pairs packed into a `P` each.
    fn packs<const W: usize, P: Word>(s: &Sample) -> bool {
        let codec = s.codec();
        let bits = (codec.coord_bits() + 1).min(32);
        let c1 = KeyCodec::new(codec.ambient_dim(), codec.simplex_dim() + 1, bits).unwrap();
        let keys: Vec<[u64; W]> = (0..s.len())
            .map(|i| std::array::from_fn(|w| s.key(i).get(w).copied().unwrap_or(0)))
            .collect();
        let Survey { lo, hi, .. } = survey(&keys, codec);
        Packer::<W, P>::new(&c1, &lo, &hi, s.len() + s.rim_len()).is_some()
    }

    /// The sample of preset `name` with `params`, traced at `edge`.
    fn traced(name: &str, params: &[(String, f64)], edge: f64) -> Sample {
        let mut p = preset(name, params).unwrap();
        p.triangulation.edge = Some(edge);
        let tri = p.triangulation.build(p.dim()).unwrap();
        let opts = TraceOptions {
            seeds: p.seeds.clone(),
            ..TraceOptions::default()
        };
        trace(&p.system, &tri, &CpuOracle::new(&p.system), &opts).unwrap()
    }

    #[test]
    fn packed_and_wide_pairs_give_the_same_cells() {
        // The sphere with no box (two-word keys, a part field cut where a word ends), and
        // cut by a box (mixed cells).
        let (_, s) = sphere(None);
        assert_eq!(s.codec().words(), 1);
        assert!(packs::<2, u64>(&s));
        assert_eq!(raw_of::<2>(&s, true), raw_of::<2>(&s, false));
        let (_, s) = sphere(Some(vec![[-2.0, 2.0], [-2.0, 2.0], [-2.0, 0.3]]));
        assert!(s.rim_len() > 10 && packs::<1, u64>(&s));
        assert_eq!(raw_of::<1>(&s, true), raw_of::<1>(&s, false));
        // The flat torus in R^4: two levels, four-dimensional keys.
        let s = traced("flat-torus", &[], 0.3);
        // A coordinate cut where a word ends.
        assert!(s.len() > 300 && packs::<2, u64>(&s));
        let packed = raw_of::<2>(&s, true);
        assert_eq!(packed.len(), 3);
        assert_eq!(packed, raw_of::<2>(&s, false));
        // S^2 in R^8: keys of four words, which pack into 128 bits, not 64.
        let s = traced("sphere", &[("d".into(), 8.0)], 0.5);
        assert!(s.len() > 1000 && !packs::<4, u64>(&s) && packs::<4, u128>(&s));
        let packed = raw_of::<4>(&s, true);
        assert_eq!(packed.len(), 3);
        assert_eq!(packed, raw_of::<4>(&s, false));
    }

    #[test]
    fn pairs_of_a_face_outside_the_packers_box_are_refused() {
        // A box one step short on one side leaves out a few simplices of one work item: the
        // whole list is refused, not the item alone.
        let (_, s) = sphere(None);
        let codec = s.codec();
        let bits = (codec.coord_bits() + 1).min(32);
        let c1 = KeyCodec::new(3, 2, bits).unwrap();
        let keys: Vec<[u64; 2]> = (0..s.len()).map(|i| [s.key(i)[0], 0]).collect();
        let Survey { counts, lo, mut hi } = survey(&keys, codec);
        assert!(counts.len() > 2);
        let packer = Packer::<2>::new(&c1, &lo, &hi, s.len()).unwrap();
        let all = packed_pairs(&keys, codec, &counts, &packer)
            .unwrap()
            .unwrap();
        assert_eq!(all.len() as u64, counts.iter().sum::<u64>());
        hi[0] -= 2;
        let packer = Packer::<2>::new(&c1, &lo, &hi, s.len()).unwrap();
        assert!(packed_pairs(&keys, codec, &counts, &packer)
            .unwrap()
            .is_none());
    }

    #[test]
    fn a_cofacets_base_vertex_is_within_a_step_of_its_faces() {
        // What the packed keys' bounds rest on: over S's simplices, their cofacets and theirs.
        let (_, s) = sphere(None);
        let mut lower: Vec<Simplex> = (0..s.len()).map(|i| s.simplex(i)).collect();
        let (mut seen, mut moved) = (0, 0);
        for _ in 0..2 {
            let mut up = Vec::new();
            for sigma in &lower {
                for tau in sigma.cofacets() {
                    let far = sigma
                        .base()
                        .iter()
                        .zip(tau.base())
                        .map(|(a, b)| (a - b).abs())
                        .max();
                    assert!(far <= Some(1), "{sigma:?} {tau:?}");
                    seen += 1;
                    moved += usize::from(far == Some(1));
                    up.push(tau);
                }
            }
            lower = up;
        }
        assert!(seen > 1000 && moved > 100, "{seen} {moved}");
    }
}
