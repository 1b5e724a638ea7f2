//! The entry point for embedders: a [`Mesher`] owns f, the triangulation, the domain and the
//! backend, and its [`trace`](Mesher::trace) or [`scan`](Mesher::scan) returns a [`Manifold`]
//! that carries all of them, so that its complex, topology, report and files need no argument
//! given twice.
//!
//! ```
//! use isomesh::Mesher;
//!
//! let torus = Mesher::preset("torus", &[])?.edge(0.1).trace()?;
//! let topology = torus.topology()?;
//! assert_eq!(topology.euler_characteristic, 0);
//! assert_eq!(topology.betti_mod2, Some(vec![1, 2, 1]));
//! # Ok::<(), isomesh::Error>(())
//! ```
//!
//! The layers below ([`trace::trace`], [`Complex`],
//! [`export`](crate::export)) stay public for callers who need them.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use crate::complex::{Complex, Topology};
use crate::error::{Error, Result};
use crate::export::mesh::{write_mesh_as, Encoding, Mesh};
use crate::export::picture::Picture;
use crate::export::{write_sample, OutputFormat, Projection};
use crate::expr::{preset, ImplicitFunction, Problem, Spec, TriangulationSpec};
use crate::memory;
use crate::report::{BackendInfo, ComplexReport, Report, RunInfo};
use crate::trace::{self, checks, CpuOracle, Oracle, Progress, Sample, TraceOptions};
use crate::triangulation::{Triangulation, TriangulationKind};

/// Which oracle decides the intersection tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// f64 on the CPU: the reference.
    #[default]
    Cpu,
    /// The GPU oracle on any adapter, software ones included (needs the `gpu` feature and f
    /// in the equation language).
    Gpu,
    /// A hardware GPU when there is one and f is in the equation language, else the CPU.
    Auto,
}

impl std::str::FromStr for Backend {
    type Err = Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "cpu" => Ok(Backend::Cpu),
            "gpu" => Ok(Backend::Gpu),
            "auto" => Ok(Backend::Auto),
            other => Err(Error::Spec(format!(
                "unknown backend '{other}': expected cpu, gpu or auto"
            ))),
        }
    }
}

/// Called after every trace level.
pub type ProgressFn = dyn Fn(&Progress) + Send + Sync;

/// A problem ready to mesh: f (equations or any [`ImplicitFunction`]), the triangulation,
/// the domain (box and f's boundary inequalities), seeds, the backend and the limits. Set it
/// up with the builder methods, then [`trace`](Self::trace) or [`scan`](Self::scan).
#[derive(Clone)]
pub struct Mesher {
    name: String,
    function: Arc<dyn ImplicitFunction>,
    triangulation: TriangulationSpec,
    bbox: Option<Vec<[f64; 2]>>,
    seeds: Vec<Vec<f64>>,
    search: Option<usize>,
    search_seed: u64,
    backend: Backend,
    #[cfg(feature = "gpu")]
    precision: Option<crate::gpu::Precision>,
    #[cfg(feature = "gpu")]
    device_values: bool,
    threads: Option<usize>,
    max_memory: u64,
    cancel: Option<Arc<AtomicBool>>,
    progress: Option<Arc<ProgressFn>>,
    warm: bool,
    key_box: Option<Vec<[f64; 2]>>,
}

impl std::fmt::Debug for Mesher {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Mesher")
            .field("name", &self.name)
            .field("ambient_dim", &self.function.ambient_dim())
            .field("codim", &self.function.codim())
            .field("triangulation", &self.triangulation)
            .field("bbox", &self.bbox)
            .field("seeds", &self.seeds)
            .field("backend", &self.backend)
            .finish_non_exhaustive()
    }
}

impl Mesher {
    /// A resolved spec or preset (see [`Spec::resolve`] and [`preset`]).
    pub fn from_problem(p: Problem) -> Self {
        let mut m = Self::with_function(Arc::new(p.system), &p.name);
        m.triangulation = p.triangulation;
        m.bbox = p.bbox;
        m.seeds = p.seeds;
        m
    }

    /// The built-in manifold `name` with parameter overrides (`isomesh presets` lists them).
    ///
    /// ```
    /// let m = isomesh::Mesher::preset("sphere", &[("r".into(), 2.0)])?;
    /// assert_eq!(m.ambient_dim(), 3);
    /// # Ok::<(), isomesh::Error>(())
    /// ```
    pub fn preset(name: &str, params: &[(String, f64)]) -> Result<Self> {
        preset(name, params).map(Self::from_problem)
    }

    /// A spec as read from TOML (see [`Spec`]), named `name`.
    pub fn from_spec(spec: &Spec, name: &str) -> Result<Self> {
        spec.resolve(name).map(Self::from_problem)
    }

    /// A spec in TOML text, the format of `isomesh trace SPEC.toml`.
    ///
    /// ```
    /// let m = isomesh::Mesher::from_toml(
    ///     "equations = [\"x^2 + y^2 - 1\"]\nvariables = [\"x\", \"y\"]\nseeds = [[1, 0]]",
    ///     "circle",
    /// )?;
    /// assert_eq!(m.trace()?.topology()?.betti_mod2, Some(vec![1, 1]));
    /// # Ok::<(), isomesh::Error>(())
    /// ```
    pub fn from_toml(text: &str, name: &str) -> Result<Self> {
        Self::from_spec(&Spec::from_toml(text)?, name)
    }

    /// A spec file; the problem is named after the file's stem.
    pub fn from_file(path: &Path) -> Result<Self> {
        let stem = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_default();
        Self::from_spec(&Spec::from_file(path)?, &stem)
    }

    /// Any f, for example a [`ClosureFunction`](crate::expr::ClosureFunction) (the CPU backend
    /// only: the GPU needs the equation language). Give seeds or a box before tracing.
    pub fn from_function(f: Arc<dyn ImplicitFunction>) -> Self {
        Self::with_function(f, "function")
    }

    fn with_function(f: Arc<dyn ImplicitFunction>, name: &str) -> Self {
        Mesher {
            name: name.to_string(),
            function: f,
            triangulation: TriangulationSpec::default(),
            bbox: None,
            seeds: Vec::new(),
            search: None,
            search_seed: 1,
            backend: Backend::Cpu,
            #[cfg(feature = "gpu")]
            precision: None,
            #[cfg(feature = "gpu")]
            device_values: false,
            threads: None,
            max_memory: memory::default_limit(),
            cancel: None,
            progress: None,
            warm: false,
            key_box: None,
        }
    }

    /// Renames the problem (reports and file headers carry the name).
    pub fn name(mut self, name: &str) -> Self {
        self.name = name.to_string();
        self
    }

    /// The longest edge of a d-simplex of the triangulation.
    pub fn edge(mut self, edge: f64) -> Self {
        self.triangulation.edge = Some(edge);
        self
    }

    /// Coxeter (the default) or Freudenthal-Kuhn.
    pub fn triangulation(mut self, kind: TriangulationKind) -> Self {
        self.triangulation.kind = Some(kind.name().to_string());
        self
    }

    /// The seed of the triangulation's random offset.
    pub fn offset_seed(mut self, seed: u64) -> Self {
        self.triangulation.offset_seed = Some(seed);
        self.triangulation.offset = None;
        self
    }

    /// The seed of the lattice's random rotation, or `None` for an unrotated lattice.
    pub fn rotation_seed(mut self, seed: Option<u64>) -> Self {
        self.triangulation.rotation_seed = seed;
        self.triangulation.rotate = Some(seed.is_some());
        self
    }

    /// The box [lo, hi] per axis: the domain, with f's boundary inequalities.
    pub fn bbox(mut self, bbox: Vec<[f64; 2]>) -> Self {
        self.bbox = Some(bbox);
        self
    }

    /// Points near M to trace from (they replace any seeds of the spec).
    pub fn seeds(mut self, seeds: Vec<Vec<f64>>) -> Self {
        self.seeds = seeds;
        self
    }

    /// Random box points projected onto M to find components (default: 512 when no seed is
    /// given, else none).
    pub fn search(mut self, samples: usize) -> Self {
        self.search = Some(samples);
        self
    }

    /// The seed of the box search's sampling.
    pub fn search_seed(mut self, seed: u64) -> Self {
        self.search_seed = seed;
        self
    }

    /// Which oracle decides (default: the CPU).
    pub fn backend(mut self, backend: Backend) -> Self {
        self.backend = backend;
        self
    }

    /// GPU shader precision (`None`: f64 where the adapter has it, else f32).
    #[cfg(feature = "gpu")]
    pub fn precision(mut self, precision: Option<crate::gpu::Precision>) -> Self {
        self.precision = precision;
        self
    }

    /// GPU backend: the exhaustive scan evaluates f on the device with certified bounds and
    /// the CPU only where the device cannot decide
    /// ([`GpuOracle::set_device_values`](crate::gpu::GpuOracle::set_device_values)); the
    /// result is the same. Off by default.
    #[cfg(feature = "gpu")]
    pub fn device_values(mut self, on: bool) -> Self {
        self.device_values = on;
        self
    }

    /// Worker threads, in a pool of the mesher's own (default: rayon's current pool); more
    /// than [`max_threads`] run [`max_threads`].
    pub fn threads(mut self, threads: usize) -> Self {
        self.threads = Some(threads);
        self
    }

    /// Stop (keeping what was found) before the trace, or refuse a complex, that would pass
    /// this many heap bytes (default: 3/4 of RAM).
    pub fn max_memory(mut self, bytes: u64) -> Self {
        self.max_memory = bytes;
        self
    }

    /// A flag that stops the run cleanly when set (what was found is kept, and the result
    /// says it is not complete).
    pub fn cancel(mut self, flag: Arc<AtomicBool>) -> Self {
        self.cancel = Some(flag);
        self
    }

    /// Called after every trace level.
    pub fn progress(mut self, f: Arc<ProgressFn>) -> Self {
        self.progress = Some(f);
        self
    }

    /// Keep the pool's other threads polling for work while a trace runs, so that small levels
    /// use every core (the command line does; it burns those cores while the trace runs).
    pub fn warm(mut self, warm: bool) -> Self {
        self.warm = warm;
        self
    }

    /// Size keys for this box instead of the run's box: scans of parts of one box that give
    /// it the whole box name every simplex alike (see [`crate::shard`]).
    pub fn key_box(mut self, bbox: Vec<[f64; 2]>) -> Self {
        self.key_box = Some(bbox);
        self
    }

    /// The box of a run, if one was given.
    pub fn domain_box(&self) -> Option<&[[f64; 2]]> {
        self.bbox.as_deref()
    }

    /// The memory limit of a run, bytes.
    pub fn memory_limit(&self) -> u64 {
        self.max_memory
    }

    /// The same settings with f replaced by `g`, which must take and give as many numbers
    /// (another wrapper of the same function, for one run of it).
    pub fn replace_function(mut self, g: Arc<dyn ImplicitFunction>) -> Result<Self> {
        let (d, k) = (self.ambient_dim(), self.codim());
        if (g.ambient_dim(), g.codim()) != (d, k) {
            return Err(Error::DimensionMismatch(format!(
                "the function maps R^{} to R^{}, the mesher's R^{d} to R^{k}",
                g.ambient_dim(),
                g.codim()
            )));
        }
        self.function = g;
        Ok(self)
    }

    /// f, shared.
    pub fn shared_function(&self) -> Arc<dyn ImplicitFunction> {
        self.function.clone()
    }

    /// d.
    pub fn ambient_dim(&self) -> usize {
        self.function.ambient_dim()
    }

    /// k, the number of equations.
    pub fn codim(&self) -> usize {
        self.function.codim()
    }

    /// f.
    pub fn function(&self) -> &dyn ImplicitFunction {
        &*self.function
    }

    /// The triangulation these settings give.
    pub fn build_triangulation(&self) -> Result<Triangulation> {
        self.triangulation.build(self.ambient_dim())
    }

    /// Traces M from the seeds (and a box search where asked or where there is no seed).
    /// An early stop (cancel flag, memory limit) returns what was found, marked incomplete;
    /// a run that finds no crossed simplex is an [`Error::Trace`] saying why.
    pub fn trace(&self) -> Result<Manifold> {
        self.run(false)
    }

    /// Scans every k-simplex in the box (no seed needed; every component is found). As with
    /// [`Mesher::trace`], finding nothing is an error.
    pub fn scan(&self) -> Result<Manifold> {
        self.run(true)
    }

    /// [`Mesher::scan`] of a shard's box, where finding nothing is a result.
    pub(crate) fn scan_part(&self) -> Result<Manifold> {
        self.run_any(true)
    }

    fn run(&self, exhaustive: bool) -> Result<Manifold> {
        let m = self.run_any(exhaustive)?;
        if let Some((i, x)) = &m.sample.stats.zero_region {
            return Err(checks::region_error(*i, x));
        }
        // Nothing found, and not for want of time or memory: an error, as on the command
        // line, rather than an empty manifold that looks like a result.
        if m.is_empty() && m.complete() {
            return Err(Error::Trace(
                m.sample
                    .stats
                    .why_nothing_found(exhaustive, !self.seeds.is_empty()),
            ));
        }
        Ok(m)
    }

    /// A trace or scan, whatever it finds.
    fn run_any(&self, exhaustive: bool) -> Result<Manifold> {
        if let Some(0) = self.threads {
            return Err(Error::Spec("threads must be at least 1".into()));
        }
        match self.threads.map(|n| n.min(max_threads())) {
            Some(n) => rayon::ThreadPoolBuilder::new()
                .num_threads(n)
                .build()
                .map_err(|e| Error::Spec(format!("cannot start {n} threads: {e}")))?
                .install(|| self.run_in_pool(exhaustive)),
            None => self.run_in_pool(exhaustive),
        }
    }

    fn run_in_pool(&self, exhaustive: bool) -> Result<Manifold> {
        let tri = self.build_triangulation()?;
        let f = &*self.function;
        checks::check_not_zero(f, self.bbox.as_deref(), &self.seeds, tri.edge())?;
        let singular_seeds = if exhaustive {
            Vec::new()
        } else {
            checks::singular_seeds(f, &self.seeds, tri.edge())
                .into_iter()
                .map(|(i, _)| i)
                .collect()
        };
        let progress = self.progress.clone();
        let report_progress = move |p: &Progress| {
            if let Some(cb) = &progress {
                cb(p)
            }
        };
        let opts = TraceOptions {
            bbox: self.bbox.clone(),
            seeds: self.seeds.clone(),
            search_samples: self.search,
            search_seed: self.search_seed,
            max_memory: self.max_memory,
            cancel: self.cancel.clone(),
            progress: Some(&report_progress),
            warm: self.warm,
            key_box: self.key_box.clone(),
        };
        let cpu = CpuOracle::new(f);
        #[cfg(feature = "gpu")]
        let gpu = self.gpu_oracle()?;
        #[cfg(feature = "gpu")]
        let oracle: &dyn Oracle = match &gpu {
            Some(o) => o,
            None => &cpu,
        };
        #[cfg(not(feature = "gpu"))]
        let oracle: &dyn Oracle = {
            if self.backend == Backend::Gpu {
                return Err(Error::Gpu(
                    "this build of isomesh has no GPU backend (the `gpu` feature)".into(),
                ));
            }
            &cpu
        };
        memory::reset_peak();
        let base = memory::live_bytes();
        let sample = if exhaustive {
            trace::exhaustive(f, &tri, oracle, &opts)?
        } else {
            trace::trace(f, &tri, oracle, &opts)?
        };
        let peak = memory::peak_bytes().saturating_sub(base) as u64;
        let mut checks = sample.check_crossings(f);
        if exhaustive {
            // A scan finds every branch.
            checks.singular.clear();
        }
        #[cfg(feature = "gpu")]
        let backend = match &gpu {
            Some(o) => BackendInfo::of_gpu(o),
            None => BackendInfo::cpu(),
        };
        #[cfg(not(feature = "gpu"))]
        let backend = BackendInfo::cpu();
        let run = RunInfo {
            name: self.name.clone(),
            exhaustive,
            bbox: self.bbox.clone(),
            backend,
            threads: rayon::current_num_threads(),
            peak_memory_bytes: peak,
            max_memory_bytes: self.max_memory,
            suspect_crossings: checks.suspect,
            singular_seeds,
            singular_crossings: checks.singular,
        };
        Ok(Manifold {
            function: self.function.clone(),
            bbox: self.bbox.clone(),
            max_memory: self.max_memory,
            report: Report::new(&sample, run),
            sample,
            complex: OnceLock::new(),
        })
    }

    /// The GPU oracle the backend asks for, or `None` for the CPU.
    #[cfg(feature = "gpu")]
    fn gpu_oracle(&self) -> Result<Option<crate::gpu::GpuOracle<'_>>> {
        use crate::gpu::{Gpu, GpuOracle};
        let f = &*self.function;
        let gpu = match self.backend {
            Backend::Cpu => return Ok(None),
            Backend::Gpu => {
                if f.system().is_none() {
                    return Err(Error::Gpu(
                        "the GPU backend needs f in the equation language; a function given \
                         as code runs on the CPU backend"
                            .into(),
                    ));
                }
                Gpu::open(true)?
            }
            Backend::Auto => {
                if f.system().is_none() {
                    return Ok(None);
                }
                match Gpu::open(false) {
                    Ok(g) => g,
                    Err(_) => return Ok(None),
                }
            }
        };
        let o = GpuOracle::new(gpu, f, self.precision)?;
        o.set_device_values(self.device_values);
        Ok(Some(o))
    }
}

/// Most worker threads per core a run may ask for: the work is all on the CPU, so a thread
/// beyond the cores only takes turns with another (eight threads on two cores ran a trace
/// four times slower than one).
const MAX_THREADS_PER_CORE: usize = 1;
/// Most worker threads in all.
const MAX_THREADS: usize = 1024;

/// The most worker threads a run uses: 4 per core, at most 1024 (more only wait on one
/// another, and thousands take seconds to start).
pub fn max_threads() -> usize {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    (cores * MAX_THREADS_PER_CORE).min(MAX_THREADS)
}

/// What a warning says of a thread count above `cap` ([`max_threads`]).
pub fn too_many_threads(cap: usize) -> String {
    format!(
        "more than this machine can use: running {cap} (at most {MAX_THREADS_PER_CORE} per \
         core, and at most {MAX_THREADS}; more threads than cores only slow a run down)"
    )
}

/// M as a trace or scan found it: the sample S, and on demand its cell complex, topology,
/// report and files. It keeps f, the box and the memory limit it was found with, so none of
/// them is given again.
pub struct Manifold {
    function: Arc<dyn ImplicitFunction>,
    bbox: Option<Vec<[f64; 2]>>,
    max_memory: u64,
    sample: Sample,
    report: Report,
    complex: OnceLock<(Complex, Topology, f64)>,
}

/// How [`Manifold::write_with`] writes a file.
#[derive(Clone, Debug, Default)]
pub struct WriteOptions {
    /// The format by name (`csv`, `xyz`, `ply`, `obj`, `off`, `stl`, `mesh`, `vtu`, `npz`),
    /// overriding the file extension.
    pub format: Option<String>,
    /// How R^d is seen in 3-D: `auto` (the default), `pca`, or coordinates such as `1,2,4`.
    pub projection: Option<String>,
    /// PLY and VTU as text instead of binary (`--ascii`).
    pub ascii: bool,
}

impl Manifold {
    /// The sample: crossed k-simplices (keys) in a deterministic order.
    pub fn sample(&self) -> &Sample {
        &self.sample
    }

    /// How many crossed k-simplices (points of M) were found.
    pub fn len(&self) -> usize {
        self.sample.len()
    }

    /// Whether nothing was found.
    pub fn is_empty(&self) -> bool {
        self.sample.is_empty()
    }

    /// One point of M per crossed simplex, d coordinates each, in the sample's order.
    pub fn points(&self) -> Vec<f64> {
        self.sample.points()
    }

    /// False when the run stopped early (cancel flag, memory limit).
    pub fn complete(&self) -> bool {
        self.sample.stats.stopped.is_none()
    }

    /// f.
    pub fn function(&self) -> &dyn ImplicitFunction {
        &*self.function
    }

    /// The cell complex, built on first use (clipped by the box and f's boundary
    /// inequalities, within the memory limit).
    pub fn complex(&self) -> Result<&Complex> {
        self.built().map(|c| &c.0)
    }

    /// The complex's topology (counts, Euler characteristic, manifoldness, Betti numbers).
    pub fn topology(&self) -> Result<&Topology> {
        self.built().map(|c| &c.1)
    }

    fn built(&self) -> Result<&(Complex, Topology, f64)> {
        self.built_cancellable(&AtomicBool::new(false))
    }

    /// [`Manifold::complex`] that stops, with an error, once `cancel` is set (Ctrl-C).
    pub fn complex_cancellable(&self, cancel: &AtomicBool) -> Result<&Complex> {
        self.built_cancellable(cancel).map(|c| &c.0)
    }

    fn built_cancellable(&self, cancel: &AtomicBool) -> Result<&(Complex, Topology, f64)> {
        if let Some(c) = self.complex.get() {
            return Ok(c);
        }
        if self.sample.is_empty() {
            return Err(Error::Trace(
                "nothing was found: there is no complex to build".into(),
            ));
        }
        let interrupted = || Error::Trace("the cell complex was interrupted".into());
        let c = Complex::build_cancellable(
            &self.sample,
            &*self.function,
            self.bbox.as_deref(),
            self.max_memory,
            cancel,
        )
        .map_err(|e| {
            if cancel.load(Ordering::Relaxed) {
                interrupted()
            } else {
                e
            }
        })?;
        let t0 = Instant::now();
        let t = c.topology_cancellable(cancel).ok_or_else(interrupted)?;
        let secs = t0.elapsed().as_secs_f64();
        Ok(self.complex.get_or_init(|| (c, t, secs)))
    }

    /// The report, with the complex's keys once the complex is built: the keys of
    /// `isomesh trace --report`.
    pub fn report(&self) -> Report {
        match self.complex.get() {
            Some((c, t, secs)) => self
                .report
                .clone()
                .with_complex(ComplexReport::new(c, t, *secs, "auto"), t.components),
            None => self.report.clone(),
        }
    }

    /// Writes the sample (`.csv`, `.xyz`, `.txt`), its keys (`.keys`) or the mesh (`.ply`,
    /// `.obj`, `.off`, `.stl`, `.mesh`, `.vtu`, `.npz`), chosen by the extension; the mesh
    /// builds the complex.
    pub fn write(&self, path: impl AsRef<Path>) -> Result<()> {
        self.write_with(path, &WriteOptions::default())
    }

    /// [`write`](Self::write) with a format and a projection.
    pub fn write_with(&self, path: impl AsRef<Path>, opts: &WriteOptions) -> Result<()> {
        let path = path.as_ref();
        match OutputFormat::for_path(path, opts.format.as_deref())? {
            OutputFormat::Sample(format) => write_sample(path, &self.sample, format),
            OutputFormat::Mesh(_) => write_complex(
                self.complex()?,
                Some(self.function()),
                &self.report.name,
                path,
                opts,
            ),
        }
    }

    /// Draws the mesh into a PNG picture of `width` x `height` pixels.
    pub fn picture(&self, path: impl AsRef<Path>, width: usize, height: usize) -> Result<()> {
        let (c, t, _) = self.built()?;
        let f = Some(self.function());
        picture_complex(c, t, f, &self.report.name, path.as_ref(), width, height)
    }
}

/// Writes the cell complex `c` of f (orienting its cells, where given) as the mesh format
/// of `path`'s extension or `opts.format` (`.ply`, `.obj`, `.off`, `.stl`, `.mesh`, `.vtu`,
/// `.npz`); `name` goes in the file's header.
pub fn write_complex(
    c: &Complex,
    f: Option<&dyn ImplicitFunction>,
    name: &str,
    path: &Path,
    opts: &WriteOptions,
) -> Result<()> {
    let OutputFormat::Mesh(format) = OutputFormat::for_path(path, opts.format.as_deref())? else {
        return Err(Error::Output(format!(
            "{}: a cell complex is written as a mesh (.ply, .obj, .off, .stl, .mesh, .vtu, \
             .npz), not as points",
            path.display()
        )));
    };
    format.check_holds(c.dim(), path)?;
    let projection = Projection::parse(
        opts.projection.as_deref().unwrap_or("auto"),
        c.ambient_dim(),
    )?;
    let mesh = Mesh::new(c, f, &projection, name);
    let encoding = if opts.ascii {
        Encoding::Ascii
    } else {
        Encoding::Binary
    };
    write_mesh_as(path, &mesh, format, encoding)
}

/// Draws the cell complex `c` (with its topology `t`) into a PNG picture of `width` x
/// `height` pixels, captioned with `name`.
pub fn picture_complex(
    c: &Complex,
    t: &Topology,
    f: Option<&dyn ImplicitFunction>,
    name: &str,
    path: &Path,
    width: usize,
    height: usize,
) -> Result<()> {
    let projection = Projection::parse("auto", c.ambient_dim())?;
    let mesh = Mesh::new(c, f, &projection, name);
    let caption = format!(
        "{name}: {}-manifold in R^{}, chi = {}",
        t.dim,
        c.ambient_dim(),
        t.euler_characteristic
    );
    Picture::render(&mesh, width, height, &caption)?.write_png(path)
}

impl std::fmt::Debug for Manifold {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Manifold")
            .field("name", &self.report.name)
            .field("simplex_count", &self.sample.len())
            .field("complete", &self.complete())
            .finish_non_exhaustive()
    }
}
