//! A rise of the SH degree on the resident model (docs/architecture.md §GPU): each Gaussian's
//! SH coefficients and their moments move into rows of the new degree's width, the new
//! coefficients and moments zero, so the model need not come back to the host and go up again.

use super::DensifyUniform;
use crate::gpu::WgpuRasterizer;
use crate::gpu::kernels::ShCoeff;
use crate::{RasterError, Result};
use gs_core::Gaussians;
use gs_core::sh::coeffs_for_degree;
use gs_gpu::{PassUniform, bytes_of};

impl WgpuRasterizer {
    /// Raises the SH degree of the resident model (of `g`'s size and degree; `g` itself is not
    /// read) to `degree`: the coefficients of the new bands and their moments start at zero,
    /// which is the host's model where its coefficients above the active degree are zero (the
    /// caller's to check). Returns `false`, with the model unchanged, where the new rows do not
    /// fit one storage binding (the host then raises it). A degree not above the resident one
    /// is an error.
    pub fn raise_sh_degree_resident(&mut self, g: &Gaussians, degree: u32) -> Result<bool> {
        let r = self.resident_to_change(g, "raising the SH degree")?;
        if degree <= r.sh_degree || degree > gs_core::sh::MAX_SH_DEGREE {
            return Err(RasterError::InvalidGaussians(format!("an SH degree rise from {} to {degree}", r.sh_degree)));
        }
        let (n, from, to) = (r.n as u64, coeffs_for_degree(r.sh_degree) as u64, coeffs_for_degree(degree) as u64);
        if n * to * bytes_of::<ShCoeff>(1) > self.ctx.max_storage_binding() {
            return Ok(false);
        }
        self.make_densify()?;
        self.scoped(|s| {
            let d = s.densify.as_mut().expect("made above");
            for id in &d.next[3..] {
                s.model.pool.ensure(*id, (n * to).max(1) * bytes_of::<ShCoeff>(1));
            }
            d.disp.write_frame(&DensifyUniform { n: n as u32, nc: from as u32, nc_next: to as u32, ..Default::default() });
            let (m, mp) = (&s.model, |id| s.model.pool.whole(id));
            let mut enc = d.disp.encoder();
            let binds = [mp(m.sh), mp(m.m_sh), mp(m.v_sh), mp(d.next[3]), mp(d.next[4]), mp(d.next[5])];
            d.disp.dispatch_1d(&mut enc, d.kernel("sh_widen"), &binds, PassUniform { n: n as u32, ..Default::default() })?;
            d.disp.submit(enc);
            s.model.swap_sh(&mut d.next[3..], degree);
            Ok(())
        })?;
        Ok(true)
    }
}
