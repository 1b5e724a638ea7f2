//! The scan stage (`shaders/scan.wgsl`): the exhaustive scan's candidate simplices from the
//! grid's integer sign codes, the twin of [`scan::candidates`](crate::trace::scan::candidates::candidates).

use std::ops::Range;
use std::sync::atomic::Ordering;
use std::time::Instant;

use rayon::prelude::*;

use super::device::{add_time, pipeline, Output, Stage};
use super::GpuOracle;
use crate::error::{Error, Result};
use crate::gpu::wgsl::{stage_prelude, validate, Precision};
use crate::trace::scan::candidates::{self, pass_mask, Candidates, BASE};
use crate::trace::ScanGrid;

/// The scan's candidate generator, before its prelude.
pub const SCAN_WGSL: &str = include_str!("../../../shaders/scan.wgsl");
/// Largest d whose scan candidates the GPU generates (each invocation holds two arrays of
/// 2^d words); above it the CPU generator runs.
pub const MAX_GPU_SCAN_DIM: usize = 8;

/// Consecutive cubes per invocation of the scan shader: they mostly lie in one grid row and
/// share its corner rows, which are looked up once.
const SCAN_RUN: usize = 8;
/// The scan shader for k-simplices in R^d, validated by naga.
pub fn scan_shader(d: usize, k: usize) -> Result<String> {
    if !(2..=MAX_GPU_SCAN_DIM).contains(&d) || k == 0 || k >= d {
        return Err(Error::Gpu(format!(
            "the scan shader takes 1 <= k < d <= {MAX_GPU_SCAN_DIM} (k = {k}, d = {d})"
        )));
    }
    let src = format!(
        "{stage}const D: u32 = {d}u;\nconst K: u32 = {k}u;\nconst KP1: u32 = {kp1}u;\n\
         const CORNERS: u32 = {corners}u;\nconst HALF: u32 = {half}u;\n\
         const MASK: u32 = {mask}u;\nconst BASE: u32 = {base}u;\nconst RUN: u32 = {SCAN_RUN}u;\n\
         {SCAN_WGSL}",
        stage = stage_prelude(),
        kp1 = k + 1,
        corners = 1u32 << d,
        half = 1u32 << (d - 1),
        mask = pass_mask(k),
        base = BASE,
    );
    validate(&src, Precision::F32)?;
    Ok(src)
}

/// What one scan dispatch reads: a window of the grid's rows and codes, relative to the
/// first vertex of its first row.
struct ScanWindow {
    /// The vertex the window starts at.
    lo: usize,
    /// The shader's input words.
    input: Vec<u32>,
}

/// The window that holds every corner of the cubes based at `cubes`, or None when its ids
/// or its size do not fit u32 words and `max_bytes`.
fn scan_window(grid: &ScanGrid, cubes: &Range<usize>, max_bytes: u64) -> Option<ScanWindow> {
    let d = grid.dim();
    let rows = grid.rows();
    let first = grid.row_of(cubes.start);
    let (id0, lo) = (rows[first].id, rows[first].offset);
    let reach: usize = (1..d).map(|j| grid.stride(j)).sum();
    let last_id = rows[grid.row_of(cubes.end - 1)].id + reach;
    let end = rows.partition_point(|r| r.id <= last_id);
    let hi = rows.get(end).map_or(grid.len(), |r| r.offset);
    let count = end - first;
    let words = 5 + (d - 1) + 5 * count + (hi - lo);
    if last_id - id0 > u32::MAX as usize || (words as u64) * 4 > max_bytes {
        return None;
    }
    let mut input = Vec::with_capacity(words);
    input.extend([
        (cubes.start - lo) as u32,
        count as u32,
        0,
        0,
        cubes.len() as u32,
    ]);
    input.extend((1..d).map(|j| grid.stride(j) as u32));
    for r in &rows[first..end] {
        input.extend([
            (r.id - id0) as u32,
            r.start as i32 as u32,
            r.len,
            (r.offset - lo) as u32,
            grid.top_axes(r.id),
        ]);
    }
    input[3] = input.len() as u32;
    input.extend_from_slice(&grid.codes()[lo..hi]);
    Some(ScanWindow { lo, input })
}

impl GpuOracle<'_> {
    /// The scan shader's pipeline for R^d, built the first time it is asked for.
    fn scan_pipeline(&self, d: usize) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.scan.get() {
            return Ok(p);
        }
        let built = pipeline(&self.gpu, &scan_shader(d, self.k)?, "scan", self.cancel())?;
        Ok(self.scan.get_or_init(|| built))
    }

    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The scan shader alone (`shaders/scan.wgsl`), the twin of
    /// [`scan::candidates`]: the candidates of the cubes based at the grid vertices
    /// `cubes`, in the same order (the device appends them in any order; the host sorts).
    /// Needs d <= [`MAX_GPU_SCAN_DIM`].
    pub fn scan_stage(&self, grid: &ScanGrid, cubes: Range<usize>) -> Result<Candidates> {
        let (d, k) = (grid.dim(), grid.codim());
        if k != self.k {
            return Err(Error::DimensionMismatch(format!(
                "the grid is of codimension {}, f of {}",
                k, self.k
            )));
        }
        let pipeline = self.scan_pipeline(d)?;
        let record = 2 * k + 1;
        let max_bytes = self.max_binding();
        let mut words: Vec<u32> = Vec::new();
        let mut pending = vec![cubes];
        while let Some(range) = pending.pop() {
            if range.is_empty() {
                continue;
            }
            let window = scan_window(grid, &range, max_bytes);
            let found = match window {
                Some(w) => self.scan_dispatch(pipeline, w, range.len(), record, max_bytes)?,
                None => None,
            };
            match found {
                Some(f) => words.extend(f),
                None if range.len() == 1 => {
                    let mut one = Candidates::default();
                    candidates::cube_candidates(
                        grid,
                        range.start,
                        &mut Default::default(),
                        &mut one,
                    );
                    for (r, c) in one.rows.chunks(k + 1).zip(one.chains.chunks(k)) {
                        words.extend_from_slice(r);
                        words.extend_from_slice(c);
                    }
                }
                None => {
                    // Too large for one binding: halves, the first one next.
                    let mid = range.start + range.len() / 2;
                    pending.push(mid..range.end);
                    pending.push(range.start..mid);
                }
            }
        }
        let sorting = Instant::now();
        let sorted = sorted_candidates(&words, k);
        add_time(&self.host_ns, sorting);
        Ok(sorted)
    }

    /// One dispatch of the scan shader over the `cubes` cubes of `window`: its records with
    /// global vertex indices, or None when they would not fit `max_bytes`.
    fn scan_dispatch(
        &self,
        pipeline: &wgpu::ComputePipeline,
        mut window: ScanWindow,
        cubes: usize,
        record: usize,
        max_bytes: u64,
    ) -> Result<Option<Vec<u32>>> {
        let k = self.k;
        let max_cap = (max_bytes / (4 * record as u64)) as usize;
        let density = self.scan_density.load(Ordering::Relaxed) as usize;
        let mut cap = (cubes * density / (1 << 16) * 5 / 4 + 1024).min(max_cap);
        loop {
            window.input[2] = cap as u32;
            let pending = self.submit(
                Stage::Scan,
                pipeline,
                bytemuck::cast_slice(&window.input),
                cubes.div_ceil(SCAN_RUN),
                &[Output::read(4), Output::read(cap * record * 4)],
                true,
            )?;
            let res = self.finish(pending)?;
            let decoding = Instant::now();
            let found = bytemuck::pod_read_unaligned::<u32>(&res[0][..4]) as usize;
            self.scan_density
                .store((found * (1 << 16) / cubes.max(1)) as u64, Ordering::Relaxed);
            if found <= cap {
                let mut out: Vec<u32> = bytemuck::pod_collect_to_vec(&res[1][..found * record * 4]);
                let lo = window.lo as u32;
                for rec in out.chunks_exact_mut(record) {
                    for v in &mut rec[..=k] {
                        *v += lo;
                    }
                }
                add_time(&self.host_ns, decoding);
                return Ok(Some(out));
            }
            if found > max_cap {
                return Ok(None);
            }
            cap = found;
        }
    }
}

/// Records of 2k + 1 words (k + 1 vertices, k corner sets) as candidates in the CPU's order:
/// by base vertex, then chain.
fn sorted_candidates(words: &[u32], k: usize) -> Candidates {
    let record = 2 * k + 1;
    let mut recs: Vec<&[u32]> = words.chunks_exact(record).collect();
    recs.par_sort_unstable_by(|a, b| a[0].cmp(&b[0]).then_with(|| a[k + 1..].cmp(&b[k + 1..])));
    let mut out = Candidates {
        rows: Vec::with_capacity(recs.len() * (k + 1)),
        chains: Vec::with_capacity(recs.len() * k),
    };
    for r in recs {
        out.rows.extend_from_slice(&r[..=k]);
        out.chains.extend_from_slice(&r[k + 1..]);
    }
    out
}
