//! The host's rows of a resident model (gpu/resident.rs) and their device records: Adam's
//! moments per [`Param`] group, the densification statistics and the parameters, packed for
//! an upload and stored back from a readback.

use super::kernels::{ParamRecord, ShCoeff};
use super::resident::StatRecord;
use crate::{RasterError, Result};
use gs_core::optim::ParamGroup;
use gs_core::{Adam, DensifyStats, Gaussians, Param};
use rayon::prelude::*;

/// Picks one moment array (m or v) of a group.
pub(super) type Moment = fn(&ParamGroup) -> &[f32];

/// The six groups of `adam` in [`Param::ALL`] order, each checked to hold `n` rows.
pub(super) fn groups_of(adam: &Adam, n: usize) -> Result<[&ParamGroup; 6]> {
    let group = |p: Param| -> Result<&ParamGroup> {
        let g = adam.groups.iter().find(|g| g.name == p.name()).ok_or_else(|| RasterError::Gpu(format!("the optimiser has no group '{}'", p.name())))?;
        if g.row_width != p.row_width() || g.m.len() != n * p.row_width() {
            return Err(RasterError::Gpu(format!("the optimiser's group '{}' holds {} moments, not {} rows of {}", p.name(), g.m.len(), n, p.row_width())));
        }
        Ok(g)
    };
    let [means, dc, rest, opacity, scales, rot] = Param::ALL.map(group);
    Ok([means?, dc?, rest?, opacity?, scales?, rot?])
}

/// Fills `out` with one moment (m or v, `pick`) of the non-SH groups, a `ParamRecord` per
/// Gaussian.
pub(super) fn fill_param_moments(out: &mut [ParamRecord], groups: &[&ParamGroup; 6], pick: Moment) {
    let [means, _, _, opacity, scales, rot] = groups.map(pick);
    out.par_iter_mut().enumerate().for_each(|(i, r)| {
        *r = ParamRecord {
            mean: means[3 * i..3 * i + 3].try_into().expect("3"),
            log_scale: scales[3 * i..3 * i + 3].try_into().expect("3"),
            rot_w: rot[4 * i],
            rot_x: rot[4 * i + 1],
            rot_y: rot[4 * i + 2],
            rot_z: rot[4 * i + 3],
            opacity_logit: opacity[i],
        }
    });
}

/// Fills `out` with one moment (m or v, `pick`) of the SH groups, `nc` `ShCoeff` per Gaussian:
/// coefficient 0 from SH DC, the others from SH rest.
pub(super) fn fill_sh_moments(out: &mut [ShCoeff], groups: &[&ParamGroup; 6], nc: usize, pick: Moment) {
    let (dc, rest, w) = (pick(groups[1]), pick(groups[2]), Param::ShRest.row_width());
    out.par_chunks_mut(nc).enumerate().for_each(|(i, coeffs)| {
        for (k, c) in coeffs.iter_mut().enumerate() {
            let rgb = if k == 0 { &dc[3 * i..3 * i + 3] } else { &rest[w * i + 3 * (k - 1)..w * i + 3 * k] };
            c.rgb = rgb.try_into().expect("3");
        }
    });
}

/// Writes device moment records back into one moment array (m or v) of each of `adam`'s
/// groups; SH coefficients above the active degree keep their host values.
pub(super) fn store_moments(adam: &mut Adam, params: &[ParamRecord], sh: &[ShCoeff], nc: usize, pick: fn(&mut ParamGroup) -> &mut [f32]) -> Result<()> {
    for p in Param::ALL {
        let g = adam.group_mut(p.name()).map_err(|e| RasterError::Gpu(e.to_string()))?;
        let rows = pick(g).par_chunks_mut(p.row_width()).enumerate();
        match p {
            Param::Means => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].mean)),
            Param::LogScales => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].log_scale)),
            Param::Rotations => rows.for_each(|(i, r)| r.copy_from_slice(&params[i].rotation())),
            Param::Opacity => rows.for_each(|(i, r)| r[0] = params[i].opacity_logit),
            Param::ShDc => rows.for_each(|(i, r)| r.copy_from_slice(&sh[i * nc].rgb)),
            Param::ShRest => rows.for_each(|(i, r)| {
                for k in 1..nc {
                    r[3 * (k - 1)..3 * k].copy_from_slice(&sh[i * nc + k].rgb);
                }
            }),
        }
    }
    Ok(())
}

impl StatRecord {
    pub(super) fn of(s: &DensifyStats, i: usize) -> Self {
        Self { grad_sum: s.grad_sum[i], abs_grad_sum: s.abs_grad_sum[i], visible_count: s.visible_count[i], max_radius: s.max_radius[i] }
    }
}

/// Checks that `stats` hold `n` rows.
pub(super) fn check_stats(stats: &DensifyStats, n: usize) -> Result<()> {
    let rows = [stats.grad_sum.len(), stats.abs_grad_sum.len(), stats.visible_count.len(), stats.max_radius.len()];
    if rows.iter().any(|&r| r != n) {
        return Err(RasterError::Gpu(format!("the densification statistics hold {rows:?} rows, not {n}")));
    }
    Ok(())
}

/// The host's statistics from the device's records.
pub(super) fn store_stats(s: &mut DensifyStats, records: &[StatRecord]) {
    let rec = |i: usize| &records[i];
    s.grad_sum.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).grad_sum);
    s.abs_grad_sum.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).abs_grad_sum);
    s.visible_count.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).visible_count);
    s.max_radius.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).max_radius);
}

/// The host's copy of the parameters from the device's records (SH above the active degree
/// untouched).
pub(super) fn store_parameters(g: &mut Gaussians, params: &[ParamRecord], sh: &[ShCoeff], nc: usize) {
    let rec = |i: usize| &params[i];
    g.means.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).mean);
    g.log_scales.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).log_scale);
    g.rotations.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).rotation());
    g.opacity_logits.par_iter_mut().enumerate().for_each(|(i, v)| *v = rec(i).opacity_logit);
    g.sh.par_iter_mut().zip(sh.par_chunks(nc)).for_each(|(c, s)| c.iter_mut().zip(s).for_each(|(c, s)| *c = s.rgb));
}
