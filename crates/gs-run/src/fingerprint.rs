//! Identities of what a run is made of (docs/architecture.md §Runs): the scene's fingerprint
//! (cameras and pixels), the model's fingerprint (every Gaussian parameter) and run ids.

use gs_core::{Gaussians, Scene};
use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};

/// Lower-case hex of `bytes`.
fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// The identity of a loaded scene, so a run is not reopened on another scene: the number of
/// views and sparse points, SHA-256 over every view's name, image size, intrinsics and pose,
/// and SHA-256 over the photos' pixels as loaded (photos swapped between names, or edited,
/// under the same cameras are noticed; the photos are in memory anyway, hashing them costs
/// about a tenth of a second per 100 MB).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SceneFingerprint {
    /// Number of views.
    pub views: usize,
    /// Number of sparse points.
    pub points: usize,
    /// SHA-256 (hex) of the views' names, sizes, intrinsics and poses.
    pub cameras_sha256: String,
    /// SHA-256 (hex) of every view's pixels (f32 bits, in view order); absent in runs
    /// written before it existed, whose pixels then go unchecked.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pixels_sha256: Option<String>,
}

impl SceneFingerprint {
    /// The fingerprint of `scene` as loaded (after any `-r`/`--width`).
    pub fn of(scene: &Scene) -> Self {
        let mut h = Sha256::new();
        for v in &scene.views {
            let c = &v.camera;
            h.update((v.name.len() as u64).to_le_bytes());
            h.update(v.name.as_bytes());
            h.update(c.width.to_le_bytes());
            h.update(c.height.to_le_bytes());
            let k = &c.intrinsics;
            let pose = c.rotation.to_cols_array().into_iter().chain(c.translation.to_array());
            for x in [k.fx, k.fy, k.cx, k.cy].into_iter().chain(pose) {
                h.update(x.to_bits().to_le_bytes());
            }
        }
        let cameras_sha256 = hex(&h.finalize());
        let mut p = Sha256::new();
        for v in &scene.views {
            let bytes: Vec<u8> = v.image.data().iter().flat_map(|x| x.to_le_bytes()).collect();
            p.update(&bytes);
        }
        let pixels_sha256 = Some(hex(&p.finalize()));
        Self { views: scene.views.len(), points: scene.points.len(), cameras_sha256, pixels_sha256 }
    }

    /// How `now` differs from this fingerprint, in words (`None` when it does not; pixels are
    /// compared only when both fingerprints have them).
    pub fn difference(&self, now: &Self) -> Option<String> {
        let pixels_differ = matches!((&self.pixels_sha256, &now.pixels_sha256), (Some(a), Some(b)) if a != b);
        if (self.views, self.points, &self.cameras_sha256) == (now.views, now.points, &now.cameras_sha256) && !pixels_differ {
            None
        } else if self.views != now.views {
            Some(format!("it has {} views, the run's scene had {}", now.views, self.views))
        } else if self.points != now.points {
            Some(format!("it has {} sparse points, the run's scene had {}", now.points, self.points))
        } else if self.cameras_sha256 != now.cameras_sha256 {
            Some(format!("its {} views differ in image names, sizes or cameras", now.views))
        } else {
            Some(format!("its photos' pixels differ under the same {} names and cameras (photos swapped or edited?)", now.views))
        }
    }
}

/// A new run id: 16 hex digits from the clock, the process id and the settings. It only labels
/// the run's files (config.json, report.json) and never reaches the trainer.
pub fn new_run_id(config: &gs_train::TrainConfig) -> String {
    let nanos = std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_nanos());
    let mut h = Sha256::new();
    h.update(nanos.to_le_bytes());
    h.update(std::process::id().to_le_bytes());
    h.update(config.summary().as_bytes());
    hex(&h.finalize()[..8])
}

/// The fingerprint of a model, as written and read back through its PLY: 32 hex digits, the
/// first 128 bits of SHA-256 over the count and the f32 bits of every Gaussian parameter
/// (positions, scales, rotations, opacities and all SH coefficients), so an edit of any of
/// them, colours included, is noticed.
pub fn model_fingerprint(g: &Gaussians) -> String {
    let mut h = Sha256::new();
    h.update((g.len() as u64).to_le_bytes());
    let sh = g.sh.iter().flatten().flatten();
    let floats = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten()).chain(&g.opacity_logits).chain(sh);
    let mut buf = Vec::with_capacity(1 << 16);
    for v in floats {
        buf.extend_from_slice(&v.to_bits().to_le_bytes());
        if buf.len() >= 1 << 16 {
            h.update(&buf);
            buf.clear();
        }
    }
    h.update(&buf);
    hex(&h.finalize()[..16])
}

/// The fingerprint runs recorded before [`model_fingerprint`] covered the SH coefficients:
/// FNV-1a (64 bits, 16 hex digits) of the count and of the f32 bits of the positions, scales,
/// rotations and opacities. Read only to accept the records of those runs.
pub(crate) fn legacy_model_fingerprint(g: &Gaussians) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    };
    eat(&(g.len() as u64).to_le_bytes());
    let floats = g.means.iter().flatten().chain(g.log_scales.iter().flatten()).chain(g.rotations.iter().flatten()).chain(&g.opacity_logits);
    for v in floats {
        eat(&v.to_bits().to_le_bytes());
    }
    format!("{h:016x}")
}

/// Whether the recorded fingerprint `recorded` is that of `g`: [`model_fingerprint`], or for
/// a record of 16 hex digits (written before the SH coefficients were covered), the older form.
pub fn fingerprint_matches(recorded: &str, g: &Gaussians) -> bool {
    if recorded.len() == 16 { recorded == legacy_model_fingerprint(g) } else { recorded == model_fingerprint(g) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use gs_core::sh::SH_COEFFS;

    fn model() -> Gaussians {
        let mut g = Gaussians::default();
        for i in 0..5 {
            let f = i as f32;
            g.push([f, 0.5, -f], [-3.0; 3], [1.0, 0.0, 0.0, 0.0], 0.2 * f, [[0.1 * f; 3]; SH_COEFFS]);
        }
        g
    }

    #[test]
    fn the_model_fingerprint_covers_every_parameter_including_sh() {
        let g = model();
        let base = model_fingerprint(&g);
        assert_eq!(base.len(), 32);
        let edits: [fn(&mut Gaussians); 6] = [
            |g| g.means[1][2] += 1e-3,
            |g| g.log_scales[2][0] += 1e-3,
            |g| g.rotations[3][1] += 1e-3,
            |g| g.opacity_logits[4] += 1e-3,
            |g| g.sh[0][0][1] += 1e-3,
            |g| g.sh[4][SH_COEFFS - 1][2] += 1e-3,
        ];
        for (i, edit) in edits.iter().enumerate() {
            let mut e = g.clone();
            edit(&mut e);
            assert_ne!(model_fingerprint(&e), base, "edit {i} went unnoticed");
        }
        assert!(fingerprint_matches(&base, &g));
    }

    #[test]
    fn records_of_the_older_form_are_still_accepted() {
        let g = model();
        let old = legacy_model_fingerprint(&g);
        assert!(fingerprint_matches(&old, &g));
        let mut e = g.clone();
        e.means[0][0] += 1.0;
        assert!(!fingerprint_matches(&old, &e));
    }
}
