//! The files of a run, planned before anything is traced and written after: an
//! [`OutputPlan`] names each output with its format, the picture, the projection and the
//! report; [`Manifold::deliver`] writes them, each on its own (one that fails leaves the
//! others written), the sample first; [`Manifold::final_report`] says what happened.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};

use super::manifold::{caption, Manifold};
use crate::complex::{Complex, Topology};
use crate::error::{shown, Error, Result};
use crate::export::mesh::{write_mesh_as, Encoding, Mesh};
use crate::export::picture::Picture;
use crate::export::safe::{check_target, FileId};
use crate::export::{write_atomic, write_sample, write_sample_to, OutputFormat, Projection};
use crate::memory;
use crate::report::{ComplexReport, Report};
use crate::trace::checks;

/// Where an output goes.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Target {
    /// A file, replaced whole once written ([`write_atomic`]).
    File(PathBuf),
    /// Standard output.
    Stdout,
}

impl Target {
    /// `-` is standard output, anything else a file.
    pub fn from_path(path: &Path) -> Self {
        if path.as_os_str() == "-" {
            Target::Stdout
        } else {
            Target::File(path.to_path_buf())
        }
    }

    /// The path as given, or `standard output`.
    fn named(&self) -> String {
        match self {
            Target::File(p) => p.display().to_string(),
            Target::Stdout => "standard output".into(),
        }
    }
}

/// One planned output: where, in what format, and the name its errors go by (`--out`).
#[derive(Clone, Debug)]
pub struct PlannedOutput {
    /// Where it goes.
    pub target: Target,
    /// The sample or the mesh, and the format.
    pub format: OutputFormat,
    /// How the caller names it in messages (a flag, an argument).
    pub label: String,
}

/// Every output of a run, checked before anything is traced: formats, the mesh dimension
/// each holds, the projection, paths that must be regular files, and no two outputs (or an
/// output and the input) the same file.
#[derive(Clone, Debug)]
pub struct OutputPlan {
    /// The sample and mesh files, in the order given.
    pub outputs: Vec<PlannedOutput>,
    /// A PNG picture: path, width and height in pixels.
    pub picture: Option<(PathBuf, usize, usize)>,
    /// How R^d is seen in 3-D, as given (`auto`, `pca`, `1,2,4`) and parsed.
    pub projection_name: String,
    /// [`OutputPlan::projection_name`], parsed.
    pub projection: Projection,
    /// Binary or text PLY and VTU.
    pub encoding: Encoding,
    /// Build the complex even when no output needs it, for its keys in the report.
    pub complex: bool,
    /// The JSON report.
    pub report: Option<Target>,
}

impl OutputPlan {
    /// No output yet, for an m-manifold in R^d seen through `projection` (`auto`, `pca`,
    /// `1,2,4`).
    pub fn new(d: usize, projection: &str) -> Result<Self> {
        Ok(OutputPlan {
            outputs: Vec::new(),
            picture: None,
            projection_name: projection.to_string(),
            projection: Projection::parse(projection, d)?,
            encoding: Encoding::Binary,
            complex: true,
            report: None,
        })
    }

    /// Adds an output of the m-manifold, refusing a mesh format that cannot hold it and a
    /// mesh on standard output.
    pub fn add(
        &mut self,
        label: &str,
        target: Target,
        format: OutputFormat,
        m: usize,
    ) -> Result<()> {
        match (&format, &target) {
            (OutputFormat::Mesh(_), Target::Stdout) => {
                return Err(Error::Usage(format!(
                    "{label} -: standard output takes the sample only (csv or xyz); write mesh \
                     files to a path"
                )))
            }
            (OutputFormat::Mesh(f), Target::File(path)) => f.check_holds(m, path)?,
            (OutputFormat::Sample(_), _) => {}
        }
        if target == Target::Stdout && self.uses_stdout() {
            return Err(Error::Usage(format!(
                "{label} -: standard output is taken twice"
            )));
        }
        self.outputs.push(PlannedOutput {
            target,
            format,
            label: label.to_string(),
        });
        Ok(())
    }

    /// Whether some output, or the report, goes to standard output.
    pub fn uses_stdout(&self) -> bool {
        self.report == Some(Target::Stdout)
            || self.outputs.iter().any(|o| o.target == Target::Stdout)
    }

    /// Whether an output needs the mesh (a mesh file, a picture).
    pub fn wants_mesh(&self) -> bool {
        self.picture.is_some()
            || self
                .outputs
                .iter()
                .any(|o| matches!(o.format, OutputFormat::Mesh(_)))
    }

    /// Checks that each file is absent or a regular file, and that no two of them, or one of
    /// them and `input` (labelled `input_label`), are the same file.
    pub fn check_files(
        &self,
        picture_label: &str,
        report_label: &str,
        input: Option<&Path>,
    ) -> Result<()> {
        let mut files: Vec<(&str, &Path, FileId)> = Vec::new();
        let named = self
            .outputs
            .iter()
            .filter_map(|o| match &o.target {
                Target::File(p) => Some((o.label.as_str(), p.as_path())),
                Target::Stdout => None,
            })
            .chain(self.picture.iter().map(|p| (picture_label, p.0.as_path())))
            .chain(self.report.iter().filter_map(|t| match t {
                Target::File(p) => Some((report_label, p.as_path())),
                Target::Stdout => None,
            }));
        for (label, path) in named {
            check_target(path).map_err(|e| e.for_flag(label))?;
            let id = FileId::of(path)?;
            if let Some((other, other_path, _)) = files.iter().find(|f| f.2.same(&id)) {
                return Err(Error::Usage(format!(
                    "{label} {} and {other} {} are the same file: give each output its own path",
                    shown(&path.display().to_string()),
                    shown(&other_path.display().to_string())
                )));
            }
            files.push((label, path, id));
        }
        if let Some(input) = input {
            let id = FileId::of(input)?;
            if let Some((label, path, _)) = files.iter().find(|f| f.2.same(&id)) {
                return Err(Error::Usage(format!(
                    "{label} {} is the input spec: it would be overwritten; give another path",
                    shown(&path.display().to_string())
                )));
            }
        }
        Ok(())
    }

    /// Writes `report` where the plan says; the path when it is a file.
    pub fn write_report(&self, report: &Report) -> Result<Option<PathBuf>> {
        match &self.report {
            None => Ok(None),
            Some(Target::Stdout) => {
                let mut out = std::io::stdout().lock();
                writeln!(out, "{}", report.to_json())
                    .and_then(|()| out.flush())
                    .map_err(|e| Error::io("standard output", e))?;
                Ok(None)
            }
            Some(Target::File(path)) => {
                write_atomic(path, |w| writeln!(w, "{}", report.to_json()))?;
                Ok(Some(path.clone()))
            }
        }
    }
}

/// What [`Manifold::deliver`] did.
#[derive(Debug, Default)]
pub struct Delivery {
    /// The files written, in order.
    pub written: Vec<PathBuf>,
    /// The outputs not written (paths, or `standard output`).
    pub not_written: Vec<String>,
    /// What went wrong, the error that decides the run's outcome first: f vanishing on a
    /// region, the complex or the mesh refused, then each output that failed.
    pub errors: Vec<Error>,
    /// Seconds the complex's topology took, when the complex was built.
    pub topology_s: Option<f64>,
}

impl Delivery {
    /// Records the outcome of writing `target`.
    fn record(&mut self, target: &Target, result: Result<()>, failed: &mut Vec<Error>) {
        match result {
            Ok(()) => {
                if let Target::File(p) = target {
                    self.written.push(p.clone());
                }
            }
            Err(e) => {
                self.not_written.push(target.named());
                failed.push(e);
            }
        }
    }

    /// Marks `target` not written unless it was written or has failed already.
    fn left_out(&mut self, target: &Target) {
        let name = target.named();
        let written = matches!(target, Target::File(p) if self.written.contains(p));
        if !written && !self.not_written.contains(&name) {
            self.not_written.push(name);
        }
    }
}

impl Manifold {
    /// Writes the plan's outputs: the sample first (whatever happens next, it is on disk),
    /// then, unless f vanishes on a region or `cancel` is set, the complex and the mesh files
    /// and the picture. Each output is written, or fails, on its own. `phase` hears each step
    /// as it starts.
    pub fn deliver(
        &self,
        plan: &OutputPlan,
        cancel: &AtomicBool,
        phase: &(dyn Fn(&str) + Sync),
    ) -> Delivery {
        // The run's pool writes too: its threads, not new ones, make the mesh.
        self.in_pool(|| self.deliver_in_pool(plan, cancel, phase))
    }

    fn deliver_in_pool(
        &self,
        plan: &OutputPlan,
        cancel: &AtomicBool,
        phase: &(dyn Fn(&str) + Sync),
    ) -> Delivery {
        let mut out = Delivery::default();
        let mut failed = Vec::new();
        self.write_samples(plan, phase, &mut out, &mut failed);
        // f vanishing on a region: the sample is kept, no mesh of it is made.
        let mut failure = self
            .sample
            .stats
            .zero_region
            .as_ref()
            .map(|(i, x)| checks::region_error(*i, x));
        let stopping = || cancel.load(Ordering::SeqCst);
        let wanted = plan.complex || plan.wants_mesh();
        if wanted && failure.is_none() && !self.is_empty() && !stopping() {
            phase("complex: building the cell complex");
            match self.built_with(cancel, phase) {
                Ok(built) => {
                    out.topology_s = Some(built.2);
                    if plan.wants_mesh() {
                        failure = self
                            .write_meshes(built, plan, cancel, phase, &mut out, &mut failed)
                            .err();
                    }
                }
                // Stopped by a signal: the report says so, with no complex.
                Err(_) if stopping() => {}
                Err(e) => failure = Some(e),
            }
        }
        // Every planned file neither written nor failed was left out.
        for o in &plan.outputs {
            if o.target != Target::Stdout {
                out.left_out(&o.target);
            }
        }
        if let Some((p, _, _)) = &plan.picture {
            out.left_out(&Target::File(p.clone()));
        }
        out.errors = failure.into_iter().chain(failed).collect();
        out
    }

    /// Writes the plan's sample outputs.
    fn write_samples(
        &self,
        plan: &OutputPlan,
        phase: &(dyn Fn(&str) + Sync),
        out: &mut Delivery,
        failed: &mut Vec<Error>,
    ) {
        for o in self.outputs_of(plan, false) {
            let OutputFormat::Sample(format) = o.format else {
                continue;
            };
            let result = match &o.target {
                Target::Stdout => {
                    let mut w = std::io::stdout().lock();
                    write_sample_to(&mut w, &self.sample, format)
                        .and_then(|()| w.flush())
                        .map_err(|e| Error::io("standard output", e))
                }
                Target::File(path) => {
                    phase(&format!("writing {}", shown(&o.target.named())));
                    write_sample(path, &self.sample, format)
                }
            };
            out.record(&o.target, result, failed);
        }
    }

    /// Writes the plan's mesh files and picture of the built complex; an error when the
    /// mesh would not fit in the memory limit. A signal lets the file being written finish,
    /// and skips the rest.
    fn write_meshes(
        &self,
        (c, t, _): &(Complex, Topology, f64),
        plan: &OutputPlan,
        cancel: &AtomicBool,
        phase: &(dyn Fn(&str) + Sync),
        out: &mut Delivery,
        failed: &mut Vec<Error>,
    ) -> Result<()> {
        let stopping = || cancel.load(Ordering::SeqCst);
        // Vertices in R^3 and the polygons as triangles, generously.
        let cells: usize = t.cells.iter().sum();
        memory::check_headroom("the mesh", 48 * t.cells[0] + 64 * cells, self.max_memory)?;
        let name = &self.report.name;
        let mesh = Mesh::new(c, Some(self.function()), &plan.projection, name);
        for o in self.outputs_of(plan, true) {
            let (OutputFormat::Mesh(format), Target::File(path), false) =
                (o.format, &o.target, stopping())
            else {
                continue;
            };
            phase(&format!("writing {}", shown(&o.target.named())));
            let result = write_mesh_as(path, &mesh, format, plan.encoding);
            out.record(&o.target, result, failed);
        }
        if let (Some((path, w, h)), false) = (&plan.picture, stopping()) {
            let target = Target::File(path.clone());
            phase(&format!("writing {}", shown(&target.named())));
            let pixels = w.saturating_mul(*h).saturating_mul(16);
            let result = memory::check_headroom("the picture", pixels, self.max_memory)
                .and_then(|()| {
                    let caption = caption(name, c.ambient_dim(), t);
                    Picture::render(&mesh, *w, *h, &caption)
                })
                .and_then(|pic| pic.write_png(path));
            out.record(&target, result, failed);
        }
        Ok(())
    }

    /// The plan's outputs of the mesh (`true`) or of the sample.
    fn outputs_of<'p>(&self, plan: &'p OutputPlan, mesh: bool) -> Vec<&'p PlannedOutput> {
        plan.outputs
            .iter()
            .filter(|o| matches!(o.format, OutputFormat::Mesh(_)) == mesh)
            .collect()
    }

    /// The report of the whole run once `delivery` is done: the complex's keys (seen
    /// through `projection`) when it was built, the peak heap since the run started, the
    /// deciding error, the outputs not written, and `signal` when one stopped it.
    pub fn final_report(
        &self,
        delivery: &Delivery,
        projection: &str,
        signal: Option<String>,
    ) -> Report {
        let mut report = self.report.clone();
        if let (Some((c, t, secs)), Some(_)) = (self.complex.get(), delivery.topology_s) {
            report = report.with_complex(ComplexReport::new(c, t, *secs, projection), t.components);
        }
        report.peak_memory_bytes = memory::peak_bytes() as u64;
        report.bytes_per_simplex = if self.is_empty() {
            0.0
        } else {
            report.peak_memory_bytes as f64 / self.len() as f64
        };
        let error = delivery
            .errors
            .first()
            .map(ToString::to_string)
            .or_else(|| self.nothing_found());
        report.complete &= error.is_none();
        report.error = error;
        report.not_written = delivery.not_written.clone();
        if let Some(sig) = signal {
            report.complete = false;
            report.stopped.get_or_insert_with(|| "interrupted".into());
            report.signal = Some(sig);
        }
        report
    }
}
