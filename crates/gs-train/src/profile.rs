//! Where the training time goes: wall seconds per part of an iteration, per phase
//! (docs/architecture.md §Training profile). The executor and the density control time their
//! parts; whatever an iteration spent outside them (planning, the SH band policy) is counted as
//! `other`. On a device it also counts the host–device traffic per iteration (`gs_gpu`'s
//! ledger: syncs, bytes read back and written, submissions). Bookkeeping only: it is not model
//! state, not checkpointed (a resumed run profiles its own segment), and reading the clock
//! never changes what the run computes.

use serde::ser::{Serialize, SerializeMap, Serializer};
use std::time::Instant;

/// A part of an iteration.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Part {
    /// Per-view caches: edge guides, grey images, feature maps, downscaled photos.
    Caches,
    /// The reference view's render (on a device, with the source views' renders submitted
    /// beside it: one wait for all).
    Render,
    /// The source views' plane depths (L_p / L_f) where the memo cannot serve them: on the
    /// CPU their renders, on a device their upkeep alone (upsampling, the memo).
    SourceDepths,
    /// L_I: L1, D-SSIM and the edge term.
    ImageLoss,
    /// L_nc and L_ns.
    NormalLosses,
    /// L_p.
    Photometric,
    /// L_f.
    Features,
    /// The rasterizer's backward pass (and the exposure backward).
    Backward,
    /// Adam, the parameter-space terms (L_o, L_s) and the densification statistics.
    Optimizer,
    /// Density control: densify, prune, trims, opacity reset, floater removal.
    Refine,
}

/// Number of [`Part`]s.
pub const PARTS: usize = 10;

impl Part {
    /// Every part, in report order.
    pub const ALL: [Part; PARTS] = [
        Part::Caches,
        Part::Render,
        Part::SourceDepths,
        Part::ImageLoss,
        Part::NormalLosses,
        Part::Photometric,
        Part::Features,
        Part::Backward,
        Part::Optimizer,
        Part::Refine,
    ];

    /// The part's name in report.json and in words.
    pub fn name(self) -> &'static str {
        match self {
            Part::Caches => "caches",
            Part::Render => "render",
            Part::SourceDepths => "source_depths",
            Part::ImageLoss => "image_loss",
            Part::NormalLosses => "normal_losses",
            Part::Photometric => "photometric",
            Part::Features => "features",
            Part::Backward => "backward",
            Part::Optimizer => "optimizer",
            Part::Refine => "refine",
        }
    }
}

/// The phases of [`crate::checkpoint::Elapsed`], by name.
pub const PHASE_NAMES: [&str; 4] = ["warm-up", "photometric", "features", "refinement"];

/// Seconds per part and whole iterations, per phase, of this process's training.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StepProfile {
    parts: [[f64; PARTS]; 4],
    whole: [f64; 4],
    iterations: [u64; 4],
    /// The host–device traffic per phase (`None`: no device took part).
    #[cfg(feature = "wgpu")]
    transfers: Option<[gs_gpu::Transfers; 4]>,
}

impl StepProfile {
    /// Adds `seconds` of `part` to phase `phase`.
    pub fn add(&mut self, phase: usize, part: Part, seconds: f64) {
        self.parts[phase][part as usize] += seconds;
    }

    /// Counts one whole iteration of phase `phase` that took `seconds`.
    pub fn finish_iteration(&mut self, phase: usize, seconds: f64) {
        self.whole[phase] += seconds;
        self.iterations[phase] += 1;
    }

    /// Adds one iteration's host–device traffic `t` to phase `phase`.
    #[cfg(feature = "wgpu")]
    pub fn add_transfers(&mut self, phase: usize, t: gs_gpu::Transfers) {
        self.transfers.get_or_insert_with(Default::default)[phase] += t;
    }

    /// The mean host–device traffic of one iteration of phase `phase`: syncs, bytes read back,
    /// bytes written and submissions. `None` without a device or when the phase did not run.
    pub fn transfers_per_iteration(&self, phase: usize) -> Option<[f64; 4]> {
        #[cfg(feature = "wgpu")]
        if let Some(t) = &self.transfers
            && self.iterations[phase] > 0
        {
            let (t, n) = (t[phase], self.iterations[phase] as f64);
            return Some([t.syncs, t.bytes_down, t.bytes_up, t.submits].map(|v| v as f64 / n));
        }
        let _ = phase;
        None
    }

    /// Iterations profiled in phase `phase`.
    pub fn iterations(&self, phase: usize) -> u64 {
        self.iterations[phase]
    }

    /// Mean milliseconds per iteration of phase `phase`: each part's, then the rest
    /// (`other`), then the whole. `None` when the phase did not run.
    pub fn per_iteration_ms(&self, phase: usize) -> Option<([f64; PARTS], f64, f64)> {
        let n = self.iterations[phase];
        if n == 0 {
            return None;
        }
        let ms = |s: f64| 1e3 * s / n as f64;
        let parts = self.parts[phase].map(ms);
        let whole = ms(self.whole[phase]);
        let other = (whole - parts.iter().sum::<f64>()).max(0.0);
        Some((parts, other, whole))
    }

    /// One line per phase that ran, in words: its iterations, the time of one, and the parts
    /// that took at least 1 % of it, largest first.
    pub fn describe(&self) -> Vec<String> {
        (0..4)
            .filter_map(|ph| {
                let (parts, other, whole) = self.per_iteration_ms(ph)?;
                let mut named: Vec<(&str, f64)> = Part::ALL.iter().map(|p| p.name()).zip(parts).collect();
                named.push(("other", other));
                named.sort_by(|a, b| b.1.total_cmp(&a.1));
                let shares: Vec<String> = named
                    .iter()
                    .filter(|(_, ms)| whole > 0.0 && *ms >= 0.01 * whole)
                    .map(|(name, ms)| format!("{name} {ms:.1} ms ({:.0} %)", 100.0 * ms / whole))
                    .collect();
                let traffic = match self.transfers_per_iteration(ph) {
                    Some([syncs, down, up, _]) => {
                        format!("; each {syncs:.1} device round trips, {} read back, {} written", bytes_text(down), bytes_text(up))
                    }
                    None => String::new(),
                };
                Some(format!(
                    "{} phase, {} iterations at {whole:.1} ms each: {}{traffic}",
                    PHASE_NAMES[ph],
                    self.iterations[ph],
                    shares.join(", ")
                ))
            })
            .collect()
    }
}

/// `{"warm-up": {"iterations": n, "ms_per_iteration": {"render": …, …, "other": …, "whole": …}}, …}`
/// for the phases that ran.
impl Serialize for StepProfile {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let ran: Vec<usize> = (0..4).filter(|&ph| self.iterations[ph] > 0).collect();
        let mut m = s.serialize_map(Some(ran.len()))?;
        for ph in ran {
            let (parts, other, whole) = self.per_iteration_ms(ph).expect("the phase ran");
            let mut ms: Vec<(&str, f64)> = Part::ALL.iter().map(|p| p.name()).zip(parts).collect();
            ms.extend([("other", other), ("whole", whole)]);
            let traffic = self.transfers_per_iteration(ph).map(|[syncs, down, up, submits]| {
                vec![("syncs", syncs), ("bytes_read_back", down), ("bytes_written", up), ("submissions", submits)]
            });
            let entry = PhaseEntry { iterations: self.iterations[ph], ms_per_iteration: ms, transfers_per_iteration: traffic };
            m.serialize_entry(PHASE_NAMES[ph], &entry)?;
        }
        m.end()
    }
}

struct PhaseEntry<'a> {
    iterations: u64,
    ms_per_iteration: Vec<(&'a str, f64)>,
    /// On a device: syncs, bytes read back and written, submissions, per iteration.
    transfers_per_iteration: Option<Vec<(&'a str, f64)>>,
}

impl Serialize for PhaseEntry<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(None)?;
        m.serialize_entry("iterations", &self.iterations)?;
        m.serialize_entry("ms_per_iteration", &Ordered(&self.ms_per_iteration))?;
        if let Some(t) = &self.transfers_per_iteration {
            m.serialize_entry("transfers_per_iteration", &Ordered(t))?;
        }
        m.end()
    }
}

/// `bytes` in words (B, KB, MB; decimal).
fn bytes_text(bytes: f64) -> String {
    match bytes {
        b if b >= 1e6 => format!("{:.2} MB", b / 1e6),
        b if b >= 1e3 => format!("{:.1} KB", b / 1e3),
        b => format!("{b:.0} B"),
    }
}

/// A list of pairs written as a JSON object in list order.
struct Ordered<'a>(&'a [(&'a str, f64)]);

impl Serialize for Ordered<'_> {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        let mut m = s.serialize_map(Some(self.0.len()))?;
        for (k, v) in self.0 {
            m.serialize_entry(k, v)?;
        }
        m.end()
    }
}

/// A started clock for one part.
pub(crate) struct Clock(Instant);

impl Clock {
    pub(crate) fn start() -> Self {
        Self(Instant::now())
    }

    /// Seconds since the start; restarts the clock.
    pub(crate) fn lap(&mut self) -> f64 {
        let now = Instant::now();
        let s = now.duration_since(self.0).as_secs_f64();
        self.0 = now;
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parts_other_and_whole_per_iteration() {
        let mut p = StepProfile::default();
        assert!(p.per_iteration_ms(1).is_none());
        assert!(p.describe().is_empty());
        for _ in 0..4 {
            p.add(1, Part::Render, 0.010);
            p.add(1, Part::Photometric, 0.030);
            p.finish_iteration(1, 0.050);
        }
        let (parts, other, whole) = p.per_iteration_ms(1).unwrap();
        assert!((parts[Part::Render as usize] - 10.0).abs() < 1e-9);
        assert!((parts[Part::Photometric as usize] - 30.0).abs() < 1e-9);
        assert!((other - 10.0).abs() < 1e-9 && (whole - 50.0).abs() < 1e-9);
        let lines = p.describe();
        assert_eq!(lines.len(), 1);
        assert!(lines[0].starts_with("photometric phase, 4 iterations at 50.0 ms each: photometric 30.0 ms (60 %)"), "{}", lines[0]);
        let v = serde_json::to_value(&p).unwrap();
        assert_eq!(v["photometric"]["iterations"], 4);
        assert!((v["photometric"]["ms_per_iteration"]["whole"].as_f64().unwrap() - 50.0).abs() < 1e-9);
        assert!(v.get("warm-up").is_none());
        let keys: Vec<&String> = v["photometric"]["ms_per_iteration"].as_object().unwrap().keys().collect();
        assert_eq!(keys.len(), PARTS + 2);
    }

    /// On a device the profile counts the host–device traffic per iteration; on the CPU it
    /// has none and says nothing of it.
    #[cfg(feature = "wgpu")]
    #[test]
    fn device_traffic_per_iteration() {
        let mut p = StepProfile::default();
        p.finish_iteration(0, 0.01);
        assert!(p.transfers_per_iteration(0).is_none(), "no device took part");
        assert!(serde_json::to_value(&p).unwrap()["warm-up"].get("transfers_per_iteration").is_none());
        for _ in 0..4 {
            p.add_transfers(1, gs_gpu::Transfers { syncs: 2, bytes_down: 8000, bytes_up: 3_000_000, submits: 6 });
            p.finish_iteration(1, 0.02);
        }
        assert_eq!(p.transfers_per_iteration(1), Some([2.0, 8000.0, 3e6, 6.0]));
        assert!(p.describe()[1].ends_with("; each 2.0 device round trips, 8.0 KB read back, 3.00 MB written"), "{}", p.describe()[1]);
        let v = serde_json::to_value(&p).unwrap();
        assert_eq!(v["photometric"]["transfers_per_iteration"]["bytes_read_back"], 8000.0);
        assert_eq!(v["warm-up"]["transfers_per_iteration"]["syncs"], 0.0);
    }
}
