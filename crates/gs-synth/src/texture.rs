//! Procedural solid textures evaluated at 3-D hit points: integer-hash value noise, fBm,
//! checkers, fine grain and speckles. Pure functions of the point, so every thread and every
//! view sees the same albedo at the same surface point.

use crate::geometry::Material;
use glam::DVec3;

const M1: u64 = 0x9E37_79B1_85EB_CA87;
const M2: u64 = 0xC2B2_AE3D_27D4_EB4F;
const M3: u64 = 0x1656_67B1_9E37_79F9;
const M4: u64 = 0xFF51_AFD7_ED55_8CCD;
const M5: u64 = 0xC4CE_B9FE_1A85_EC53;

/// Uniform hash of an integer lattice point into `[0, 1)` (one multiply-xorshift finaliser:
/// plenty for texture noise and cheap, since every noise lookup needs eight of them).
#[inline]
fn hash01(ix: i64, iy: i64, iz: i64, seed: u64) -> f64 {
    let mut x =
        (ix as u64).wrapping_mul(M1) ^ (iy as u64).wrapping_mul(M2) ^ (iz as u64).wrapping_mul(M3);
    x ^= seed.wrapping_mul(M5);
    x ^= x >> 32;
    x = x.wrapping_mul(M4);
    x ^= x >> 29;
    (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
}

/// 3-D value noise in `[0, 1]`, C¹-smooth (smoothstep interpolation of lattice hashes).
pub fn value_noise(p: DVec3, seed: u64) -> f64 {
    let f = p.floor();
    let (ix, iy, iz) = (f.x as i64, f.y as i64, f.z as i64);
    let r = p - f;
    let w = r * r * (DVec3::splat(3.0) - 2.0 * r);
    let mut out = 0.0;
    for dz in 0..2 {
        let wz = if dz == 1 { w.z } else { 1.0 - w.z };
        for dy in 0..2 {
            let wy = if dy == 1 { w.y } else { 1.0 - w.y };
            let h0 = hash01(ix, iy + dy, iz + dz, seed);
            let h1 = hash01(ix + 1, iy + dy, iz + dz, seed);
            out += wz * wy * (h0 + (h1 - h0) * w.x);
        }
    }
    out
}

/// Fractal Brownian motion: `octaves` of value noise, frequency ×2.03 and amplitude ×`gain`
/// per octave, normalised to `[0, 1]`.
pub fn fbm(p: DVec3, octaves: u32, seed: u64, gain: f64) -> f64 {
    let (mut total, mut amp, mut norm, mut q) = (0.0, 1.0, 0.0, p);
    for o in 0..octaves {
        total += amp * value_noise(q, seed * 131 + o as u64);
        norm += amp;
        amp *= gain;
        q = q * 2.03 + DVec3::splat(17.17);
    }
    total / norm
}

fn smoothstep(e0: f64, e1: f64, x: f64) -> f64 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

fn contrast(n: f64, k: f64) -> f64 {
    (0.5 + k * (n - 0.5)).clamp(0.0, 1.0)
}

fn checker(a: f64, b: f64, c: f64, size: f64) -> bool {
    ((a / size).floor() as i64 + (b / size).floor() as i64 + (c / size).floor() as i64) & 1 == 1
}

/// Fine grain (periods ≈ 0.1 … 0.025 units at `freq` = 10) times dark speckles: the
/// high-contrast detail that keeps 7×7 NCC patches and SSIM windows textured everywhere.
fn detail(p: DVec3, freq: f64, seed: u64) -> f64 {
    let g = contrast(fbm(p * freq, 3, seed, 0.75), 2.4);
    let sp = smoothstep(0.70, 0.86, value_noise(p * (freq * 1.7), seed + 1000));
    (0.45 + 1.1 * g) * (1.0 - 0.55 * sp)
}

/// Linear-RGB albedo of `material` at world point `p`, in `[0, 0.95]`.
pub fn albedo(material: Material, p: DVec3) -> DVec3 {
    let a = match material {
        Material::Sphere => {
            // Orange ↔ dark red blotches with a bluish drift.
            let n1 = fbm(p * 4.0, 3, 1, 0.5);
            let n3 = fbm(p * 1.7, 2, 3, 0.5);
            let base = DVec3::new(0.85, 0.45, 0.15)
                .lerp(DVec3::new(0.35, 0.06, 0.05), smoothstep(0.38, 0.62, n1));
            let base = base.lerp(
                DVec3::new(0.30, 0.45, 0.62),
                0.5 * smoothstep(0.5, 0.75, n3),
            );
            base * detail(p, 12.0, 2)
        }
        Material::Cuboid => {
            // Solid 3-D checker, white ↔ blue.
            let base = if checker(p.x, p.y, p.z, 0.12) {
                DVec3::new(0.80, 0.80, 0.82)
            } else {
                DVec3::new(0.14, 0.24, 0.60)
            };
            base * detail(p, 11.0, 4)
        }
        Material::Torus => {
            // Green ↔ yellow stripes across the tube, plus blotches.
            let s = (p.dot(DVec3::new(0.8, 0.3, 0.52)) * 9.0).rem_euclid(1.0);
            let stripe = smoothstep(0.35, 0.5, s) - smoothstep(0.85, 1.0, s);
            let base = DVec3::new(0.20, 0.55, 0.18).lerp(DVec3::new(0.85, 0.78, 0.22), stripe);
            let blot = 0.75 + 0.5 * fbm(p * 5.0, 2, 6, 0.5);
            base * blot * detail(p, 12.0, 7)
        }
        Material::Floor => {
            let base = if checker(p.x, p.y, 0.0, 0.3) {
                DVec3::new(0.30, 0.33, 0.38)
            } else {
                DVec3::new(0.72, 0.70, 0.64)
            };
            let broad = fbm(p * 0.6, 2, 5, 0.5);
            let tint = DVec3::new(1.05, 0.95, 0.85).lerp(DVec3::new(0.85, 0.97, 1.08), broad);
            base * tint * detail(p, 10.0, 9)
        }
        Material::Part(k) => part_albedo(k, p, 0),
        Material::Wall(k) => {
            let u = if k < 2 { p.y } else { p.x };
            let tints = [
                DVec3::new(0.75, 0.45, 0.40),
                DVec3::new(0.40, 0.60, 0.45),
                DVec3::new(0.42, 0.50, 0.75),
                DVec3::new(0.75, 0.68, 0.40),
            ];
            let base = tints[k as usize % 4] * if checker(u, p.z, 0.0, 0.5) { 1.0 } else { 0.55 };
            base * detail(p, 7.0, 11)
        }
        Material::Facade(k) => {
            // Panels 0.45 m square along the street (x) and up (z), two shades per tint.
            let tint = DVec3::from_array(FACADE_TINTS[k as usize % FACADE_TINTS.len()]);
            let base = tint
                * if checker(p.x, p.z, 0.0, 0.45) {
                    1.0
                } else {
                    0.6
                };
            base * detail(p, 7.0, 13 + k as u64)
        }
    };
    a.clamp(DVec3::ZERO, DVec3::splat(0.95))
}

/// Specular weight k_s and Blinn-Phong shininess of a material.
pub fn specular(material: Material) -> (f64, f64) {
    match material {
        Material::Sphere => (0.25, 40.0),
        Material::Cuboid => (0.15, 30.0),
        Material::Torus => (0.20, 32.0),
        Material::Floor => (0.10, 24.0),
        Material::Wall(_) => (0.05, 16.0),
        Material::Part(_) => (0.2, 32.0),
        Material::Facade(_) => (0.05, 16.0),
    }
}

/// Tints of the street's facade segments (`Material::Facade(k)`, cycled by `k`).
const FACADE_TINTS: [[f64; 3]; 5] = [
    [0.78, 0.55, 0.42],
    [0.55, 0.62, 0.70],
    [0.80, 0.74, 0.52],
    [0.52, 0.66, 0.50],
    [0.70, 0.50, 0.58],
];

/// Two colours per suite object part (`Material::Part(k)`, cycled by `k`).
const PART_PALETTE: [([f64; 3], [f64; 3]); 6] = [
    ([0.80, 0.50, 0.20], [0.35, 0.10, 0.06]),
    ([0.25, 0.45, 0.75], [0.85, 0.85, 0.80]),
    ([0.30, 0.60, 0.25], [0.80, 0.75, 0.25]),
    ([0.70, 0.30, 0.55], [0.20, 0.18, 0.35]),
    ([0.75, 0.72, 0.62], [0.30, 0.25, 0.20]),
    ([0.20, 0.55, 0.55], [0.75, 0.40, 0.30]),
];

/// Albedo of a suite object part: two-colour fBm blotches times the fine grain and speckles.
fn part_albedo(k: u8, p: DVec3, seed: u64) -> DVec3 {
    let (a, b) = PART_PALETTE[k as usize % PART_PALETTE.len()];
    let s = seed.wrapping_mul(7919).wrapping_add(k as u64 * 101);
    let blot = smoothstep(0.38, 0.62, fbm(p * 4.5, 3, s + 1, 0.5));
    DVec3::from_array(a).lerp(DVec3::from_array(b), blot) * detail(p, 12.0, s + 2)
}

/// The colour a material's texture fades to as its strength goes to 0.
fn mean_albedo(material: Material) -> DVec3 {
    match material {
        Material::Part(k) => {
            let (a, b) = PART_PALETTE[k as usize % PART_PALETTE.len()];
            0.5 * (DVec3::from_array(a) + DVec3::from_array(b))
        }
        Material::Floor => DVec3::new(0.50, 0.50, 0.48),
        Material::Wall(k) => {
            let tints = [
                [0.75, 0.45, 0.40],
                [0.40, 0.60, 0.45],
                [0.42, 0.50, 0.75],
                [0.75, 0.68, 0.40],
            ];
            0.78 * DVec3::from_array(tints[k as usize % 4])
        }
        Material::Facade(k) => {
            0.8 * DVec3::from_array(FACADE_TINTS[k as usize % FACADE_TINTS.len()])
        }
        Material::Sphere => DVec3::new(0.6, 0.3, 0.12),
        Material::Cuboid => DVec3::new(0.47, 0.52, 0.71),
        Material::Torus => DVec3::new(0.5, 0.66, 0.2),
    }
}

/// Albedo of `material` at `p` under a style's texture strengths: [`albedo`] (or a suite
/// part's texture) blended towards the material's mean colour; exactly [`albedo`] for the
/// built-in materials at strength 1.
pub fn albedo_styled(material: Material, p: DVec3, style: &crate::render::Style) -> DVec3 {
    let (a, strength) = match material {
        Material::Part(k) => (
            part_albedo(k, p, style.texture_seed),
            style.texture_strength,
        ),
        Material::Floor | Material::Wall(_) => (albedo(material, p), style.background_strength),
        _ => (albedo(material, p), style.texture_strength),
    };
    if strength >= 1.0 {
        return a.clamp(DVec3::ZERO, DVec3::splat(0.95));
    }
    let m = mean_albedo(material);
    (m + (a - m) * strength.max(0.0)).clamp(DVec3::ZERO, DVec3::splat(0.95))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_in_range_and_varies() {
        let mut lo: f64 = 1.0;
        let mut hi: f64 = 0.0;
        for i in 0..2000 {
            let p = DVec3::new(i as f64 * 0.137, -(i as f64) * 0.071, (i % 17) as f64 * 0.3);
            let n = fbm(p, 3, 1, 0.6);
            assert!((0.0..=1.0).contains(&n));
            lo = lo.min(n);
            hi = hi.max(n);
        }
        assert!(hi - lo > 0.4, "fbm range {lo}..{hi}");
        // Continuity: a tiny step changes the value by a tiny amount.
        let p = DVec3::new(0.3, 1.7, -2.2);
        assert!((value_noise(p, 3) - value_noise(p + DVec3::splat(1e-7), 3)).abs() < 1e-5);
        // Lattice values are hashes, not constant.
        assert_ne!(value_noise(DVec3::ZERO, 1), value_noise(DVec3::X, 1));
    }

    #[test]
    fn albedo_is_bounded_for_every_material() {
        let mats = [
            Material::Sphere,
            Material::Cuboid,
            Material::Torus,
            Material::Floor,
            Material::Wall(0),
            Material::Wall(3),
            Material::Facade(0),
            Material::Facade(7),
        ];
        for m in mats {
            for i in 0..200 {
                let p = DVec3::new(
                    (i as f64 * 0.377).sin() * 3.0,
                    (i as f64 * 0.123).cos() * 3.0,
                    i as f64 * 0.01,
                );
                let a = albedo(m, p);
                assert!(
                    a.min_element() >= 0.0 && a.max_element() <= 0.95,
                    "{m:?} {a}"
                );
            }
        }
    }
}
