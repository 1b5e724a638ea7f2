//! The report of a run: what was traced, how, what it cost and, with the cell complex, its
//! topology. One typed struct, serialised to JSON by `isomesh trace --report` and returned by
//! [`Manifold::report`](crate::Manifold::report), so the keys are the same everywhere; each
//! field's documentation is the key's meaning.

use serde::Serialize;

use crate::complex::topology::Offender;
use crate::complex::{Complex, Topology};
use crate::trace::{LevelSteps, Sample};

/// What an adapter is, for reports and `isomesh info`.
#[derive(Clone, Debug, Serialize)]
pub struct AdapterSummary {
    /// The adapter's name.
    pub name: String,
    /// The graphics API wgpu drives it through (Vulkan, Metal, Dx12, Gl).
    pub backend: String,
    /// DiscreteGpu, IntegratedGpu, VirtualGpu, Cpu (software) or Other.
    pub device_type: String,
    /// The driver and its version.
    pub driver: String,
    /// Whether shaders can use f64 (SHADER_F64).
    pub shader_f64: bool,
    /// Largest storage buffer binding, bytes.
    pub max_storage_binding: u64,
}

impl AdapterSummary {
    /// Whether it is a software rasterizer (lavapipe, llvmpipe, WARP): slower than the CPU
    /// path, so `--backend auto` skips it.
    pub fn is_software(&self) -> bool {
        self.device_type == "Cpu"
    }
}

/// Which oracle decided, as the report names it.
#[derive(Clone, Debug, Serialize)]
pub struct BackendInfo {
    /// `"cpu"`, or `"gpu: <adapter>"`.
    pub backend: String,
    /// Shader precision (`"f64"` on the CPU).
    pub precision: String,
    /// GPU: the share of solved simplices decided again on the CPU.
    pub recheck_share: Option<f64>,
    /// GPU: seconds in device round trips, summed over the threads that made them.
    pub gpu_s: Option<f64>,
    /// GPU: seconds of host work per item inside the GPU oracle (packing, decoding,
    /// re-deciding on the CPU), summed over threads ([`crate::gpu::GpuStats::host_s`]).
    pub host_s: Option<f64>,
    /// GPU: bytes written to the device.
    pub upload_bytes: Option<u64>,
    /// GPU: bytes copied back from the device.
    pub readback_bytes: Option<u64>,
    /// GPU: the adapter.
    pub adapter: Option<AdapterSummary>,
}

impl BackendInfo {
    /// The CPU oracle.
    pub fn cpu() -> Self {
        BackendInfo {
            backend: "cpu".into(),
            precision: "f64".into(),
            recheck_share: None,
            gpu_s: None,
            host_s: None,
            upload_bytes: None,
            readback_bytes: None,
            adapter: None,
        }
    }
}

/// ```
/// let circle = isomesh::Mesher::preset("circle", &[])?.trace()?;
/// let r = circle.report();
/// assert!(r.complete);
/// let json: serde_json::Value = serde_json::from_str(&r.to_json()).unwrap();
/// assert_eq!(json["simplex_count"].as_u64(), Some(circle.len() as u64));
/// assert_eq!(json["manifold_dim"], 1);
/// # Ok::<(), isomesh::Error>(())
/// ```
///
/// The JSON report of a trace or an exhaustive scan (`--report`).
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// The problem's name (preset name or spec file stem).
    pub name: String,
    /// `"trace"` or `"exhaustive"`.
    pub mode: String,
    /// d.
    pub ambient_dim: usize,
    /// k, the number of equations.
    pub codim: usize,
    /// m = d - k.
    pub manifold_dim: usize,
    /// `"coxeter"`, `"freudenthal"` or `"custom"`.
    pub triangulation: String,
    /// Longest edge of a d-simplex.
    pub edge: f64,
    /// The triangulation's offset b.
    pub offset: Vec<f64>,
    /// The box [lo, hi] per axis, if any.
    #[serde(rename = "box")]
    pub bbox: Option<Vec<[f64; 2]>>,
    /// Crossed k-simplices in S (one point of M each).
    pub simplex_count: usize,
    /// Connected components: the complex's when it was built, else the trace's.
    pub components: usize,
    /// Which oracle decided.
    #[serde(flatten)]
    pub backend: BackendInfo,
    /// Worker threads.
    pub threads: usize,
    /// Tracing wall time, seconds.
    pub elapsed_s: f64,
    /// `simplex_count / elapsed_s`.
    pub simplices_per_s: f64,
    /// Heap high-water mark of the run, bytes (0 without the counting allocator): the whole
    /// run from the command line (parsing to export), the trace from the library.
    pub peak_memory_bytes: u64,
    /// The memory limit, bytes.
    pub max_memory_bytes: u64,
    /// `peak_memory_bytes / simplex_count`.
    pub bytes_per_simplex: f64,
    /// Breadth-first levels.
    pub levels: u64,
    /// Where the levels' wall time went, seconds (zero for a scan).
    pub level_steps_s: LevelSteps,
    /// Most simplices one level found.
    pub widest_level: u64,
    /// k-simplices sent to the oracle.
    pub oracle_calls: u64,
    /// Decisions taken by the exact rational path.
    pub exact_decisions: u64,
    /// Cofacets whose pivot could not run or named a facet the oracle rejected.
    pub pivot_fallbacks: u64,
    /// Candidates with a singular labelling matrix.
    pub degenerate: u64,
    /// Candidates with a non-finite vertex value.
    pub non_finite: u64,
    /// Lattice vertices where f was evaluated.
    pub vertices_evaluated: u64,
    /// Of the lattice vertices, those where a device evaluated f with a bound.
    pub device_vertex_evaluations: u64,
    /// Lattice vertices where the CPU evaluated f (a scan with device values: only where
    /// the device could not decide, or found a crossing whose point the CPU computes).
    pub cpu_vertex_evaluations: u64,
    /// Decisions a device took with a certificate and the CPU did not redo.
    pub device_decisions: u64,
    /// Decisions made or redone on the CPU.
    pub cpu_decisions: u64,
    /// Projected box samples used as seeds.
    pub seed_points: u64,
    /// Crossings where f looks like it has a pole or a jump (see
    /// [`Sample::suspect_crossings`]).
    pub suspect_crossings: usize,
    /// Seeds (from 1) where the Jacobian of f is rank-deficient: the trace follows at most
    /// one branch from each.
    pub singular_seeds: Vec<usize>,
    /// Crossings of a trace near a point where the Jacobian of f is rank-deficient (see
    /// [`Sample::check_crossings`]; empty for a scan): branches of M may cross there, and
    /// a trace follows only those it reaches.
    pub singular_crossings: Vec<Vec<f64>>,
    /// False when the run stopped early (Ctrl-C, memory limit, no box for an unbounded M),
    /// found nothing, or a later phase failed.
    pub complete: bool,
    /// Why it stopped early.
    pub stopped: Option<String>,
    /// The signal that stopped the run (SIGINT, SIGTERM, SIGHUP), if one did.
    pub signal: Option<String>,
    /// What failed after tracing (the complex or a file), or why nothing was found.
    pub error: Option<String>,
    /// Requested files that were not written.
    pub not_written: Vec<String>,
    /// The cell complex's figures, when it was built.
    #[serde(flatten)]
    pub complex: Option<ComplexReport>,
}

/// The report's cell-complex keys.
#[derive(Clone, Debug, Serialize)]
pub struct ComplexReport {
    /// Cells per dimension 0..=m.
    pub cells: Vec<usize>,
    /// Alternating sum of `cells`.
    pub euler_characteristic: i64,
    /// Every (m-1)-cell has 2 m-cells around it (1 on the boundary), no edge left out.
    pub manifold: bool,
    /// No boundary cell.
    pub closed: bool,
    /// Boundary cells per dimension 0..m.
    pub boundary_cells: Vec<usize>,
    /// Euler characteristic of the boundary.
    pub boundary_euler_characteristic: i64,
    /// m = 2: whether the polygons orient consistently (null otherwise).
    pub orientable: Option<bool>,
    /// b_0..b_m over Z/2 (m <= 3 and a manifold, else null).
    pub betti_mod2: Option<Vec<usize>>,
    /// Components without boundary.
    pub closed_components: usize,
    /// (m-1)-cells without the right number of m-cells.
    pub offender_count: usize,
    /// The first of them.
    pub offenders: Vec<Offender>,
    /// Edges left out while building.
    pub defects: usize,
    /// Construction time, seconds.
    pub complex_s: f64,
    /// Topology analysis time, seconds.
    pub topology_s: f64,
    /// How R^d was seen in 3-D (`--project`).
    pub projection: String,
}

impl ComplexReport {
    /// The keys of `complex` and its topology `t` (analysed in `topology_s` seconds).
    pub fn new(complex: &Complex, t: &Topology, topology_s: f64, projection: &str) -> Self {
        ComplexReport {
            cells: t.cells.clone(),
            euler_characteristic: t.euler_characteristic,
            manifold: t.manifold,
            closed: t.closed,
            boundary_cells: t.boundary_cells.clone(),
            boundary_euler_characteristic: t.boundary_euler_characteristic,
            orientable: t.orientable,
            betti_mod2: t.betti_mod2.clone(),
            closed_components: t.closed_components,
            offender_count: t.offender_count,
            offenders: t.offenders.clone(),
            defects: t.defects,
            complex_s: complex.stats.elapsed_s,
            topology_s,
            projection: projection.to_string(),
        }
    }
}

/// What a report says of a run besides its sample.
#[derive(Clone, Debug)]
pub(crate) struct RunInfo {
    /// The problem's name.
    pub name: String,
    /// Whether it was an exhaustive scan.
    pub exhaustive: bool,
    /// The box, if any.
    pub bbox: Option<Vec<[f64; 2]>>,
    /// Which oracle decided.
    pub backend: BackendInfo,
    /// Worker threads.
    pub threads: usize,
    /// Heap high-water mark of the run, bytes.
    pub peak_memory_bytes: u64,
    /// The memory limit, bytes.
    pub max_memory_bytes: u64,
    /// [`Sample::suspect_crossings`].
    pub suspect_crossings: usize,
    /// Seeds (from 1) at a singular point of f.
    pub singular_seeds: Vec<usize>,
    /// [`crate::trace::CrossingChecks::singular`] of a trace.
    pub singular_crossings: Vec<Vec<f64>>,
}

impl Report {
    /// The report of `sample`, without the complex's keys.
    pub(crate) fn new(sample: &Sample, run: RunInfo) -> Self {
        let st = &sample.stats;
        let tri = sample.triangulation();
        let (d, k) = (sample.ambient_dim(), sample.codim());
        let n = sample.len();
        let per = |x: f64, y: f64| if y > 0.0 { x / y } else { 0.0 };
        Report {
            name: run.name,
            mode: if run.exhaustive {
                "exhaustive"
            } else {
                "trace"
            }
            .into(),
            ambient_dim: d,
            codim: k,
            manifold_dim: d - k,
            triangulation: tri.kind().name().into(),
            edge: tri.edge(),
            offset: tri.offset().to_vec(),
            bbox: run.bbox,
            simplex_count: n,
            components: st.components,
            backend: run.backend,
            threads: run.threads,
            elapsed_s: st.elapsed_s,
            simplices_per_s: per(n as f64, st.elapsed_s),
            peak_memory_bytes: run.peak_memory_bytes,
            max_memory_bytes: run.max_memory_bytes,
            bytes_per_simplex: per(run.peak_memory_bytes as f64, n as f64),
            levels: st.levels,
            level_steps_s: st.steps,
            widest_level: st.widest_level,
            oracle_calls: st.oracle_calls,
            exact_decisions: st.exact_decisions,
            pivot_fallbacks: st.pivot_fallbacks,
            degenerate: st.degenerate,
            non_finite: st.non_finite,
            vertices_evaluated: st.vertices,
            device_vertex_evaluations: st.device_vertex_evaluations,
            cpu_vertex_evaluations: st.cpu_vertex_evaluations,
            device_decisions: st.device_decisions,
            cpu_decisions: st.cpu_decisions,
            seed_points: st.seed_points,
            suspect_crossings: run.suspect_crossings,
            singular_seeds: run.singular_seeds,
            singular_crossings: run.singular_crossings,
            complete: st.stopped.is_none(),
            stopped: st.stopped.as_ref().map(ToString::to_string),
            signal: None,
            error: None,
            not_written: Vec::new(),
            complex: None,
        }
    }

    /// Adds the complex's keys; `components` becomes the complex's count.
    pub fn with_complex(mut self, c: ComplexReport, components: usize) -> Self {
        self.components = components;
        self.complex = Some(c);
        self
    }

    /// The report as pretty JSON.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("a report always serialises")
    }
}
