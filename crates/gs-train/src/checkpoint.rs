//! Versioned, checksummed training checkpoints (docs/architecture.md §Errors): the configuration (JSON), the
//! Gaussians, the Adam moments, the densification statistics, the exposure corrections, the
//! wall time spent so far, the memo of source-view plane depths and the 3D smoothing filter's
//! variances, little-endian, followed by
//! a CRC-32 of everything before it. Written atomically (temporary file + rename).

use crate::exposure::Exposure;
use crate::config::TrainConfig;
use crate::densify::DensifyStats;
use crate::error::{Result, TrainError};
use crate::smoothing::Smoothing;
use crate::source_depths::SourceDepths;
use crate::trainer::TrainState;
use gs_core::optim::ParamGroup;
use gs_core::sh::SH_COEFFS;
use gs_core::{Adam, AdamConfig, Gaussians, Image};
use gs_features::weights::crc32;
use std::io::Write;
use std::path::Path;

/// File magic.
pub const MAGIC: &[u8; 8] = b"VAGSLCKP";
/// Format version (3 added the elapsed wall time, 4 the source-depth memo, 5 the 3D smoothing
/// filter's variances).
pub const VERSION: u32 = 5;

/// Wall seconds a run has spent in the training loop so far, per phase (warm-up, photometric
/// L_p, features L_f, refinement). Carried in the checkpoint so that a run resumed over several
/// sessions reports its whole training time, not only the last segment's. It is bookkeeping,
/// not model state: it does not affect the continuation.
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct Elapsed {
    /// Seconds per phase: warm-up, photometric (L_p), features (L_f), refinement.
    pub phase_seconds: [f64; 4],
}

impl Elapsed {
    /// The phase an iteration belongs to (index into `phase_seconds`).
    pub fn phase_of(config: &TrainConfig, iteration: u64) -> usize {
        if iteration <= config.warmup_end {
            0
        } else if iteration <= config.photometric_end {
            1
        } else if iteration <= config.features_end {
            2
        } else {
            3
        }
    }

    /// Adds the seconds that iteration `iteration` took.
    pub fn add(&mut self, config: &TrainConfig, iteration: u64, seconds: f64) {
        self.phase_seconds[Self::phase_of(config, iteration)] += seconds;
    }

    /// Total seconds over all phases.
    pub fn total(&self) -> f64 {
        self.phase_seconds.iter().sum()
    }
}

/// What a checkpoint holds.
#[derive(Debug, Clone)]
pub struct Checkpoint {
    /// The run's configuration (a resumed run uses it).
    pub config: TrainConfig,
    /// Parameters, optimiser and statistics.
    pub state: TrainState,
    /// Wall time spent before the checkpoint; `None` for checkpoints older than version 3.
    pub elapsed: Option<Elapsed>,
}

struct Writer(Vec<u8>);

impl Writer {
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64s(&mut self, v: &[f64]) {
        self.u64(v.len() as u64);
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    fn f32s(&mut self, v: &[f32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    fn u32s(&mut self, v: &[u32]) {
        self.u64(v.len() as u64);
        for x in v {
            self.0.extend_from_slice(&x.to_le_bytes());
        }
    }
    fn bytes(&mut self, b: &[u8]) {
        self.u64(b.len() as u64);
        self.0.extend_from_slice(b);
    }
}

struct Reader<'a> {
    buf: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> std::result::Result<&'a [u8], String> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.buf.len()).ok_or_else(|| {
            format!("truncated: needs {n} bytes at offset {}, file has {}", self.pos, self.buf.len())
        })?;
        let s = &self.buf[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn u32(&mut self) -> std::result::Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().expect("4 bytes")))
    }
    fn u64(&mut self) -> std::result::Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().expect("8 bytes")))
    }
    fn len(&mut self, elem: usize, what: &str) -> std::result::Result<usize, String> {
        let n = self.u64()?;
        let left = (self.buf.len() - self.pos) as u64;
        if n.checked_mul(elem as u64).is_none_or(|b| b > left) {
            return Err(format!("{what}: count {n} exceeds the {left} bytes left"));
        }
        Ok(n as usize)
    }
    fn f32s(&mut self, what: &str) -> std::result::Result<Vec<f32>, String> {
        let n = self.len(4, what)?;
        Ok(self.take(n * 4)?.chunks_exact(4).map(|c| f32::from_le_bytes(c.try_into().expect("4"))).collect())
    }
    fn f64s(&mut self, what: &str) -> std::result::Result<Vec<f64>, String> {
        let n = self.len(8, what)?;
        Ok(self.take(n * 8)?.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().expect("8"))).collect())
    }
    fn u32s(&mut self, what: &str) -> std::result::Result<Vec<u32>, String> {
        let n = self.len(4, what)?;
        Ok(self.take(n * 4)?.chunks_exact(4).map(|c| u32::from_le_bytes(c.try_into().expect("4"))).collect())
    }
    fn bytes(&mut self, what: &str) -> std::result::Result<&'a [u8], String> {
        let n = self.len(1, what)?;
        self.take(n)
    }
}

/// Serialises a checkpoint to bytes.
pub fn encode(config: &TrainConfig, state: &TrainState, elapsed: &Elapsed) -> Vec<u8> {
    let mut w = Writer(Vec::new());
    w.0.extend_from_slice(MAGIC);
    w.u32(VERSION);
    w.bytes(serde_json::to_string(config).expect("config serialises").as_bytes());
    w.u64(state.iteration);
    w.u32(state.capped as u32);
    let g = &state.gaussians;
    w.u32(g.sh_degree);
    w.f32s(g.means.as_flattened());
    // The raw (optimised) log-scales and opacity logits, also while the 3D filter is applied.
    let (log_scales, opacity_logits) = state.smoothing.as_ref().map_or((&g.log_scales[..], &g.opacity_logits[..]), |s| s.raw(g));
    w.f32s(log_scales.as_flattened());
    w.f32s(g.rotations.as_flattened());
    w.f32s(opacity_logits);
    w.f32s(g.sh.as_flattened().as_flattened());
    let a = &state.adam;
    w.f32s(&[a.config.beta1, a.config.beta2, a.config.eps]);
    w.u32(a.groups.len() as u32);
    for grp in &a.groups {
        w.bytes(grp.name.as_bytes());
        w.f32s(&[grp.lr]);
        w.u64(grp.row_width as u64);
        w.u64(grp.step);
        w.f32s(&grp.m);
        w.f32s(&grp.v);
    }
    let s = &state.stats;
    w.f32s(&s.grad_sum);
    w.f32s(&s.abs_grad_sum);
    w.u32s(&s.visible_count);
    w.f32s(&s.max_radius);
    // Version 2: the exposure corrections (absent = 0).
    match &state.exposure {
        None => w.u32(0),
        Some(e) => {
            w.u32(1);
            w.f32s(e.params.as_flattened());
            let g = &e.adam.groups[0];
            w.f32s(&[g.lr]);
            w.u64(g.step);
            w.f32s(&g.m);
            w.f32s(&g.v);
        }
    }
    // Version 3: the wall time spent so far.
    w.f64s(&elapsed.phase_seconds);
    // Version 4: the source-depth memo (slot count, then per slot a flag, iteration, size, depth).
    w.u32(state.source_depths.len() as u32);
    // A depth on the device alone is read back before a checkpoint (`Trainer::checkpoint`
    // pulls); one still there is written as absent (rendered again on resume).
    for entry in state.source_depths.entries() {
        match entry.as_ref().and_then(|(at, d)| Some((at, d.host()?))) {
            None => w.u32(0),
            Some((at, d)) => {
                w.u32(1);
                w.u64(*at);
                w.u64(d.width() as u64);
                w.f32s(d.data());
            }
        }
    }
    // Version 5: the 3D smoothing filter's variances (absent = 0).
    match &state.smoothing {
        None => w.u32(0),
        Some(s) => {
            w.u32(1);
            w.f32s(s.variances());
        }
    }
    let crc = crc32(&w.0);
    w.u32(crc);
    w.0
}

/// Parses a checkpoint; `path` names the file in errors.
pub fn decode(bytes: &[u8], path: &Path) -> Result<Checkpoint> {
    let err = |problem: String| TrainError::Checkpoint { path: path.to_path_buf(), problem };
    if bytes.len() < MAGIC.len() + 8 || &bytes[..8] != MAGIC {
        return Err(err("not a vagsl checkpoint (wrong magic)".into()));
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes(tail.try_into().expect("4 bytes"));
    if crc32(body) != stored {
        return Err(err("checksum mismatch (the file is corrupt or truncated)".into()));
    }
    let mut r = Reader { buf: body, pos: 8 };
    let parse = |r: &mut Reader| -> std::result::Result<Checkpoint, String> {
        let version = r.u32()?;
        if !(1..=VERSION).contains(&version) {
            return Err(format!("format version {version}, this build reads versions 1 to {VERSION}"));
        }
        let config: TrainConfig =
            serde_json::from_slice(r.bytes("config")?).map_err(|e| format!("configuration: {e}"))?;
        let iteration = r.u64()?;
        let capped = r.u32()? != 0;
        let sh_degree = r.u32()?;
        let means = r.f32s("means")?;
        let n = means.len() / 3;
        let log_scales = r.f32s("log_scales")?;
        let rotations = r.f32s("rotations")?;
        let opacity_logits = r.f32s("opacity")?;
        let sh = r.f32s("sh")?;
        if means.len() != n * 3
            || log_scales.len() != n * 3
            || rotations.len() != n * 4
            || opacity_logits.len() != n
            || sh.len() != n * SH_COEFFS * 3
        {
            return Err("Gaussian arrays have inconsistent lengths".into());
        }
        let gaussians = Gaussians {
            means: means.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            log_scales: log_scales.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            rotations: rotations.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect(),
            opacity_logits,
            sh: sh
                .chunks_exact(SH_COEFFS * 3)
                .map(|c| std::array::from_fn(|k| [c[3 * k], c[3 * k + 1], c[3 * k + 2]]))
                .collect(),
            sh_degree,
        };
        let ac = r.f32s("adam config")?;
        if ac.len() != 3 {
            return Err("Adam configuration must have 3 values".into());
        }
        let mut adam = Adam::new(AdamConfig { beta1: ac[0], beta2: ac[1], eps: ac[2] });
        let groups = r.u32()?;
        for _ in 0..groups {
            let name = String::from_utf8(r.bytes("group name")?.to_vec()).map_err(|_| "group name is not UTF-8".to_string())?;
            let lr = r.f32s("group lr")?;
            let row_width = r.u64()? as usize;
            let step = r.u64()?;
            let m = r.f32s("moments")?;
            let v = r.f32s("moments")?;
            // checked: a row width from the file times the count must not wrap to the moments' length.
            if lr.len() != 1 || row_width == 0 || n.checked_mul(row_width) != Some(m.len()) || v.len() != m.len() {
                return Err(format!("optimiser group '{name}' does not match {n} Gaussians"));
            }
            adam.groups.push(ParamGroup { name, lr: lr[0], row_width, step, m, v });
        }
        let stats = DensifyStats {
            grad_sum: r.f32s("stats")?,
            abs_grad_sum: r.f32s("stats")?,
            visible_count: r.u32s("stats")?,
            max_radius: r.f32s("stats")?,
        };
        if stats.grad_sum.len() != n || stats.abs_grad_sum.len() != n || stats.visible_count.len() != n || stats.max_radius.len() != n {
            return Err("densification statistics do not match the Gaussians".into());
        }
        let exposure = if version >= 2 && r.u32()? != 0 {
            let params = r.f32s("exposure")?;
            let lr = r.f32s("exposure lr")?;
            let step = r.u64()?;
            let m = r.f32s("exposure moments")?;
            let v = r.f32s("exposure moments")?;
            if params.len() % 6 != 0 || lr.len() != 1 || m.len() != params.len() || v.len() != params.len() {
                return Err("exposure corrections have inconsistent lengths".into());
            }
            let mut e = Exposure::new(params.len() / 6).map_err(|e| e.to_string())?;
            e.params = params.chunks_exact(6).map(|c| std::array::from_fn(|k| c[k])).collect();
            e.adam.groups[0] = ParamGroup { name: "exposure".into(), lr: lr[0], row_width: 6, step, m, v };
            Some(e)
        } else {
            None
        };
        let elapsed = if version >= 3 {
            let s = r.f64s("elapsed time")?;
            let phase_seconds: [f64; 4] =
                s.try_into().map_err(|_| "elapsed time must have 4 phases".to_string())?;
            if phase_seconds.iter().any(|t| !t.is_finite() || *t < 0.0) {
                return Err(format!("elapsed time {phase_seconds:?} is not a finite, non-negative number of seconds"));
            }
            Some(Elapsed { phase_seconds })
        } else {
            None
        };
        let source_depths = if version >= 4 { read_source_depths(r)? } else { SourceDepths::default() };
        let smoothing = match version >= 5 && r.u32()? != 0 {
            true => Some(Smoothing::new(r.f32s("3D smoothing variances")?).map_err(|e| e.to_string())?),
            false => None,
        };
        if r.pos != r.buf.len() {
            return Err(format!("{} unexpected bytes after the last record", r.buf.len() - r.pos));
        }
        let state = TrainState { iteration, gaussians, adam, stats, capped, exposure, source_depths, smoothing };
        Ok(Checkpoint { config, state, elapsed })
    };
    let ck = parse(&mut r).map_err(err)?;
    ck.state.gaussians.validate().map_err(|e| err(e.to_string()))?;
    ck.config.validate().map_err(|e| err(e.to_string()))?;
    Ok(ck)
}

/// The source-depth memo of a version-4 checkpoint.
fn read_source_depths(r: &mut Reader) -> std::result::Result<SourceDepths, String> {
    let slots = r.u32()? as usize;
    let mut entries = Vec::new();
    for slot in 0..slots {
        if r.u32()? == 0 {
            entries.push(None);
            continue;
        }
        let at = r.u64()?;
        let width = r.u64()? as usize;
        let data = r.f32s("source depth")?;
        if width == 0 || data.is_empty() || data.len() % width != 0 {
            return Err(format!("source depth of training view {slot}: {} values do not fill rows of {width}", data.len()));
        }
        let depth = Image::from_vec(width, data.len() / width, 1, data).map_err(|e| e.to_string())?;
        entries.push(Some((at, depth)));
    }
    Ok(SourceDepths::from_entries(entries))
}

/// Writes a checkpoint atomically.
pub fn save(path: &Path, config: &TrainConfig, state: &TrainState, elapsed: &Elapsed) -> Result<()> {
    let bytes = encode(config, state, elapsed);
    gs_io::write_atomic(path, |w: &mut dyn Write| w.write_all(&bytes))?;
    Ok(())
}

/// Reads and verifies a checkpoint.
pub fn load(path: &Path) -> Result<Checkpoint> {
    decode(&gs_io::capped::CHECKPOINT.read(path)?, path)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_file_over_the_checkpoint_cap_or_a_device_is_refused_unread() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("ck.bin");
        std::fs::File::create(&p).unwrap().set_len(gs_io::capped::CHECKPOINT.bytes + 1).unwrap();
        let e = load(&p).unwrap_err().to_string();
        assert!(e.ends_with("ck.bin: the file holds 40.0 GiB, more than the cap of 40 GiB for a checkpoint"), "{e}");
        let e = load(Path::new("/dev/zero")).unwrap_err().to_string();
        assert_eq!(e, "/dev/zero: it gives more than the cap of 1 GiB for a checkpoint read from a pipe or device");
    }
}
