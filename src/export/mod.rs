//! Writing results to files. Every writer goes through [`write_atomic`]: a file appears whole
//! under its final name or not at all, so an interrupted or failed write never leaves a
//! truncated result in place of a good one.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;

use crate::error::{Error, Result};
use crate::trace::Sample;

pub mod mesh;
pub mod picture;
pub mod plot;
pub mod projection;
pub mod raster;
pub mod safe;
pub mod section;

pub use mesh::{write_mesh, write_mesh_as, Encoding, Mesh, MeshFormat};
pub use projection::{Projection, View};

/// Writes `path` through `body` into a temporary file of its own beside it (see
/// [`safe::check_target`] for what may be replaced), then renames it into place.
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let io = |e: std::io::Error| Error::io(path.display(), e);
    safe::check_target(path)?;
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    let (tmp, file) = safe::create_partial(path).map_err(io)?;
    let mut w = BufWriter::with_capacity(1 << 20, file);
    let written = body(&mut w).and_then(|()| w.flush());
    drop(w);
    // A file replaced keeps its permissions (a private 0600 file stays private).
    let kept = match std::fs::metadata(path) {
        Ok(m) if m.is_file() => std::fs::set_permissions(&tmp, m.permissions()),
        _ => Ok(()),
    };
    // The target may have turned into something else meanwhile.
    let done = written
        .and(kept)
        .map_err(io)
        .and_then(|()| safe::check_target(path))
        .and_then(|()| std::fs::rename(&tmp, path).map_err(io));
    if done.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    safe::release_partial(&tmp);
    done
}

/// Sample formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFormat {
    /// Comma-separated, a header `x1,..,xd` then one point per line.
    Csv,
    /// Space-separated, one point per line, no header (`.xyz`, `.txt`).
    Xyz,
    /// The crossed simplices' keys (`.keys`): a `#` comment line, then one simplex per line,
    /// its key's 64-bit words in decimal, in the sample's order (`numpy.loadtxt(path,
    /// dtype=numpy.uint64)` reads it). Keys name simplices exactly, so two runs can be compared
    /// or merged simplex by simplex.
    Keys,
}

/// Every output format's name, as `--format` and `format=` take them.
pub const FORMAT_NAMES: &str = "csv, xyz, keys, ply, obj, off, stl, mesh, vtu or npz";

impl SampleFormat {
    /// The format for `path`'s extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("csv") => Ok(SampleFormat::Csv),
            Some("xyz") | Some("txt") => Ok(SampleFormat::Xyz),
            Some("keys") => Ok(SampleFormat::Keys),
            _ => Err(Error::Output(format!(
                "{}: unknown output format; use .csv, .xyz, .txt or .keys",
                path.display()
            ))),
        }
    }
}

/// What an output file receives: the sample's points or the mesh.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OutputFormat {
    /// One point of M per crossed simplex.
    Sample(SampleFormat),
    /// The cell complex, as a mesh file.
    Mesh(MeshFormat),
}

impl OutputFormat {
    /// The format called `name`: csv, xyz, txt, or a [`MeshFormat`] name.
    pub fn from_name(name: &str) -> Option<Self> {
        match name.to_ascii_lowercase().as_str() {
            "csv" => Some(OutputFormat::Sample(SampleFormat::Csv)),
            "xyz" | "txt" => Some(OutputFormat::Sample(SampleFormat::Xyz)),
            "keys" => Some(OutputFormat::Sample(SampleFormat::Keys)),
            other => MeshFormat::from_name(other).map(OutputFormat::Mesh),
        }
    }

    /// The format for `path`: `format` when given, else the file extension.
    pub fn for_path(path: &Path, format: Option<&str>) -> Result<Self> {
        match format {
            Some(f) => Self::from_name(f)
                .ok_or_else(|| Error::Spec(format!("format {f}: use {FORMAT_NAMES}"))),
            None => path
                .extension()
                .and_then(|e| Self::from_name(&e.to_string_lossy()))
                .ok_or_else(|| {
                    Error::Output(format!(
                        "{}: unknown output format; use .csv, .xyz, .txt, .keys, .ply, .obj, \
                         .off, .stl, .mesh, .vtu or .npz",
                        path.display()
                    ))
                }),
        }
    }
}

/// Writes the points of S, one per line, in full f64 precision (shortest round-trip form).
pub fn write_sample(path: &Path, sample: &Sample, format: SampleFormat) -> Result<()> {
    write_atomic(path, |w| write_sample_to(w, sample, format))
}

/// [`write_sample`] into any writer (standard output for `--out -`).
pub fn write_sample_to(
    w: &mut impl Write,
    sample: &Sample,
    format: SampleFormat,
) -> std::io::Result<()> {
    let d = sample.ambient_dim();
    if format == SampleFormat::Keys {
        let words = sample.codec().words();
        writeln!(
            w,
            "# isomesh simplex keys: {words} 64-bit words per crossed simplex, in the sample's order"
        )?;
        for i in 0..sample.len() {
            for (j, word) in sample.key(i).iter().enumerate() {
                if j > 0 {
                    w.write_all(b" ")?;
                }
                write!(w, "{word}")?;
            }
            writeln!(w)?;
        }
        return Ok(());
    }
    let sep = match format {
        SampleFormat::Csv => ",",
        SampleFormat::Xyz | SampleFormat::Keys => " ",
    };
    if format == SampleFormat::Csv {
        let header: Vec<String> = (1..=d).map(|i| format!("x{i}")).collect();
        writeln!(w, "{}", header.join(","))?;
    }
    for p in sample.shared_points().chunks_exact(d) {
        for (i, v) in p.iter().enumerate() {
            if i > 0 {
                w.write_all(sep.as_bytes())?;
            }
            write!(w, "{v:?}")?;
        }
        writeln!(w)?;
    }
    Ok(())
}
