//! [`Manifold`]: what a run found, with everything needed to build its complex, report and
//! files without being given f, the box or the limits again; and the [`Warning`]s of a run.

use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::Instant;

use crate::complex::{Complex, Topology};
use crate::error::{Error, Result};
use crate::export::mesh::{write_mesh_as, Encoding, Mesh};
use crate::export::picture::Picture;
use crate::export::{write_sample, OutputFormat, Projection};
use crate::expr::ImplicitFunction;
use crate::report::{ComplexReport, Report};
use crate::trace::{checks, Sample};

/// Something a run found that its user should hear of, beside the mesh it returns.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum Warning {
    /// More worker threads were asked for than the machine can use; `running` ran.
    Threads {
        /// The threads asked for.
        asked: usize,
        /// The threads that ran ([`max_threads`](super::max_threads)).
        running: usize,
    },
    /// [`Backend::Auto`](super::Backend::Auto) found no GPU to use (why), so the CPU decided;
    /// `gpu_settings` when GPU-only settings were given, which then do not apply.
    NoGpu {
        /// Why no GPU was used.
        why: String,
        /// Whether precision, level slices or device values were set.
        gpu_settings: bool,
    },
    /// Seed `seed` (from 1) projects to `point`, where f's Jacobian is rank-deficient.
    SingularSeed {
        /// The seed, from 1.
        seed: usize,
        /// Where it projects.
        point: Vec<f64>,
    },
    /// The trace passed near `point`, where f's Jacobian is rank-deficient: branches may
    /// cross there, and a trace follows only those it reaches.
    SingularCrossing(Vec<f64>),
    /// At `count` of `of` crossings |f| is more than half the spread of its values at the
    /// simplex's vertices ([`Sample::suspect_crossings`]).
    Suspect {
        /// Crossings found suspect.
        count: usize,
        /// All crossings.
        of: usize,
    },
}

impl Warning {
    /// Whether this is only a note on how the run was done, not on what it found.
    pub fn is_note(&self) -> bool {
        matches!(self, Warning::NoGpu { .. })
    }
}

impl std::fmt::Display for Warning {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Warning::Threads { asked, running } => write!(
                f,
                "{asked} threads: {}",
                super::too_many_threads(*running)
            ),
            Warning::NoGpu { why, gpu_settings } => {
                write!(f, "{why}; using the CPU")?;
                if *gpu_settings {
                    write!(
                        f,
                        " (the precision, level slices and device values apply on a GPU only)"
                    )?;
                }
                Ok(())
            }
            Warning::SingularSeed { seed, point } => write!(
                f,
                "seed {seed} projects to {point:?}, where the Jacobian of f is rank-deficient \
                 (a crossing of branches, a cusp): the trace follows at most one branch from \
                 there; move the seed off the singular point, or scan the box exhaustively"
            ),
            Warning::SingularCrossing(x) => write!(
                f,
                "the trace passed near a point where the Jacobian of f is rank-deficient, \
                 about {x:?} (branches of M may cross there, or a cusp): it follows only the \
                 branches it reaches from its seeds; an exhaustive scan finds all of them in the box"
            ),
            Warning::Suspect { count, of } => write!(
                f,
                "at {count} of {of} crossings |f| is more than half the spread of its values \
                 at the simplex's vertices: f may have a pole or a jump there (the mesh then \
                 shows a sign change, not a zero), or the edge is too coarse for f"
            ),
        }
    }
}

/// M as a trace or scan found it: the sample S, and on demand its cell complex, topology,
/// report and files. It keeps f, the box, the memory limit and the thread pool it was found
/// with, so none of them is given again.
pub struct Manifold {
    pub(super) function: Arc<dyn ImplicitFunction>,
    pub(super) bbox: Option<Vec<[f64; 2]>>,
    pub(super) max_memory: u64,
    /// The run's own pool, when it asked for a thread count; the complex is built in it.
    pub(super) pool: Option<Arc<rayon::ThreadPool>>,
    pub(super) exhaustive: bool,
    pub(super) had_seeds: bool,
    pub(super) sample: Sample,
    pub(super) report: Report,
    pub(super) warnings: Vec<Warning>,
    pub(super) complex: OnceLock<(Complex, Topology, f64)>,
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

    /// Whether the run was an exhaustive scan.
    pub fn exhaustive(&self) -> bool {
        self.exhaustive
    }

    /// f.
    pub fn function(&self) -> &dyn ImplicitFunction {
        &*self.function
    }

    /// What the run warns of, in the order found.
    pub fn warnings(&self) -> &[Warning] {
        &self.warnings
    }

    /// Why the sample is no mesh of M, when it is not: f vanishes on a region, or a complete
    /// run found nothing (the reason). [`Mesher::trace`](super::Mesher::trace) and
    /// [`Mesher::scan`](super::Mesher::scan) return it as their error.
    pub fn failure(&self) -> Option<Error> {
        if let Some((i, x)) = &self.sample.stats.zero_region {
            return Some(checks::region_error(*i, x));
        }
        self.nothing_found().map(Error::Trace)
    }

    /// This manifold, or its [`failure`](Self::failure) as the error.
    pub(super) fn found(self) -> Result<Self> {
        match self.failure() {
            Some(e) => Err(e),
            None => Ok(self),
        }
    }

    /// Why a complete run found nothing, when it did.
    pub fn nothing_found(&self) -> Option<String> {
        (self.is_empty() && self.complete()).then(|| {
            self.sample
                .stats
                .why_nothing_found(self.exhaustive, self.had_seeds)
        })
    }

    /// Runs `f` in the run's thread pool (the current one when the run asked for none).
    pub(super) fn in_pool<T: Send>(&self, f: impl FnOnce() -> T + Send) -> T {
        match &self.pool {
            Some(pool) => pool.install(f),
            None => f(),
        }
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

    /// The complex, its topology and the seconds the topology took.
    pub(super) fn built(&self) -> Result<&(Complex, Topology, f64)> {
        self.built_with(&AtomicBool::new(false), &|_| {})
    }

    /// [`Manifold::complex`] that stops, with an error, once `cancel` is set (Ctrl-C).
    pub fn complex_cancellable(&self, cancel: &AtomicBool) -> Result<&Complex> {
        self.built_with(cancel, &|_| {}).map(|c| &c.0)
    }

    /// The complex, its topology and the seconds the topology took, built on first use;
    /// `phase` hears when the topology starts.
    pub(super) fn built_with(
        &self,
        cancel: &AtomicBool,
        phase: &(dyn Fn(&str) + Sync),
    ) -> Result<&(Complex, Topology, f64)> {
        if let Some(c) = self.complex.get() {
            return Ok(c);
        }
        if self.sample.is_empty() {
            return Err(Error::Trace(
                "nothing was found: there is no complex to build".into(),
            ));
        }
        let interrupted = || Error::Interrupted("the cell complex was interrupted".into());
        let built = self.in_pool(|| {
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
            phase("complex: topology");
            let t0 = Instant::now();
            let t = c.topology_cancellable(cancel).ok_or_else(interrupted)?;
            Ok::<_, Error>((c, t, t0.elapsed().as_secs_f64()))
        })?;
        Ok(self.complex.get_or_init(|| built))
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
/// `height` pixels, captioned with `name` and the topology.
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
    Picture::render(&mesh, width, height, &caption(name, c.ambient_dim(), t))?.write_png(path)
}

/// The caption of a picture of the complex of `name` in R^d with topology `t`.
pub fn caption(name: &str, d: usize, t: &Topology) -> String {
    format!(
        "{name}: {}-manifold in R^{d}, cells {}, chi = {}{}",
        t.dim,
        t.cells
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join("/"),
        t.euler_characteristic,
        if t.closed { "" } else { ", with boundary" }
    )
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
