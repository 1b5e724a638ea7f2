//! Which backend `--backend auto` picks on an adapter: the speeds `isomesh bench` measured
//! there, against the CPU of the same machine.
//!
//! The bench's whole traces and exhaustive scans give, per adapter, the geometric mean over
//! their cases of CPU time / GPU time. Auto takes the GPU for a job only where that mean is
//! at least [`MIN_SPEEDUP`] for this adapter, driver and version of isomesh; a scan takes
//! device values where those measured faster still. Without such a measurement it keeps the
//! CPU: on the one hardware GPU measured so far (an H200 beside 16 cores) the GPU path was
//! slower than the CPU on every trace.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};
use crate::mesher::Job;
use crate::report::AdapterSummary;

/// The least speed-up over the CPU (geometric mean over the bench's cases) for which auto
/// takes the GPU: below it the measurement does not tell the two apart from the machine's
/// noise, and a GPU run also pays for opening the device and compiling its shaders.
pub const MIN_SPEEDUP: f64 = 1.1;

/// The file `isomesh bench` writes and auto reads: `ISOMESH_CALIBRATION` when set, else
/// `isomesh/calibration.toml` in the user's cache directory.
pub fn default_path() -> Option<PathBuf> {
    match std::env::var_os("ISOMESH_CALIBRATION") {
        Some(p) if !p.is_empty() => Some(PathBuf::from(p)),
        _ => dirs::cache_dir().map(|d| d.join("isomesh").join("calibration.toml")),
    }
}

/// Speed-ups measured on one adapter: GPU over CPU, geometric means over the bench's cases.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Speedups {
    /// Cases measured.
    pub cases: usize,
    /// CPU time / GPU time.
    pub gpu: f64,
    /// CPU time / GPU time with f's values from the device (scans only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub device_values: Option<f64>,
}

/// What the bench measured on one adapter with one version of isomesh.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Entry {
    /// The adapter's name.
    pub adapter: String,
    /// Its driver and version.
    pub driver: String,
    /// The API wgpu drove it through.
    pub api: String,
    /// The version of isomesh that measured it.
    pub isomesh: String,
    /// CPU threads the CPU side ran with.
    pub cpu_threads: usize,
    /// Whole traces of the reference cases.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub traces: Option<Speedups>,
    /// Exhaustive scans of boxes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scans: Option<Speedups>,
}

impl Entry {
    /// An entry for `adapter` measured by this version of isomesh.
    pub fn new(adapter: &AdapterSummary, cpu_threads: usize) -> Self {
        Entry {
            adapter: adapter.name.clone(),
            driver: adapter.driver.clone(),
            api: adapter.backend.clone(),
            isomesh: env!("CARGO_PKG_VERSION").into(),
            cpu_threads,
            traces: None,
            scans: None,
        }
    }

    /// The entry for what `isomesh bench` measured on a hardware `adapter`: its trace and
    /// scan rows (`cpu_s` against `gpu_s`, and `device_values_s` for scans; rows without a
    /// GPU time are left out). `None` for a software adapter, or when nothing was measured
    /// on the GPU.
    pub fn from_bench(
        adapter: &AdapterSummary,
        cpu_threads: usize,
        traces: &[serde_json::Value],
        scans: &[serde_json::Value],
    ) -> Option<Self> {
        if adapter.is_software() {
            return None;
        }
        let pairs = |rows: &[serde_json::Value], gpu: &str| -> Vec<(f64, f64)> {
            rows.iter()
                .filter_map(|r| Some((r["cpu_s"].as_f64()?, r[gpu].as_f64()?)))
                .collect()
        };
        let speedups = |rows: &[serde_json::Value], values: bool| {
            let plain = pairs(rows, "gpu_s");
            Some(Speedups {
                cases: plain.len(),
                gpu: speedup(&plain)?,
                device_values: values
                    .then(|| speedup(&pairs(rows, "device_values_s")))
                    .flatten(),
            })
        };
        let entry = Entry {
            traces: speedups(traces, false),
            scans: speedups(scans, true),
            ..Entry::new(adapter, cpu_threads)
        };
        (entry.traces.is_some() || entry.scans.is_some()).then_some(entry)
    }

    fn is_for(&self, adapter: &AdapterSummary) -> bool {
        self.adapter == adapter.name
            && self.driver == adapter.driver
            && self.api == adapter.backend
            && self.isomesh == env!("CARGO_PKG_VERSION")
    }
}

/// The geometric mean of CPU time / GPU time over `(cpu_s, gpu_s)` pairs; `None` when there
/// is none, or a time is not positive and finite.
pub fn speedup(times: &[(f64, f64)]) -> Option<f64> {
    let ok = |t: f64| t.is_finite() && t > 0.0;
    if times.is_empty() || !times.iter().all(|&(c, g)| ok(c) && ok(g)) {
        return None;
    }
    let logs: f64 = times.iter().map(|&(c, g)| (c / g).ln()).sum();
    Some((logs / times.len() as f64).exp())
}

/// What auto runs a job on.
#[derive(Clone, Debug, PartialEq)]
pub enum Pick {
    /// The GPU, with f's values from the device or not.
    Gpu {
        /// Take a scan's values of f from the device.
        device_values: bool,
    },
    /// The CPU, and why (for the report's note).
    Cpu(String),
}

/// Every adapter's measurements: the calibration file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct Calibration {
    /// One entry per adapter, driver and version of isomesh.
    #[serde(default, rename = "adapter")]
    pub entries: Vec<Entry>,
}

impl Calibration {
    /// Reads `path`; a file that does not exist is an empty calibration.
    pub fn load(path: &Path) -> Result<Self> {
        let text = match std::fs::read_to_string(path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(Self::default()),
            Err(e) => return Err(Error::io(path.display(), e)),
        };
        toml::from_str(&text).map_err(|e| {
            Error::Spec(format!(
                "calibration file {}: {} (run `isomesh bench` again to rewrite it)",
                path.display(),
                e.message()
            ))
        })
    }

    /// Writes it to `path` (atomically, creating the directory).
    pub fn save(&self, path: &Path) -> Result<()> {
        let text =
            toml::to_string_pretty(self).map_err(|e| Error::Spec(format!("calibration: {e}")))?;
        crate::export::write_atomic(path, |w| {
            use std::io::Write;
            w.write_all(b"# Written by `isomesh bench`: its GPU/CPU speed-ups, which `--backend auto` reads.\n")?;
            w.write_all(text.as_bytes())
        })
    }

    /// Records `entry`, replacing what was measured before on its adapter, driver and
    /// version (only the jobs it measured: a bench of traces alone keeps the scans).
    pub fn record(&mut self, entry: Entry) {
        let same = |e: &Entry| {
            e.adapter == entry.adapter
                && e.driver == entry.driver
                && e.api == entry.api
                && e.isomesh == entry.isomesh
        };
        match self.entries.iter_mut().find(|e| same(e)) {
            Some(old) => {
                old.cpu_threads = entry.cpu_threads;
                if entry.traces.is_some() {
                    old.traces = entry.traces;
                }
                if entry.scans.is_some() {
                    old.scans = entry.scans;
                }
            }
            None => self.entries.push(entry),
        }
    }

    /// Where auto runs `job` on `adapter` (a hardware one: auto never opens a software
    /// adapter, and the bench records none): the GPU only where the bench measured it at
    /// least [`MIN_SPEEDUP`] times the CPU.
    pub fn pick(&self, adapter: &AdapterSummary, job: Job) -> Pick {
        let what = match job {
            Job::Trace => "traces",
            Job::Scan => "scans",
        };
        let Some(m) = self
            .entries
            .iter()
            .find(|e| e.is_for(adapter))
            .and_then(|e| match job {
                Job::Trace => e.traces.as_ref(),
                Job::Scan => e.scans.as_ref(),
            })
        else {
            return Pick::Cpu(format!(
                "auto: no measurement of {what} on {} ({}) with this version says its GPU \
                 is faster (`isomesh bench --traces {}` measures one)",
                adapter.name,
                adapter.driver,
                match job {
                    Job::Trace => "quick",
                    Job::Scan => "scans",
                }
            ));
        };
        let values = m.device_values.unwrap_or(0.0);
        let best = m.gpu.max(values);
        if best >= MIN_SPEEDUP {
            Pick::Gpu {
                device_values: job == Job::Scan && values > m.gpu,
            }
        } else {
            Pick::Cpu(format!(
                "auto: {what} on {} measured {best:.2}x the CPU's speed (the GPU is taken \
                 from {MIN_SPEEDUP}x)",
                adapter.name
            ))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adapter(name: &str) -> AdapterSummary {
        AdapterSummary {
            name: name.into(),
            backend: "Vulkan".into(),
            device_type: "DiscreteGpu".into(),
            driver: "nvidia 580".into(),
            shader_f64: true,
            max_storage_binding: 1 << 30,
        }
    }

    fn measured(a: &AdapterSummary, traces: Option<f64>, scans: Option<(f64, f64)>) -> Entry {
        Entry {
            traces: traces.map(|gpu| Speedups {
                cases: 4,
                gpu,
                device_values: None,
            }),
            scans: scans.map(|(gpu, v)| Speedups {
                cases: 2,
                gpu,
                device_values: Some(v),
            }),
            ..Entry::new(a, 16)
        }
    }

    #[test]
    fn the_gpu_is_taken_only_where_it_measured_faster() {
        let h = adapter("H200");
        let mut c = Calibration::default();
        assert!(matches!(c.pick(&h, Job::Trace), Pick::Cpu(_)));
        c.record(measured(&h, Some(0.6), Some((1.3, 2.0))));
        assert!(matches!(c.pick(&h, Job::Trace), Pick::Cpu(w) if w.contains("0.60x")));
        assert_eq!(
            c.pick(&h, Job::Scan),
            Pick::Gpu {
                device_values: true
            }
        );
        // A bench of traces alone replaces the traces and keeps the scans.
        c.record(measured(&h, Some(1.5), None));
        assert_eq!(c.entries.len(), 1);
        assert_eq!(
            c.pick(&h, Job::Trace),
            Pick::Gpu {
                device_values: false
            }
        );
        assert!(matches!(c.pick(&h, Job::Scan), Pick::Gpu { .. }));
        // Just under the threshold, and device values slower than the plain GPU scan.
        c.record(measured(&h, Some(MIN_SPEEDUP * 0.99), Some((1.2, 0.5))));
        assert!(matches!(c.pick(&h, Job::Trace), Pick::Cpu(_)));
        assert_eq!(
            c.pick(&h, Job::Scan),
            Pick::Gpu {
                device_values: false
            }
        );
    }

    #[test]
    fn a_measurement_counts_only_for_its_adapter_driver_and_version() {
        let h = adapter("H200");
        let mut c = Calibration::default();
        c.record(measured(&h, Some(3.0), Some((3.0, 3.0))));
        let mut other = h.clone();
        other.name = "A100".into();
        assert!(matches!(c.pick(&other, Job::Trace), Pick::Cpu(_)));
        let mut driver = h.clone();
        driver.driver = "nvidia 590".into();
        assert!(matches!(c.pick(&driver, Job::Scan), Pick::Cpu(_)));
        assert!(matches!(c.pick(&h, Job::Trace), Pick::Gpu { .. }));
        c.entries[0].isomesh = "0.0.1".into();
        assert!(matches!(c.pick(&h, Job::Trace), Pick::Cpu(_)));
    }

    #[test]
    fn the_bench_rows_make_an_entry_for_hardware_adapters_only() {
        use serde_json::json;
        let h = adapter("H200");
        let traces = [
            json!({"cpu_s": 1.0, "gpu_s": 2.0}),
            json!({"cpu_s": 1.0, "gpu_s": 0.5}),
            json!({"cpu_s": 4.0, "gpu_s": 1.0}),
        ];
        let scans = [json!({"cpu_s": 3.0, "gpu_s": 1.0, "device_values_s": 0.5})];
        let e = Entry::from_bench(&h, 16, &traces, &scans).unwrap();
        let t = e.traces.unwrap();
        assert_eq!(t.cases, 3);
        assert!((t.gpu - 2f64.powf(2.0 / 3.0)).abs() < 1e-12, "{}", t.gpu);
        assert_eq!(t.device_values, None);
        let s = e.scans.unwrap();
        assert_eq!(s.cases, 1);
        assert!((s.gpu - 3.0).abs() < 1e-12 && (s.device_values.unwrap() - 6.0).abs() < 1e-12);
        assert_eq!(e.cpu_threads, 16);
        // CPU-only rows (no GPU time) measure nothing.
        let cpu_only = [json!({"cpu_s": 1.0})];
        let e = Entry::from_bench(&h, 2, &cpu_only, &scans).unwrap();
        assert!(e.traces.is_none() && e.scans.is_some());
        assert!(Entry::from_bench(&h, 2, &cpu_only, &[]).is_none());
        let mut lavapipe = adapter("llvmpipe");
        lavapipe.device_type = "Cpu".into();
        assert!(Entry::from_bench(&lavapipe, 2, &traces, &scans).is_none());
    }

    #[test]
    fn the_speedup_is_the_geometric_mean_of_the_ratios() {
        let s = speedup(&[(2.0, 1.0), (1.0, 2.0)]).unwrap();
        assert!((s - 1.0).abs() < 1e-12);
        let s = speedup(&[(4.0, 1.0), (1.0, 1.0)]).unwrap();
        assert!((s - 2.0).abs() < 1e-12);
        assert_eq!(speedup(&[]), None);
        assert_eq!(speedup(&[(1.0, 0.0)]), None);
        assert_eq!(speedup(&[(f64::NAN, 1.0)]), None);
    }

    #[test]
    fn the_file_round_trips_and_a_bad_one_is_a_clear_error() {
        let dir = std::env::temp_dir().join(format!("isomesh-calib-{}", std::process::id()));
        let path = dir.join("sub").join("calibration.toml");
        assert_eq!(Calibration::load(&path).unwrap(), Calibration::default());
        let h = adapter("H200");
        let mut c = Calibration::default();
        c.record(measured(&h, Some(0.5), Some((1.2, 0.9))));
        c.record(measured(&adapter("RTX"), None, Some((2.0, 4.0))));
        c.save(&path).unwrap();
        assert_eq!(Calibration::load(&path).unwrap(), c);
        std::fs::write(&path, "[[adapter]]\nadapter = 3\n").unwrap();
        let e = Calibration::load(&path).unwrap_err().to_string();
        assert!(
            e.contains("calibration file") && e.contains("isomesh bench"),
            "{e}"
        );
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
