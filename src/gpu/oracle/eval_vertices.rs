//! The vertex-evaluation stage (`shaders/eval_vertices.wgsl`): f at lattice vertices, mapped
//! to R^d inside the shader; the twin of [`eval_lattice`](crate::cpu::eval_vertices::eval_lattice).

use std::sync::OnceLock;
use std::time::Instant;

use super::device::{add_time, pipeline, Output, Stage};
use super::GpuOracle;
use crate::error::{Error, Result};

use crate::expr::program::Program;
use crate::gpu::wgsl::{eval_shader, Precision};
use crate::triangulation::Triangulation;

impl GpuOracle<'_> {
    /// A pipeline of a shader written for f (`shader` emits it from f's program), built in
    /// `cell` the first time it is asked for.
    pub(super) fn f_pipeline<'a>(
        &self,
        cell: &'a OnceLock<wgpu::ComputePipeline>,
        shader: fn(&Program, Precision) -> Result<String>,
        label: &str,
    ) -> Result<&'a wgpu::ComputePipeline> {
        if let Some(p) = cell.get() {
            return Ok(p);
        }
        let Some(system) = self.f.system() else {
            return Err(Error::Gpu(
                "the GPU evaluates only functions written in the equation language".into(),
            ));
        };
        let built = pipeline(
            &self.gpu,
            &shader(system.values(), self.precision)?,
            label,
            self.cancel(),
        )?;
        Ok(cell.get_or_init(|| built))
    }

    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The vertex shader alone (`shaders/eval_vertices.wgsl`), the twin of
    /// [`eval_lattice`](crate::cpu::eval_vertices::eval_lattice): f at the lattice vertices
    /// `lattice` (rows of d) of `tri`, mapped to R^d inside the shader; rows of k values.
    /// Tracing does not use it (see the module documentation): it is the building block of
    /// GPU-side scans, and measured by `isomesh bench`.
    pub fn eval_vertices_stage(&self, tri: &Triangulation, lattice: &[i32]) -> Result<Vec<f64>> {
        let eval = self.f_pipeline(&self.eval, eval_shader, "eval_vertices")?;
        self.lattice_stage(Stage::EvalVertices, eval, tri, lattice, self.k)
    }

    /// Runs a shader over lattice vertices (`shaders/eval_vertices.wgsl` and
    /// `shaders/eval_certified.wgsl` share its input: A, b, then the rows of `lattice`)
    /// with `outs` reals out per vertex, in chunks that fit one binding.
    pub(super) fn lattice_stage(
        &self,
        stage: Stage,
        pipe: &wgpu::ComputePipeline,
        tri: &Triangulation,
        lattice: &[i32],
        outs: usize,
    ) -> Result<Vec<f64>> {
        let d = tri.dim();
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
        let chunk = self.chunk(rs * d.max(outs));
        let mut values = Vec::with_capacity(lattice.len() / d.max(1) * outs);
        for part in lattice.chunks(chunk * d) {
            let count = part.len() / d;
            let packing = Instant::now();
            let input: Vec<f64> = head
                .iter()
                .copied()
                .chain(part.iter().map(|&u| u as f64))
                .collect();
            let input = self.encode_reals(&input);
            add_time(&self.host_ns, packing);
            let pending = self.submit(
                stage,
                pipe,
                &input,
                count,
                &[Output::read(count * outs * rs)],
                false,
            )?;
            let out = self.finish(pending)?;
            let decoding = Instant::now();
            values.extend(self.decode_reals(&out[0]));
            add_time(&self.host_ns, decoding);
        }
        Ok(values)
    }
}
