//! The test hook of [`GpuOracle::perturb_device_values`]: certified values moved anywhere
//! within their bounds, as a device that rounds otherwise could return them.

use rayon::prelude::*;

use super::GpuOracle;
use crate::error::Result;
use crate::trace::Evaluate;
use crate::triangulation::Triangulation;

impl GpuOracle<'_> {
    /// The hook of [`GpuOracle::perturb_device_values`] on certified pairs `out`.
    pub(super) fn perturb_values(
        &self,
        tri: &Triangulation,
        lattice: &[i32],
        seed: u64,
        out: &mut [f64],
    ) -> Result<()> {
        let (d, k) = (tri.dim(), self.k);
        let mut cpu = vec![0.0; lattice.len() / d * k];
        self.cpu.eval_vertices(tri, lattice, &mut cpu)?;
        out.par_chunks_mut(2 * k)
            .zip(lattice.par_chunks(d))
            .zip(cpu.par_chunks(k))
            .for_each(|((o, v), c)| {
                let mut h = seed;
                for &u in v {
                    h = splitmix(h ^ u as u32 as u64);
                }
                for (j, &cv) in c.iter().enumerate() {
                    h = splitmix(h ^ j as u64);
                    let e = o[2 * j + 1];
                    if !(e.is_finite() && cv.is_finite()) {
                        continue;
                    }
                    let u = (h >> 11) as f64 / (1u64 << 53) as f64;
                    let t = if h & 1 == 0 {
                        (2.0 * u - 1.0) * (1.0 - 2f64.powi(-10))
                    } else {
                        let s = if h & 2 == 0 { 1.0 } else { -1.0 };
                        s * (1.0 - 2f64.powi(-10) * (1.0 + u))
                    };
                    let moved = cv + t * e;
                    o[2 * j] = if (moved - cv).abs() <= e { moved } else { cv };
                }
            });
        Ok(())
    }
}

/// A step of the splitmix64 generator.
fn splitmix(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}
