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

pub use mesh::{write_mesh, Mesh, MeshFormat};
pub use projection::{Projection, View};

/// Writes `path` through `body` into a temporary file beside it, then renames it into place.
pub fn write_atomic(
    path: &Path,
    body: impl FnOnce(&mut BufWriter<File>) -> std::io::Result<()>,
) -> Result<()> {
    let io = |e: std::io::Error| Error::Io(format!("{}: {e}", path.display()));
    if let Some(dir) = path.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(io)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    let tmp = std::path::PathBuf::from(tmp);
    let file = File::create(&tmp).map_err(io)?;
    let mut w = BufWriter::new(file);
    let written = body(&mut w).and_then(|()| w.flush());
    if let Err(e) = written {
        let _ = std::fs::remove_file(&tmp);
        return Err(io(e));
    }
    drop(w);
    std::fs::rename(&tmp, path).map_err(io)
}

/// Sample formats, chosen by file extension.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SampleFormat {
    /// Comma-separated, a header `x1,..,xd` then one point per line.
    Csv,
    /// Space-separated, one point per line, no header (`.xyz`, `.txt`).
    Xyz,
}

impl SampleFormat {
    /// The format for `path`'s extension.
    pub fn from_path(path: &Path) -> Result<Self> {
        let ext = path
            .extension()
            .map(|e| e.to_string_lossy().to_ascii_lowercase());
        match ext.as_deref() {
            Some("csv") => Ok(SampleFormat::Csv),
            Some("xyz") | Some("txt") => Ok(SampleFormat::Xyz),
            _ => Err(Error::Io(format!(
                "{}: unknown output format; use .csv, .xyz or .txt",
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
            other => MeshFormat::from_name(other).map(OutputFormat::Mesh),
        }
    }

    /// The format for `path`: `format` when given, else the file extension.
    pub fn for_path(path: &Path, format: Option<&str>) -> Result<Self> {
        match format {
            Some(f) => Self::from_name(f).ok_or_else(|| {
                Error::Spec(format!(
                    "format {f}: use csv, xyz, ply, obj, off, stl, mesh, vtu or npz"
                ))
            }),
            None => path
                .extension()
                .and_then(|e| Self::from_name(&e.to_string_lossy()))
                .ok_or_else(|| {
                    Error::Io(format!(
                        "{}: unknown output format; use .csv, .xyz, .txt, .ply, .obj, .off, \
                         .stl, .mesh, .vtu or .npz",
                        path.display()
                    ))
                }),
        }
    }
}

/// Writes the points of S, one per line, in full f64 precision (shortest round-trip form).
pub fn write_sample(path: &Path, sample: &Sample, format: SampleFormat) -> Result<()> {
    let d = sample.ambient_dim();
    let sep = match format {
        SampleFormat::Csv => ",",
        SampleFormat::Xyz => " ",
    };
    write_atomic(path, |w| {
        if format == SampleFormat::Csv {
            let header: Vec<String> = (1..=d).map(|i| format!("x{i}")).collect();
            writeln!(w, "{}", header.join(","))?;
        }
        for p in sample.points().chunks_exact(d) {
            for (i, v) in p.iter().enumerate() {
                if i > 0 {
                    w.write_all(sep.as_bytes())?;
                }
                write!(w, "{v:?}")?;
            }
            writeln!(w)?;
        }
        Ok(())
    })
}
