//! The device-resident scan (`shaders/tile_values.wgsl`, `shaders/tile_scan.wgsl`, then
//! `shaders/tile_certify.wgsl`):
//! per tile the host uploads a descriptor of a few words; f's certified values and the sign
//! codes stay in device buffers, and only the compacted records of the candidates the device
//! could not prove outside come back. Two tiles are in flight at once, each in its own set
//! of buffers, so the host settles one tile while the device computes the next. The twin is
//! [`twin_tile`](crate::trace::scan::tiles::twin_tile).

use std::sync::atomic::Ordering;
use std::sync::mpsc::Receiver;
use std::sync::OnceLock;
use std::time::Instant;

use super::device::{add_time, pipeline};
use super::solve::{solve_prelude, CERTIFY_WGSL, GAUSS_JORDAN_WGSL};
use super::GpuOracle;
use crate::error::{Error, Result};
use crate::expr::program::Program;
use crate::gpu::wgsl::{certified_prelude, stage_prelude, validate, Precision, WORKGROUP};
use crate::trace::scan::candidates::{pass_mask, BASE};
use crate::trace::scan::tiles::{twin_scan, twin_tile, Tile, TileFound, TilePlan, UNKNOWN};
use crate::trace::scan::MAX_TILED_DIM;
use crate::triangulation::Triangulation;

/// The first tile stage, before its prelude.
pub const TILE_VALUES_WGSL: &str = include_str!("../../../shaders/tile_values.wgsl");
/// The second tile stage (candidates), before its prelude.
pub const TILE_SCAN_WGSL: &str = include_str!("../../../shaders/tile_scan.wgsl");
/// The third tile stage (verdicts), before its prelude.
pub const TILE_CERTIFY_WGSL: &str = include_str!("../../../shaders/tile_certify.wgsl");

/// Workgroups per dispatch row (the limit per dimension).
const MAX_GROUPS: u32 = 65_535;
/// Bytes of the counters: records, candidates, unknown vertices, evaluated vertices.
const COUNTERS: u64 = 16;

/// The tile values shader of `prog` in precision `p`, validated by naga.
pub fn tile_values_shader(prog: &Program, p: Precision) -> Result<String> {
    let src = format!(
        "{prelude}const BASE: u32 = {BASE}u;\nconst UNKNOWN: u32 = {UNKNOWN}u;\n{TILE_VALUES_WGSL}",
        prelude = certified_prelude(prog, p)?
    );
    validate(&src, p)?;
    Ok(src)
}

/// The tile scan shader (candidates) for k-simplices in R^d, validated by naga.
pub fn tile_scan_shader(d: usize, k: usize) -> Result<String> {
    check_dims(d, k)?;
    let src = format!(
        "{stage}const D: u32 = {d}u;\nconst K: u32 = {k}u;\nconst KP1: u32 = {kp1}u;\n\
         const CORNERS: u32 = {corners}u;\nconst MASK: u32 = {mask}u;\nconst BASE: u32 = {BASE}u;\n\
         {TILE_SCAN_WGSL}",
        stage = stage_prelude(),
        kp1 = k + 1,
        corners = 1u32 << d,
        mask = pass_mask(k),
    );
    validate(&src, Precision::F32)?;
    Ok(src)
}

/// The tile certify shader (verdicts) for k-simplices in R^d in precision `p`, validated by
/// naga.
pub fn tile_certify_shader(d: usize, k: usize, p: Precision) -> Result<String> {
    check_dims(d, k)?;
    let src = format!(
        "{prelude}{GAUSS_JORDAN_WGSL}{CERTIFY_WGSL}const D: u32 = {d}u;\nconst K: u32 = {k}u;\n\
         const UNKNOWN: u32 = {UNKNOWN}u;\n{TILE_CERTIFY_WGSL}",
        prelude = solve_prelude(k, p)?,
    );
    validate(&src, p)?;
    Ok(src)
}

fn check_dims(d: usize, k: usize) -> Result<()> {
    if !(2..=MAX_TILED_DIM).contains(&d) || k == 0 || k >= d {
        return Err(Error::Gpu(format!(
            "the tile shaders take 1 <= k < d <= {MAX_TILED_DIM} (k = {k}, d = {d})"
        )));
    }
    Ok(())
}

/// The pipelines of the three stages.
type Pipes<'a> = [&'a wgpu::ComputePipeline; 3];

/// Room for a tile's results: records back, and candidates on the device.
#[derive(Clone, Copy, Debug)]
struct Caps {
    records: usize,
    candidates: usize,
}

/// One set of buffers for a tile in flight.
#[derive(Default)]
struct Slot {
    buffers: Option<Buffers>,
}

struct Buffers {
    tile: wgpu::Buffer,
    params: [wgpu::Buffer; 3],
    values: wgpu::Buffer,
    codes: wgpu::Buffer,
    counters: wgpu::Buffer,
    cands: wgpu::Buffer,
    out: wgpu::Buffer,
    staging: wgpu::Buffer,
}

/// A tile on its way: the room it ran with, and its readback.
struct InFlight {
    caps: Caps,
    index: wgpu::SubmissionIndex,
    mapped: Receiver<std::result::Result<(), wgpu::BufferAsyncError>>,
    size: u64,
}

impl GpuOracle<'_> {
    /// The three tile pipelines, built the first time they are asked for.
    fn tile_pipelines(&self, d: usize) -> Result<Pipes<'_>> {
        let values = self.f_pipeline(&self.tile_values, tile_values_shader, "tile_values")?;
        let built = |cell: &'_ OnceLock<wgpu::ComputePipeline>, src: Result<String>, label| {
            if cell.get().is_none() {
                let p = pipeline(&self.gpu, &src?, label, self.cancel())?;
                let _ = cell.set(p);
            }
            Ok::<_, Error>(())
        };
        built(&self.tile_scan, tile_scan_shader(d, self.k), "tile_scan")?;
        built(
            &self.tile_certify,
            tile_certify_shader(d, self.k, self.precision),
            "tile_certify",
        )?;
        Ok([
            values,
            self.tile_scan.get().expect("built"),
            self.tile_certify.get().expect("built"),
        ])
    }

    /// Whether the shaders take the plan: its lattice coordinates are exact in the
    /// shaders' floats and its dimension within the scan shader's.
    fn takes(&self, plan: &TilePlan) -> bool {
        let exact: i64 = match self.precision {
            Precision::F32 => 1 << 24,
            Precision::F64 => 1 << 31,
        };
        plan.d <= MAX_TILED_DIM
            && plan.tiles.iter().all(|t| {
                t.origin
                    .iter()
                    .zip(&t.counts)
                    .all(|(&o, &n)| (o as i64).abs() < exact && (o as i64 + n as i64).abs() < exact)
            })
    }

    /// [`DeviceValues::scan_tiles`](crate::trace::DeviceValues::scan_tiles) on this device:
    /// the tile shaders, or where they cannot run (an emulated or perturbed device, a plan
    /// the shaders do not take) the twin.
    pub(super) fn scan_tiles_on_device(
        &self,
        tri: &Triangulation,
        plan: &TilePlan,
        each: &mut dyn FnMut(usize, TileFound) -> Result<bool>,
    ) -> Result<()> {
        let twin = self.emulated().is_some()
            || self.perturb.load(Ordering::Relaxed) != 0
            || !self.takes(plan);
        if twin {
            return twin_scan(self, tri, plan, each);
        }
        let pipes = self.tile_pipelines(plan.d)?;
        self.upload_map(tri, plan)?;
        let record = plan.k + 2;
        let max = (self.max_binding() / (4 * record as u64)) as usize;
        let mut slots = [Slot::default(), Slot::default()];
        // Records and candidates per cube in the last tile, to size the next one's room.
        let mut density = (1.0 / 16.0, 1.0 / 8.0);
        let caps = |tile: &Tile, (r, c): (f64, f64)| {
            let cubes = tile.cubes() as f64;
            Caps {
                records: ((cubes * r * 1.25) as usize + 256).min(max),
                candidates: ((cubes * c * 1.25) as usize + 1024).min(max),
            }
        };
        let mut flight: [Option<InFlight>; 2] = [None, None];
        for (t, tile) in plan.tiles.iter().enumerate().take(2) {
            flight[t] =
                Some(self.submit_tile(&mut slots[t], pipes, plan, t, caps(tile, density))?);
        }
        for t in 0..plan.tiles.len() {
            let s = t % 2;
            let run = flight[s].take().expect("a tile in flight");
            let mut ran = run.caps;
            let mut got = self.finish_tile(&slots[s], run, plan.k)?;
            let tile = &plan.tiles[t];
            loop {
                let (records, candidates) = (got.open, got.found.candidates as usize);
                if records <= ran.records && candidates <= ran.candidates {
                    break;
                }
                // Past its room: the tile again with room for all (the records are at most
                // the candidates), or past a binding through the twin.
                if candidates > max {
                    got = Found::whole(twin_tile(self, tri, plan, tile)?, record);
                    break;
                }
                ran = Caps {
                    records: if candidates > ran.candidates {
                        candidates
                    } else {
                        records.max(ran.records)
                    },
                    candidates: candidates.max(ran.candidates),
                };
                let again = self.submit_tile(&mut slots[s], pipes, plan, t, ran)?;
                got = self.finish_tile(&slots[s], again, plan.k)?;
            }
            let cubes = tile.cubes().max(1) as f64;
            density = (got.open as f64 / cubes, got.found.candidates as f64 / cubes);
            if let Some(next) = plan.tiles.get(t + 2) {
                let room = caps(next, density);
                flight[s] = Some(self.submit_tile(&mut slots[s], pipes, plan, t + 2, room)?);
            }
            if !each(t, got.found)? {
                break;
            }
        }
        Ok(())
    }

    /// Uploads the map the tiles share (A, b, the boxes of scanned bases and of evaluated
    /// vertices).
    fn upload_map(&self, tri: &Triangulation, plan: &TilePlan) -> Result<()> {
        let (a, b) = tri.affine_map();
        let mut map: Vec<f64> = a.into_iter().chain(b).collect();
        // Already padded (`TilePlan`): rounding to f32 moves them by less than the pad.
        for b in [&plan.near, &plan.far] {
            map.extend(b.iter().map(|r| r[0]));
            map.extend(b.iter().map(|r| r[1]));
        }
        let bytes = self.encode_reals(&map);
        let buffer = self.gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("isomesh tile map"),
            size: (bytes.len() as u64).next_multiple_of(4),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        self.gpu.queue.write_buffer(&buffer, 0, &bytes);
        self.upload_bytes
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        *self
            .tile_map
            .lock()
            .map_err(|_| Error::Gpu("a previous GPU call panicked".into()))? = Some(buffer);
        Ok(())
    }

    /// Buffers of `slot` large enough for `tile` with room `caps`.
    fn slot_buffers<'s>(
        &self,
        slot: &'s mut Slot,
        plan: &TilePlan,
        tile: &Tile,
        caps: Caps,
    ) -> &'s Buffers {
        let n = tile.vertices() as u64;
        let rs = self.real_size() as u64;
        let want = [
            n * plan.k as u64 * 2 * rs,
            n * 4,
            (caps.candidates * (plan.k + 1) * 4) as u64,
            (caps.records * (plan.k + 2) * 4) as u64,
        ];
        let had = |b: &Buffers| {
            [
                b.values.size(),
                b.codes.size(),
                b.cands.size(),
                b.out.size(),
            ]
        };
        let old = slot.buffers.as_ref().map(had);
        if old.is_some_and(|h| h.iter().zip(&want).all(|(h, w)| h >= w)) {
            return slot.buffers.as_ref().expect("checked");
        }
        let size = |i: usize| want[i].max(old.map_or(0, |h| h[i])).max(16);
        let dev = &self.gpu.device;
        let make = |size: u64, usage: wgpu::BufferUsages| {
            dev.create_buffer(&wgpu::BufferDescriptor {
                label: Some("isomesh tile"),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let storage = wgpu::BufferUsages::STORAGE;
        let dst = wgpu::BufferUsages::COPY_DST;
        let src = wgpu::BufferUsages::COPY_SRC;
        let uniform = wgpu::BufferUsages::UNIFORM | dst;
        slot.buffers = Some(Buffers {
            tile: make((8 * plan.d as u64 + 16).next_multiple_of(16), storage | dst),
            params: [make(16, uniform), make(16, uniform), make(16, uniform)],
            values: make(size(0), storage),
            codes: make(size(1), storage),
            counters: make(COUNTERS, storage | dst | src),
            cands: make(size(2), storage),
            out: make(size(3), storage | src),
            staging: make(COUNTERS + size(3), wgpu::BufferUsages::MAP_READ | dst),
        });
        slot.buffers.as_ref().expect("made above")
    }

    /// Starts tile `t` on the device with room `caps`: the three stages, then the counters
    /// and the records copied back.
    fn submit_tile(
        &self,
        slot: &mut Slot,
        pipes: Pipes<'_>,
        plan: &TilePlan,
        t: usize,
        caps: Caps,
    ) -> Result<InFlight> {
        let started = Instant::now();
        let tile = &plan.tiles[t];
        let bufs = self.slot_buffers(slot, plan, tile, caps);
        let map = self
            .tile_map
            .lock()
            .map_err(|_| Error::Gpu("a previous GPU call panicked".into()))?
            .clone()
            .ok_or_else(|| Error::Gpu("the tile map was not uploaded".into()))?;
        let mut desc: Vec<u32> = tile.origin.iter().map(|&o| o as u32).collect();
        desc.extend_from_slice(&tile.counts);
        desc.extend([caps.records as u32, caps.candidates as u32]);
        let q = &self.gpu.queue;
        q.write_buffer(&bufs.tile, 0, bytemuck::cast_slice(&desc));
        let counts = [tile.vertices(), tile.cubes(), caps.candidates];
        let mut groups = [(0u32, 0u32); 3];
        for (i, &count) in counts.iter().enumerate() {
            let g = (count as u32).div_ceil(WORKGROUP).max(1);
            groups[i] = if g > MAX_GROUPS {
                (MAX_GROUPS, g.div_ceil(MAX_GROUPS))
            } else {
                (g, 1)
            };
            let params: [u32; 4] = [count as u32, groups[i].0 * WORKGROUP, 0, 0];
            q.write_buffer(&bufs.params[i], 0, bytemuck::cast_slice(&params));
        }
        self.upload_bytes
            .fetch_add(4 * desc.len() as u64 + 48, Ordering::Relaxed);
        let dev = &self.gpu.device;
        let bind = |p: &wgpu::ComputePipeline, res: &[&wgpu::Buffer]| {
            let entries: Vec<wgpu::BindGroupEntry> = res
                .iter()
                .enumerate()
                .map(|(i, b)| wgpu::BindGroupEntry {
                    binding: i as u32,
                    resource: b.as_entire_binding(),
                })
                .collect();
            dev.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout: &p.get_bind_group_layout(0),
                entries: &entries,
            })
        };
        let b = bufs;
        let binds = [
            bind(
                pipes[0],
                &[
                    &map,
                    &b.tile,
                    &b.values,
                    &b.codes,
                    &b.counters,
                    &b.params[0],
                ],
            ),
            bind(
                pipes[1],
                &[&b.tile, &b.codes, &b.counters, &b.cands, &b.params[1]],
            ),
            bind(
                pipes[2],
                &[
                    &b.tile,
                    &b.values,
                    &b.codes,
                    &b.counters,
                    &b.cands,
                    &b.out,
                    &b.params[2],
                ],
            ),
        ];
        let mut enc = dev.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: None });
        enc.clear_buffer(&b.counters, 0, None);
        for i in 0..3 {
            let mut pass = enc.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: None,
                timestamp_writes: None,
            });
            pass.set_pipeline(pipes[i]);
            pass.set_bind_group(0, &binds[i], &[]);
            pass.dispatch_workgroups(groups[i].0, groups[i].1, 1);
        }
        let out_bytes = (caps.records * (plan.k + 2) * 4) as u64;
        enc.copy_buffer_to_buffer(&b.counters, 0, &b.staging, 0, COUNTERS);
        if out_bytes > 0 {
            enc.copy_buffer_to_buffer(&b.out, 0, &b.staging, COUNTERS, out_bytes);
        }
        let index = q.submit([enc.finish()]);
        let size = COUNTERS + out_bytes;
        self.readback_bytes.fetch_add(size, Ordering::Relaxed);
        let (tx, rx) = std::sync::mpsc::channel();
        b.staging
            .slice(..size)
            .map_async(wgpu::MapMode::Read, move |r| {
                let _ = tx.send(r);
            });
        add_time(&self.gpu_ns, started);
        Ok(InFlight {
            caps,
            index,
            mapped: rx,
            size,
        })
    }

    /// Waits for a tile and reads its counters and records.
    fn finish_tile(&self, slot: &Slot, run: InFlight, k: usize) -> Result<Found> {
        let started = Instant::now();
        self.wait(Some(run.index))?;
        run.mapped
            .recv()
            .map_err(|_| Error::Gpu("the readback was dropped".into()))?
            .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
        add_time(&self.gpu_ns, started);
        let decoding = Instant::now();
        let staging = &slot.buffers.as_ref().expect("submitted").staging;
        let found = {
            let view = staging
                .slice(..run.size)
                .get_mapped_range()
                .map_err(|e| Error::Gpu(format!("readback: {e}")))?;
            let counters: [u32; 4] = bytemuck::pod_read_unaligned(&view[..COUNTERS as usize]);
            let open = counters[0] as usize;
            let kept = open.min(run.caps.records) * (k + 2) * 4;
            let at = COUNTERS as usize;
            Found {
                found: TileFound {
                    records: bytemuck::pod_collect_to_vec(&view[at..at + kept]),
                    candidates: counters[1] as u64,
                    unknown: counters[2] as u64,
                    evaluated: counters[3] as u64,
                },
                open,
            }
        };
        staging.unmap();
        add_time(&self.host_ns, decoding);
        Ok(found)
    }
}

/// A tile's readback, with the number of records the device counted (more than it holds
/// when they overflowed their room).
struct Found {
    found: TileFound,
    open: usize,
}

impl Found {
    fn whole(found: TileFound, record: usize) -> Self {
        let open = found.records.len() / record;
        Found { found, open }
    }
}
