//! The flags of `isomesh trace` and the parsers of their values.

use std::path::PathBuf;

use clap::builder::{PossibleValuesParser, TypedValueParser};
use clap::Args;
use isomesh::export::picture::SIDES;
use isomesh::gpu::Precision;
use isomesh::triangulation::{TriangulationKind, EDGE_RANGE};
use isomesh::{Backend, Error, Result};

use super::text::{num, shown};

/// `--backend`: cpu, gpu or auto, as [`Backend`].
pub fn backend_parser() -> impl TypedValueParser<Value = Backend> {
    PossibleValuesParser::new(["cpu", "gpu", "auto"])
        .map(|s| s.parse::<Backend>().expect("one of the listed backends"))
}

/// Flags of `isomesh trace`; they override the spec's values.
#[derive(Args, Clone, Debug, Default)]
pub struct TraceArgs {
    /// A spec file (TOML).
    pub spec: Option<PathBuf>,
    /// A built-in manifold instead of a spec file (`isomesh presets` lists them).
    #[arg(long)]
    pub preset: Option<String>,
    /// Preset parameter, name=value (repeatable).
    #[arg(long = "param", value_parser = super::parse_param)]
    pub params: Vec<(String, f64)>,
    /// Triangulation: coxeter or freudenthal.
    #[arg(long)]
    pub triangulation: Option<TriangulationKind>,
    /// Seed of the random offset of the triangulation.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<u64>)]
    pub offset_seed: Option<u64>,
    /// Seed of the random rotation of the triangulation (default 1).
    #[arg(long, conflicts_with = "no_rotation", allow_hyphen_values = true, value_parser = parse_count::<u64>)]
    pub rotation_seed: Option<u64>,
    /// Keep the triangulation's lattice axis-aligned (no rotation).
    #[arg(long)]
    pub no_rotation: bool,
    /// Seed point x1,..,xd near M (repeatable; replaces the spec's seeds).
    #[arg(long = "seed", allow_hyphen_values = true)]
    pub seeds: Vec<NumList>,
    /// Longest edge of a d-simplex of the triangulation.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_edge)]
    pub edge: Option<f64>,
    /// Scan every k-simplex in the box instead of tracing from seeds.
    #[arg(long)]
    pub exhaustive: bool,
    /// The box: LO,HI (the cube [LO,HI]^d) or lo1,hi1,...,lod,hid.
    #[arg(long = "box", allow_hyphen_values = true)]
    pub bbox: Option<NumList>,
    /// Random box points projected onto M to find components (default: 512 when there is no
    /// seed, else 0).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub search: Option<usize>,
    /// Oracle backend [default: cpu]: gpu uses any adapter (software ones too); auto a
    /// hardware GPU where `isomesh bench` measured it faster than the CPU for this job (its
    /// calibration file, ISOMESH_CALIBRATION or the user's cache), else the CPU.
    #[arg(long, value_parser = backend_parser())]
    pub backend: Option<Backend>,
    /// GPU shader precision: f64 (needs SHADER_F64), f32 (a filter; crossings are computed
    /// on the CPU), or auto (f64 where the adapter has it) [default: auto].
    #[arg(long, value_parser = ["f32", "f64", "auto"])]
    pub precision: Option<String>,
    /// GPU backend: frontier simplices per slice of a trace level; wider levels are decided
    /// slice by slice, the next slice named on the CPU meanwhile (for example 16384; default
    /// 0: whole levels). The result does not depend on it.
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub level_slice: Option<usize>,
    /// GPU backend, --exhaustive: the scan stays on the device (d <= 8), tile by tile: f
    /// evaluated there with certified bounds, candidates and certified verdicts, and only the
    /// candidates it could not rule out sent back, where the CPU evaluates f at their
    /// vertices and decides them. The result does not depend on it.
    #[arg(long)]
    pub device_values: bool,
    /// Worker threads (default: all cores).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_count::<usize>)]
    pub threads: Option<usize>,
    /// Memory limit, bytes or with a K/M/G suffix (default: 3/4 of RAM).
    #[arg(long, allow_hyphen_values = true, value_parser = parse_bytes)]
    pub max_memory: Option<u64>,
    /// Write the result (repeatable): the sample as .csv, .xyz or .txt; the mesh as .ply,
    /// .obj, .off, .stl (surfaces), .mesh (Medit), .vtu (ParaView) or .npz (NumPy). `-` is
    /// standard output, for the sample (CSV unless --format says xyz).
    #[arg(long)]
    pub out: Vec<PathBuf>,
    /// Output format for --out, overriding the file extension: csv, xyz, ply, obj, off, stl,
    /// mesh, vtu or npz.
    #[arg(long)]
    pub format: Option<String>,
    /// Draw the mesh into a PNG picture.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Size of the picture, WIDTHxHEIGHT (64 to 8192 pixels a side) [default: 1200x900].
    #[arg(long, value_parser = parse_size)]
    pub png_size: Option<(usize, usize)>,
    /// How R^d is seen in 3-D for files and pictures: auto (the coordinates up to d = 3,
    /// else pca), pca, or coordinates such as 1,2,4.
    #[arg(long, default_value = "auto")]
    pub project: String,
    /// Only the sample: no cell complex, no topology report, no mesh outputs.
    #[arg(long)]
    pub no_complex: bool,
    /// PLY and VTU files as text rather than binary (Medit `.mesh`, OBJ and OFF are text
    /// always, STL and NPZ binary always).
    #[arg(long)]
    pub ascii: bool,
    /// Write a JSON report.
    #[arg(long)]
    pub report: Option<PathBuf>,
    /// No progress bar and no summary.
    #[arg(long, short)]
    pub quiet: bool,
    /// Name each phase on standard error as it starts (grid, search, levels, complex,
    /// writing): a log for batch jobs.
    #[arg(long, short, conflicts_with = "quiet")]
    pub verbose: bool,
}

/// A comma-separated list of numbers, as a flag value.
#[derive(Clone, Debug, PartialEq)]
pub struct NumList(pub Vec<f64>);

impl std::str::FromStr for NumList {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        s.split(',')
            .map(|t| {
                t.trim()
                    .parse::<f64>()
                    .map_err(|_| format!("'{}' is not a number", shown(t)))
            })
            .collect::<std::result::Result<_, _>>()
            .map(NumList)
    }
}

/// Parses a byte count with an optional K, M, G or T suffix (powers of 1024).
pub fn parse_bytes(s: &str) -> std::result::Result<u64, String> {
    let t = s.trim();
    let (num, mult) = match t.chars().last().map(|c| c.to_ascii_uppercase()) {
        Some('K') => (&t[..t.len() - 1], 1u64 << 10),
        Some('M') => (&t[..t.len() - 1], 1 << 20),
        Some('G') => (&t[..t.len() - 1], 1 << 30),
        Some('T') => (&t[..t.len() - 1], 1 << 40),
        _ => (t, 1),
    };
    let v: f64 = num
        .trim()
        .parse()
        .map_err(|_| format!("'{}' is not a size (e.g. 2G, 512M, 1000000)", shown(s)))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{}' must be positive", shown(s)));
    }
    let bytes = v * mult as f64;
    if bytes < 1.0 {
        return Err(format!(
            "'{}' is less than one byte (sizes are bytes, or K, M, G, T)",
            shown(s)
        ));
    }
    Ok(bytes as u64)
}

/// Parses WIDTHxHEIGHT.
pub fn parse_size(s: &str) -> std::result::Result<(usize, usize), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("'{s}' is not WIDTHxHEIGHT (e.g. 1200x900)"))?;
    let p = |t: &str| match t.trim().parse::<usize>() {
        Ok(n) if SIDES.contains(&n) => Ok(n),
        Ok(_) => Err(format!(
            "'{}': each side must be {} to {} pixels",
            shown(s),
            SIDES.start(),
            SIDES.end()
        )),
        Err(_) => Err(format!(
            "'{}' is not WIDTHxHEIGHT (e.g. 1200x900)",
            shown(s)
        )),
    };
    Ok((p(w)?, p(h)?))
}

/// The size of a picture when --png-size is not given.
pub const DEFAULT_PNG_SIZE: (usize, usize) = (1200, 900);

/// Parses an edge length within [`EDGE_RANGE`].
pub fn parse_edge(s: &str) -> std::result::Result<f64, String> {
    match s.trim().parse::<f64>() {
        Ok(v) if EDGE_RANGE.contains(&v) => Ok(v),
        Ok(v) if v.is_finite() && v > 0.0 => Err(format!(
            "{} is out of range: the edge must be from {:e} to {:e}",
            num(v),
            EDGE_RANGE.start(),
            EDGE_RANGE.end()
        )),
        Ok(v) => Err(format!(
            "{} is not a length: the edge must be positive and finite",
            num(v)
        )),
        Err(_) => Err(format!("'{}' is not a number", shown(s))),
    }
}

/// Parses a non-negative whole number, naming a negative one as such.
pub fn parse_count<T: std::str::FromStr>(s: &str) -> std::result::Result<T, String> {
    let t = s.trim();
    t.parse::<T>().map_err(|_| {
        if t.starts_with('-') && t[1..].parse::<f64>().is_ok() {
            format!("{} is negative: give a whole number from 0 up", shown(t))
        } else {
            format!("'{}' is not a whole number", shown(t))
        }
    })
}

/// The box from `--box` for dimension d.
pub fn box_from_flag(v: &[f64], d: usize) -> Result<Vec<[f64; 2]>> {
    match v.len() {
        2 => Ok(vec![[v[0], v[1]]; d]),
        n if n == 2 * d => Ok(v.chunks_exact(2).map(|c| [c[0], c[1]]).collect()),
        n => Err(Error::DimensionMismatch(format!(
            "--box has {n} numbers: give LO,HI or {} numbers lo1,hi1,...,lo{d},hi{d}",
            2 * d
        ))),
    }
}

impl TraceArgs {
    /// `--precision`: `None` for auto (f64 where the adapter has it, else f32).
    pub fn shader_precision(&self) -> Option<Precision> {
        match self.precision.as_deref() {
            Some("f32") => Some(Precision::F32),
            Some("f64") => Some(Precision::F64),
            _ => None,
        }
    }

    /// `--report -`: the JSON report goes to standard output.
    pub fn report_to_stdout(&self) -> bool {
        self.report.as_ref().is_some_and(|p| p.as_os_str() == "-")
    }
}
