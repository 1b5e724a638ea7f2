//! The certified vertex-evaluation stage (`shaders/eval_certified.wgsl`): f at lattice
//! vertices with a bound on the distance to the CPU's value; the twin of
//! [`eval_lattice_certified`](crate::cpu::eval_certified::eval_lattice_certified).

use super::device::{pipeline, Stage};
use super::GpuOracle;
use crate::error::{Error, Result};
use crate::gpu::wgsl::{certified_shader, Precision};
use crate::triangulation::Triangulation;

impl GpuOracle<'_> {
    fn certified_pipeline(&self) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.certified.get() {
            return Ok(p);
        }
        let Some(system) = self.f.system() else {
            return Err(Error::Gpu(
                "the GPU evaluates only functions written in the equation language".into(),
            ));
        };
        let built = pipeline(
            &self.gpu,
            &certified_shader(system.values(), self.precision)?,
            "eval_certified",
        )?;
        Ok(self.certified.get_or_init(|| built))
    }

    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The certified vertex shader alone: f at the lattice vertices `lattice` (rows of d) of
    /// `tri`, as rows of k pairs (value, bound): the CPU's f64 value of each component lies
    /// within the bound of the value (see [`crate::expr::certified`]; a bound at or above
    /// the precision's [`Accuracy::big`](crate::expr::certified::Accuracy) means unknown).
    pub fn certified_stage(&self, tri: &Triangulation, lattice: &[i32]) -> Result<Vec<f64>> {
        let pipe = self.certified_pipeline()?;
        let (d, k) = (tri.dim(), self.k);
        if self.f.ambient_dim() != d {
            return Err(Error::DimensionMismatch(format!(
                "the triangulation is in R^{d}, f in R^{}",
                self.f.ambient_dim()
            )));
        }
        let exact = match self.precision {
            Precision::F32 => 1 << 24,
            Precision::F64 => i32::MAX,
        };
        if lattice.iter().any(|&u| u.unsigned_abs() > exact as u32) {
            return Err(Error::Gpu(format!(
                "lattice coordinates beyond {exact} do not fit the {} shader exactly",
                self.precision.ty()
            )));
        }
        let (a, b) = tri.affine_map();
        let head: Vec<f64> = a.into_iter().chain(b).collect();
        let rs = self.real_size();
        let chunk = self.chunk(rs * d.max(2 * k));
        let mut values = Vec::with_capacity(lattice.len() / d.max(1) * 2 * k);
        for part in lattice.chunks(chunk * d) {
            let count = part.len() / d;
            let input: Vec<f64> = head
                .iter()
                .copied()
                .chain(part.iter().map(|&u| u as f64))
                .collect();
            let pending = self.submit(
                Stage::Certified,
                pipe,
                &self.encode_reals(&input),
                count,
                &[count * 2 * k * rs],
                false,
            )?;
            values.extend(self.decode_reals(&self.finish(pending)?[0]));
        }
        Ok(values)
    }
}
