//! The certified vertex-evaluation stage (`shaders/eval_certified.wgsl`): f at lattice
//! vertices with a bound on the distance to the CPU's value; the twin of
//! [`eval_lattice_certified`](crate::cpu::eval_certified::eval_lattice_certified).

use super::device::Stage;
use super::GpuOracle;
use crate::error::Result;
use crate::gpu::wgsl::certified_shader;
use crate::triangulation::Triangulation;

impl GpuOracle<'_> {
    #[doc(hidden)] // a stage alone, for tests and benchmarks
    /// The certified vertex shader alone: f at the lattice vertices `lattice` (rows of d) of
    /// `tri`, as rows of k pairs (value, bound): the CPU's f64 value of each component lies
    /// within the bound of the value (see [`crate::expr::certified`]; a bound at or above
    /// the precision's [`Accuracy::big`](crate::expr::certified::Accuracy) means unknown).
    pub fn eval_certified_stage(&self, tri: &Triangulation, lattice: &[i32]) -> Result<Vec<f64>> {
        if let Some(seed) = self.emulated() {
            return self.emulated_certified(seed, tri, lattice);
        }
        let pipe = self.f_pipeline(&self.certified, certified_shader, "eval_certified")?;
        self.lattice_stage(Stage::EvalCertified, pipe, tri, lattice, 2 * self.k)
    }
}
