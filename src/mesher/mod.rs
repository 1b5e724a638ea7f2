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
//! [`Mesher::run`] is the one driver: the command line, the Python package and the shards
//! all run through it, and a [`Manifold`] is the only maker of reports. The command line then
//! writes an [`OutputPlan`] with [`Manifold::deliver`] and reports with
//! [`Manifold::final_report`].
//!
//! The layers below ([`trace::trace`], [`Complex`](crate::complex::Complex),
//! [`export`](crate::export)) stay public for callers who need them.

mod manifold;
mod outputs;

use std::path::Path;
use std::sync::atomic::AtomicBool;
use std::sync::{Arc, OnceLock};

use crate::error::{Error, Result};
use crate::expr::{preset, ImplicitFunction, Problem, Spec, TriangulationSpec};
use crate::memory;
use crate::report::{BackendInfo, Report, RunInfo};
use crate::trace::{self, checks, CpuOracle, Oracle, Progress, TraceOptions};
use crate::triangulation::{Triangulation, TriangulationKind};

pub use manifold::{caption, picture_complex, write_complex, Manifold, Warning, WriteOptions};
pub use outputs::{Delivery, OutputPlan, PlannedOutput, Target};

/// What a run does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Job {
    /// Trace M from seeds (and from box points projected onto M).
    Trace,
    /// Scan every k-simplex in the box.
    Scan,
}

/// Which oracle decides the intersection tests.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Backend {
    /// f64 on the CPU: the reference.
    #[default]
    Cpu,
    /// The GPU oracle on any adapter, software ones included (needs the `gpu` feature and f
    /// in the equation language).
    Gpu,
    /// A hardware GPU where `isomesh bench` measured it faster than the CPU for the job
    /// ([`crate::gpu::calibration`]) and f is in the equation language, else the CPU.
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
    #[cfg(feature = "gpu")]
    level_slice: Option<usize>,
    #[cfg(feature = "gpu")]
    calibration: Option<std::path::PathBuf>,
    #[cfg(feature = "gpu")]
    auto_software: bool,
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
            #[cfg(feature = "gpu")]
            level_slice: None,
            #[cfg(feature = "gpu")]
            calibration: None,
            #[cfg(feature = "gpu")]
            auto_software: false,
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
    /// ([`GpuOptions::device_values`](crate::gpu::GpuOptions::device_values)); the
    /// result is the same. Off by default.
    #[cfg(feature = "gpu")]
    pub fn device_values(mut self, on: bool) -> Self {
        self.device_values = on;
        self
    }

    /// GPU backend: frontier simplices per slice of a trace level, `None` for whole levels
    /// ([`GpuOptions::level_slice`](crate::gpu::GpuOptions::level_slice)); the result
    /// is the same.
    #[cfg(feature = "gpu")]
    pub fn level_slice(mut self, simplices: Option<usize>) -> Self {
        self.level_slice = simplices;
        self
    }

    /// [`Backend::Auto`]: the calibration file that says where the GPU is faster (default:
    /// [`calibration::default_path`](crate::gpu::calibration::default_path), which
    /// `isomesh bench` writes).
    #[cfg(feature = "gpu")]
    pub fn calibration(mut self, path: Option<std::path::PathBuf>) -> Self {
        self.calibration = path;
        self
    }

    #[doc(hidden)] // a test hook: auto as on a hardware GPU, on a software adapter
    #[cfg(all(feature = "gpu", feature = "internals"))]
    pub fn auto_opens_software(mut self, on: bool) -> Self {
        self.auto_software = on;
        self
    }

    /// Worker threads, in a pool of the mesher's own that builds the complex too (default:
    /// rayon's current pool); more than [`max_threads`] run [`max_threads`], with a
    /// [`Warning::Threads`].
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

    /// How many seeds a trace starts from.
    pub fn seed_count(&self) -> usize {
        self.seeds.len()
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
    /// a run that finds no crossed simplex, or finds f vanishing on a region, is an error
    /// saying why ([`Manifold::failure`]).
    pub fn trace(&self) -> Result<Manifold> {
        self.run(Job::Trace).and_then(Manifold::found)
    }

    /// Scans every k-simplex in the box (no seed needed; every component is found). As with
    /// [`Mesher::trace`], finding nothing is an error.
    pub fn scan(&self) -> Result<Manifold> {
        self.run(Job::Scan).and_then(Manifold::found)
    }

    /// The one driver of every run (the command line, Python and the shards alike): a trace
    /// or scan that returns whatever it finds, even nothing, with its report and warnings.
    /// Its errors are those of the setup (threads, the triangulation, the backend, f zero at
    /// every seed); [`Manifold::failure`] says whether what it found is a mesh of M.
    pub fn run(&self, job: Job) -> Result<Manifold> {
        if let Some(0) = self.threads {
            return Err(Error::Usage("threads must be at least 1".into()));
        }
        let cap = max_threads();
        let mut warnings = Vec::new();
        let pool = match self.threads {
            Some(n) => {
                if n > cap {
                    warnings.push(Warning::Threads {
                        asked: n,
                        running: cap,
                    });
                }
                let n = n.min(cap);
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| {
                        Error::io(
                            format!("cannot start {n} threads"),
                            std::io::Error::other(e),
                        )
                    })?;
                Some(Arc::new(pool))
            }
            None => None,
        };
        let mut m = match &pool {
            Some(p) => p.install(|| self.run_in_pool(job, warnings))?,
            None => self.run_in_pool(job, warnings)?,
        };
        m.pool = pool;
        Ok(m)
    }

    fn run_in_pool(&self, job: Job, mut warnings: Vec<Warning>) -> Result<Manifold> {
        let exhaustive = job == Job::Scan;
        let tri = self.build_triangulation()?;
        let f = &*self.function;
        checks::check_not_zero(f, self.bbox.as_deref(), &self.seeds, tri.edge())?;
        let singular_seeds = if exhaustive {
            Vec::new()
        } else {
            checks::singular_seeds(f, &self.seeds, tri.edge())
        };
        warnings.extend(
            singular_seeds
                .iter()
                .map(|(seed, point)| Warning::SingularSeed {
                    seed: *seed,
                    point: point.clone(),
                }),
        );
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
        let gpu = match self.gpu_oracle(job, &mut warnings) {
            // Stopped while a shader compiled: the trace below stops at once on the raised
            // flag (keeping at most its seeds' simplices), marked interrupted, as on the CPU.
            Err(Error::Interrupted(_)) => None,
            other => other?,
        };
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
        // One warning stands for the crossings found; the report lists them all.
        if let Some(x) = checks.singular.first() {
            warnings.push(Warning::SingularCrossing(x.clone()));
        }
        if checks.suspect > 0 {
            warnings.push(Warning::Suspect {
                count: checks.suspect,
                of: sample.len(),
            });
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
            singular_seeds: singular_seeds.into_iter().map(|(i, _)| i).collect(),
            singular_crossings: checks.singular,
        };
        Ok(Manifold {
            function: self.function.clone(),
            bbox: self.bbox.clone(),
            max_memory: self.max_memory,
            pool: None,
            exhaustive,
            had_seeds: !self.seeds.is_empty(),
            report: Report::new(&sample, run),
            sample,
            warnings,
            complex: OnceLock::new(),
        })
    }

    /// The GPU oracle the backend asks for, or `None` for the CPU. Auto takes a hardware
    /// GPU only where the calibration file says it was measured faster for `job`
    /// ([`crate::gpu::calibration`]), with device values for a scan where those were
    /// faster still.
    #[cfg(feature = "gpu")]
    fn gpu_oracle(
        &self,
        job: Job,
        warnings: &mut Vec<Warning>,
    ) -> Result<Option<crate::gpu::GpuOracle<'_>>> {
        use crate::gpu::calibration::{self, Calibration, Pick};
        use crate::gpu::{Gpu, GpuOptions, GpuOracle};
        let f = &*self.function;
        let gpu_settings =
            self.precision.is_some() || self.level_slice.is_some() || self.device_values;
        let mut device_values = self.device_values;
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
                let g = match Gpu::open(self.auto_software) {
                    Ok(g) => g,
                    Err(e) => {
                        warnings.push(Warning::NoGpu {
                            why: e.to_string(),
                            gpu_settings,
                        });
                        return Ok(None);
                    }
                };
                let file = self.calibration.clone().or_else(calibration::default_path);
                let pick = match file.as_deref().map(Calibration::load).transpose() {
                    Ok(c) => c.unwrap_or_default().pick(&g.adapter, job),
                    Err(e) => Pick::Cpu(format!("auto: {e}")),
                };
                match pick {
                    Pick::Gpu { device_values: v } => {
                        device_values |= v;
                        g
                    }
                    Pick::Cpu(why) => {
                        warnings.push(Warning::NoGpu { why, gpu_settings });
                        return Ok(None);
                    }
                }
            }
        };
        let options = GpuOptions {
            precision: self.precision,
            level_slice: self.level_slice.unwrap_or(0),
            device_values,
            cancel: self.cancel.clone(),
        };
        GpuOracle::with_options(gpu, f, options).map(Some)
    }
}

/// Most worker threads per core a run may ask for: the work is all on the CPU, so a thread
/// beyond the cores only takes turns with another (eight threads on two cores ran a trace
/// four times slower than one).
const MAX_THREADS_PER_CORE: usize = 1;
/// Most worker threads in all.
const MAX_THREADS: usize = 1024;

/// The most worker threads a run uses: one per core, at most 1024 (more only wait on one
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
