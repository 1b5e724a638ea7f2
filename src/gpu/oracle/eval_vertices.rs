//! The vertex-evaluation stage (`shaders/eval_vertices.wgsl`): f at lattice vertices, mapped
//! to R^d inside the shader; the twin of [`eval_lattice`](crate::cpu::eval_vertices::eval_lattice).

use super::device::{pipeline, Stage};
use super::GpuOracle;
use crate::error::{Error, Result};
use crate::gpu::wgsl::{eval_shader, Precision};
use crate::triangulation::Triangulation;

impl GpuOracle<'_> {
    /// The vertex shader's pipeline, built the first time it is asked for.
    fn eval_pipeline(&self) -> Result<&wgpu::ComputePipeline> {
        if let Some(p) = self.eval.get() {
            return Ok(p);
        }
        let Some(system) = self.f.system() else {
            return Err(Error::Gpu(
                "the GPU evaluates only functions written in the equation language".into(),
            ));
        };
        let built = pipeline(
            &self.gpu,
            &eval_shader(system.values(), self.precision)?,
            "eval_vertices",
        )?;
        Ok(self.eval.get_or_init(|| built))
    }

    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The vertex shader alone (`shaders/eval_vertices.wgsl`), the twin of
    /// [`eval_lattice`](crate::cpu::eval_vertices::eval_lattice): f at the lattice vertices
    /// `lattice` (rows of d) of `tri`, mapped to R^d inside the shader; rows of k values.
    /// Tracing does not use it (see the module documentation): it is the building block of
    /// GPU-side scans, and measured by `isomesh bench`.
    pub fn eval_stage(&self, tri: &Triangulation, lattice: &[i32]) -> Result<Vec<f64>> {
        let eval = self.eval_pipeline()?;
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
        let chunk = self.chunk(rs * d.max(k));
        let mut values = Vec::with_capacity(lattice.len() / d.max(1) * k);
        for part in lattice.chunks(chunk * d) {
            let count = part.len() / d;
            let input: Vec<f64> = head
                .iter()
                .copied()
                .chain(part.iter().map(|&u| u as f64))
                .collect();
            let pending = self.submit(
                Stage::Eval,
                eval,
                &self.encode_reals(&input),
                count,
                &[count * k * rs],
                false,
            )?;
            values.extend(self.decode_reals(&self.finish(pending)?[0]));
        }
        Ok(values)
    }
}
