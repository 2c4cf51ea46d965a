//! The multi-view trim without its counts crossing (docs/architecture.md §GPU): each training
//! view's render keeps its per-Gaussian pixel counts on the device
//! ([`crate::RenderRequest::observed_on_device`]), a kernel adds one to each Gaussian's view
//! count where the view observed it (densify/views.wgsl), and the trim's keep mask is made from
//! those counts there and scanned for the retain's scatters (gpu/densify/retain.rs). The host
//! reads back the survivors' number alone (4 bytes), where it would read 4 bytes a Gaussian a
//! view.

use crate::gpu::WgpuRasterizer;
use crate::{RasterConfig, RasterError, RenderRequest, Result, TrimOnDevice};
use gs_core::sh::coeffs_for_degree;
use gs_core::{Camera, Gaussians};
use gs_gpu::PassUniform;

impl WgpuRasterizer {
    /// For each Gaussian of the resident model (of `g`'s size and degree; `g` itself is not
    /// read), the number of `cameras` in which it was observed (contributed to a pixel while
    /// T > 0.5), counted on the device and kept there for
    /// [`WgpuRasterizer::retain_observed_resident`]: gs-train's `views_observed`. One render
    /// (and its wait) a camera; no count comes back.
    pub fn count_views_resident(&mut self, g: &Gaussians, cameras: &[&Camera], config: &RasterConfig) -> Result<()> {
        let Some(r) = self.model.residency().filter(|_| self.model.holds(g)) else {
            return Err(RasterError::Gpu("counting views on the device needs the model resident".into()));
        };
        self.make_densify()?;
        let n = r.n as u64;
        let d = self.densify.as_mut().expect("made above");
        self.model.pool.ensure(d.views, 4 * n.max(1));
        self.pool.ensure(d.dest, 4 * (n + 1));
        let mut enc = d.disp.encoder();
        enc.encoder.clear_buffer(self.model.pool.buffer(d.views), 0, None);
        d.disp.submit(enc);
        d.counted = None;
        let req = RenderRequest { color: false, alpha: false, radii: false, observed: true, observed_on_device: true, ..RenderRequest::default() };
        for camera in cameras {
            self.render(g, camera, &req, config)?;
            let d = self.densify.as_ref().expect("made above");
            let mut enc = d.disp.encoder();
            let binds = [self.pool.whole(self.bufs.observed), self.model.pool.whole(d.views), self.pool.whole(d.dest)];
            d.disp.dispatch_1d(&mut enc, d.kernel("densify_count_views"), &binds, PassUniform { n: n as u32, ..Default::default() })?;
            d.disp.submit(enc);
        }
        self.densify.as_mut().expect("made above").counted = Some(r.n);
        Ok(())
    }

    /// The view counts of [`WgpuRasterizer::count_views_resident`], read back (4 bytes a
    /// Gaussian): what the host's rule reads where the device's trim would keep none.
    pub fn read_view_counts(&mut self) -> Result<Vec<u32>> {
        let Some(n) = self.densify.as_ref().and_then(|d| d.counted) else {
            return Err(RasterError::Gpu("no view counts on the device (count them first)".into()));
        };
        let bytes = 4 * n as u64;
        self.pool.ensure(self.bufs.staging, bytes.max(4));
        let d = self.densify.as_ref().expect("counted above");
        let staging = self.pool.buffer(self.bufs.staging);
        let mut enc = d.disp.encoder();
        enc.encoder.copy_buffer_to_buffer(self.model.pool.buffer(d.views), 0, staging, 0, bytes);
        d.disp.submit(enc);
        Ok(self.ctx.read_mapped(staging, bytes, bytemuck::pod_collect_to_vec)?)
    }

    /// The multi-view trim on the resident model (of `g`'s size and degree): keeps the rows
    /// observed in at least `min_views` of the views [`WgpuRasterizer::count_views_resident`]
    /// counted, with their parameters, moments and statistics, as gs-train's `trim_unobserved`
    /// keeps them. The mask is made and scanned on the device; the survivors' number alone
    /// comes back. `None`, with the model unchanged, where the model's buffers do not fit one
    /// storage binding each; an error where the counts are not of this model.
    pub fn retain_observed_resident(&mut self, g: &Gaussians, min_views: u32) -> Result<Option<TrimOnDevice>> {
        let counted = self.densify.as_mut().and_then(|d| d.counted.take());
        let r = self.resident_to_change(g, "the multi-view trim")?;
        if counted != Some(r.n) {
            return Err(RasterError::Gpu("the trim's view counts are not of the resident model (count them first)".into()));
        }
        let (n, nc) = (r.n as u64, coeffs_for_degree(r.sh_degree) as u64);
        if !self.rows_fit(n, nc) {
            return Ok(None);
        }
        let kept = self.scoped(|s| {
            s.scan_mask(n, nc, |s, enc| {
                let d = s.densify.as_ref().expect("made above");
                let binds = [s.pool.whole(s.bufs.observed), s.model.pool.whole(d.views), s.pool.whole(d.dest)];
                Ok(d.disp.dispatch_1d(enc, d.kernel("densify_observed_keep"), &binds, PassUniform { n: n as u32, p1: min_views, ..Default::default() })?)
            })
        })?;
        let done = self.scoped(|s| s.keep_scanned(n, nc, kept))?;
        if done == TrimOnDevice::NoneKept {
            self.densify.as_mut().expect("made above").counted = Some(r.n);
        }
        Ok(Some(done))
    }
}
