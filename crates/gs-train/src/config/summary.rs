//! The configuration in words, for the start-up line of `vagsl train`: the schedule, the
//! terms, and every setting that differs from the preset it started from.

use super::TrainConfig;
use crate::terms::term_name;

impl TrainConfig {
    /// A one-paragraph description for people (no Rust syntax).
    pub fn summary(&self) -> String {
        let l = &self.losses;
        let mut s = format!("preset {}, {} iterations: colour warm-up to {}", self.preset, self.iterations, self.warmup_end);
        s.push_str(&self.phases_after_warmup());
        s.push_str(&format!(
            "; seed {}; {} source views, {p}×{p} NCC patches ({})",
            self.seed,
            self.source_views,
            self.ncc,
            p = self.patch_size
        ));
        if self.multiview_interval > 1 {
            s.push_str(&format!("; L_p/L_f every {} iterations", self.multiview_interval));
        }
        if self.source_depth_downscale > 1 {
            s.push_str(&format!("; source depths at 1/{} size", self.source_depth_downscale));
        }
        let c2f = &self.coarse_to_fine;
        if c2f.levels > 0 && c2f.until > 0 {
            s.push_str(&format!("; coarse-to-fine from 1/{} size to full by {}", 1u32 << c2f.levels, c2f.until));
        }
        let off: Vec<&str> = l.named().into_iter().filter_map(|(name, on)| (!on).then_some(name)).collect();
        if !off.is_empty() {
            s.push_str(&format!("; off: {}", off.join(", ")));
        }
        let changed = self.changed_from_preset();
        if !changed.is_empty() {
            s.push_str(&format!("; changed from the preset: {}", changed.join(", ")));
        }
        s
    }

    /// The terms after the colour warm-up and the iteration each one ends at (docs/method.md §Schedule):
    /// edge, L_nc, L_ns and L_o run to the last iteration; L_p to `photometric_end`, L_f from there
    /// to `features_end` (with L_p when `overlap_mv`).
    fn phases_after_warmup(&self) -> String {
        let l = &self.losses;
        let n = self.iterations;
        let geometry: Vec<&str> = l
            .geometry_terms()
            .into_iter()
            .chain([(term_name::OPACITY, self.weights.lambda_o > 0.0)])
            .filter_map(|(name, on)| on.then_some(name))
            .collect();
        let p_end = self.photometric_end.min(n);
        let photometric = l.photometric && p_end > self.warmup_end;
        let features = self.has_feature_phase() && p_end < n;
        let mut parts = Vec::new();
        if photometric && p_end == n {
            parts.push(format!("{} to {n}", [geometry.as_slice(), &[term_name::PHOTOMETRIC]].concat().join(" + ")));
        } else {
            if !geometry.is_empty() {
                parts.push(format!("{} to {n}", geometry.join(" + ")));
            }
            if photometric {
                parts.push(format!("{} to {p_end}", term_name::PHOTOMETRIC));
            }
            if features {
                let with_p = if self.overlap_mv && l.photometric { format!(" + {}", term_name::PHOTOMETRIC) } else { String::new() };
                parts.push(format!("{}{with_p} from {p_end} to {}", term_name::FEATURES, self.features_end.min(n)));
            }
        }
        if parts.is_empty() { String::new() } else { format!(", then {}", parts.join(", ")) }
    }

    /// `key value (preset value)` for every setting that differs from the preset scaled to
    /// this length (switches of the loss terms are listed by [`TrainConfig::summary`] instead).
    pub fn changed_from_preset(&self) -> Vec<String> {
        let mut base = TrainConfig::preset(self.preset);
        if base.iterations != self.iterations {
            base = base.scaled(self.iterations);
        }
        let base: std::collections::HashMap<String, serde_json::Value> = base.settings().into_iter().collect();
        self.settings()
            .into_iter()
            .filter(|(k, v)| !k.starts_with("losses.") && k != "seed" && base.get(k) != Some(v))
            .map(|(k, v)| format!("{k} {} (preset {})", show(&v), base.get(&k).map_or("none".into(), show)))
            .collect()
    }
}

/// A setting's value as written by hand: an f32 stored through f64 prints as the f32 it is.
fn show(v: &serde_json::Value) -> String {
    match v.as_f64() {
        Some(x) if !v.is_i64() && !v.is_u64() && (x as f32) as f64 == x => format!("{}", x as f32),
        _ => v.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::super::{Preset, TrainConfig};

    #[test]
    fn the_summary_is_words() {
        let c = TrainConfig::default().scaled(60);
        let s = c.summary();
        assert!(s.starts_with("preset dtu, 60 iterations: colour warm-up to 21, then edge + L_nc + L_ns to 60, L_p to 45, L_f from 45 to 60;"), "{s}");
        let std = TrainConfig::preset(Preset::Standard).summary();
        assert!(std.contains("colour warm-up to 560, then edge + L_nc + L_ns + L_p to 1600;"), "{std}");
        // L_p ended early with no L_f phase: the normal terms still run to the end.
        let tail = TrainConfig { photometric_end: 1200, features_end: 1200, ..TrainConfig::preset(Preset::Standard) };
        assert!(tail.summary().contains("then edge + L_nc + L_ns to 1600, L_p to 1200;"), "{}", tail.summary());
        assert!(!s.contains('{') && !s.contains("changed"), "{s}");
        let d = TrainConfig { seed: 4, ..TrainConfig::preset(Preset::Fast) }.with_assignment("weights.lambda_p=0.3").unwrap();
        let mut d = d;
        d.losses.features = false;
        let s = d.summary();
        assert!(s.contains("off: L_f") && s.contains("weights.lambda_p 0.3 (preset 0.15)") && s.contains("seed 4"), "{s}");
    }
}
