//! The nine objects of the validation suite (`crate::suite`), built from `crate::shapes`
//! at a seeded size factor; each rests on the floor (z = 0) near the origin.

use crate::geometry::{Builder, Material};
use crate::shapes::{closed_curve, open_curve};
use glam::{DMat3, DVec3};
use std::f64::consts::{PI, TAU};

fn v(x: f64, y: f64, z: f64) -> DVec3 {
    DVec3::new(x, y, z)
}

/// Scales every profile point by `s`.
fn scaled(profile: &[[f64; 2]], s: f64) -> Vec<[f64; 2]> {
    profile.iter().map(|[r, z]| [r * s, z * s]).collect()
}

/// Suite scene object 'cup' at size factor `s`.
pub(crate) fn cup(b: &mut Builder, s: f64) {
    let (r, h, t, tb) = (0.32 * s, 0.5 * s, 0.025 * s, 0.04 * s);
    let c = v(-0.15 * s, 0.0, 0.0);
    b.lathe(
        c,
        &[
            [0.0, 0.0],
            [r, 0.0],
            [r, h],
            [r - t, h],
            [r - t, tb],
            [0.0, tb],
        ],
        72,
        Material::Part(0),
    );
    // C-shaped handle whose ends sit inside the cup's wall.
    let hc = c + v(r - 0.012 * s, 0.0, 0.5 * h);
    let path = open_curve(24, |u| {
        let a = -PI / 2.0 + PI * u;
        hc + v(0.17 * s * a.cos(), 0.0, 0.17 * s * a.sin())
    });
    b.tube(&path, 0.03 * s, 16, false, Material::Part(1));
    b.sphere(
        v(0.38 * s, -0.4 * s, 0.17 * s),
        0.17 * s,
        (40, 20),
        Material::Part(2),
    );
}

/// Suite scene object 'knot' at size factor `s`.
pub(crate) fn knot(b: &mut Builder, s: f64) {
    let (k, zc, r) = (0.13 * s, 0.62 * s, 0.055 * s);
    let f = |t: f64| {
        let a = TAU * t;
        v(
            k * (a.sin() + 2.0 * (2.0 * a).sin()),
            k * (a.cos() - 2.0 * (2.0 * a).cos()),
            zc - k * (3.0 * a).sin(),
        )
    };
    b.tube(&closed_curve(240, f), r, 16, true, Material::Part(0));
    // Pedestal and a thin post up into the knot's lowest strand (t = 1/12: sin 3a = 1).
    let low = f(1.0 / 12.0);
    let foot = v(low.x, low.y, 0.0);
    b.lathe(
        foot,
        &scaled(&[[0.0, 0.0], [0.22, 0.0], [0.22, 0.05], [0.0, 0.05]], s),
        48,
        Material::Part(1),
    );
    b.tube(
        &[foot + v(0.0, 0.0, 0.04 * s), v(low.x, low.y, low.z)],
        0.025 * s,
        12,
        false,
        Material::Part(2),
    );
}

/// Suite scene object 'window' at size factor `s`.
pub(crate) fn window(b: &mut Builder, s: f64) {
    b.frame(
        v(0.0, 0.1 * s, 0.0),
        0.9 * s,
        0.8 * s,
        0.12 * s,
        [0.5 * s, 0.42 * s, 0.2 * s],
        Material::Part(0),
    );
    b.torus(
        v(0.1 * s, -0.45 * s, 0.07 * s),
        DMat3::IDENTITY,
        0.25 * s,
        0.07 * s,
        (64, 24),
        Material::Part(1),
    );
    b.sphere(
        v(-0.1 * s, 0.6 * s, 0.16 * s),
        0.16 * s,
        (40, 20),
        Material::Part(2),
    );
}

/// Suite scene object 'table' at size factor `s`.
pub(crate) fn table(b: &mut Builder, s: f64) {
    let (hx, hy, top, th) = (0.45 * s, 0.3 * s, 0.5 * s, 0.05 * s);
    b.aabox(v(-hx, -hy, top), v(hx, hy, top + th), Material::Part(0));
    let leg = scaled(&[[0.0, 0.0], [0.025, 0.0], [0.025, 0.5], [0.0, 0.5]], s);
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        b.lathe(
            v(sx * (hx - 0.06 * s), sy * (hy - 0.06 * s), 0.0),
            &leg,
            24,
            Material::Part(1),
        );
    }
    b.lathe(
        v(0.0, 0.0, 0.0),
        &scaled(&[[0.0, 0.0], [0.16, 0.0], [0.0, 0.32]], s),
        48,
        Material::Part(2),
    );
}

/// Suite scene object 'vase' at size factor `s`.
pub(crate) fn vase(b: &mut Builder, s: f64) {
    let profile = [
        [0.0, 0.0],
        [0.2, 0.0],
        [0.28, 0.15],
        [0.3, 0.3],
        [0.2, 0.5],
        [0.1, 0.62],
        [0.17, 0.76],
        [0.15, 0.76],
        [0.08, 0.64],
        [0.0, 0.55],
    ];
    b.lathe(
        v(-0.1 * s, 0.0, 0.0),
        &scaled(&profile, s),
        72,
        Material::Part(0),
    );
    let r = 0.02 * s;
    b.tube(
        &[v(0.4 * s, 0.25 * s, 0.0), v(0.4 * s, 0.25 * s, 0.9 * s)],
        r,
        12,
        false,
        Material::Part(1),
    );
    let rod = 0.025 * s;
    b.tube(
        &[v(-0.55 * s, -0.42 * s, rod), v(0.2 * s, -0.42 * s, rod)],
        rod,
        12,
        false,
        Material::Part(2),
    );
}

/// Suite scene object 'stairs' at size factor `s`.
pub(crate) fn stairs(b: &mut Builder, s: f64) {
    let heights: Vec<f64> = [0.15, 0.3, 0.45, 0.6, 0.45].iter().map(|h| h * s).collect();
    b.stairs(
        v(-0.5 * s, -0.3 * s, 0.0),
        0.2 * s,
        0.5 * s,
        &heights,
        Material::Part(0),
    );
    let arch = open_curve(48, |u| {
        let a = PI * u;
        v(0.35 * s * a.cos(), 0.45 * s, 0.4 * s * a.sin())
    });
    b.tube(&arch, 0.035 * s, 16, false, Material::Part(1));
}

/// Suite scene object 'spring' at size factor `s`.
pub(crate) fn spring(b: &mut Builder, s: f64) {
    let (turns, r, pitch, tr) = (4.5, 0.18 * s, 0.12 * s, 0.03 * s);
    let helix = open_curve(360, |u| {
        let a = TAU * turns * u;
        v(0.32 * s + r * a.cos(), r * a.sin(), tr + pitch * turns * u)
    });
    b.tube(&helix, tr, 14, false, Material::Part(0));
    // Bowl: a spherical shell cut at its equator, resting on its lowest point.
    let (rb, t) = (0.33 * s, 0.02 * s);
    let n = 24;
    let mut profile: Vec<[f64; 2]> = (0..=n)
        .map(|i| {
            let p = 0.5 * PI * i as f64 / n as f64;
            [rb * p.sin(), rb * (1.0 - p.cos())]
        })
        .collect();
    profile.extend((0..=n).rev().map(|i| {
        let p = 0.5 * PI * i as f64 / n as f64;
        [(rb - t) * p.sin(), rb - (rb - t) * p.cos()]
    }));
    b.lathe(v(-0.3 * s, 0.05 * s, 0.0), &profile, 64, Material::Part(1));
}

/// Suite scene object 'pillars' at size factor `s`.
pub(crate) fn pillars(b: &mut Builder, s: f64) {
    let (ring, h, pr) = (0.4 * s, 0.6 * s, 0.03 * s);
    let pillar = [[0.0, 0.0], [pr, 0.0], [pr, h], [0.0, h]];
    for k in 0..6 {
        let a = TAU * k as f64 / 6.0;
        b.lathe(
            v(ring * a.cos(), ring * a.sin(), 0.0),
            &pillar,
            20,
            Material::Part(0),
        );
    }
    let minor = 0.05 * s;
    b.torus(
        v(0.0, 0.0, h + minor),
        DMat3::IDENTITY,
        ring,
        minor,
        (72, 20),
        Material::Part(1),
    );
    b.sphere(v(0.0, 0.0, 0.2 * s), 0.2 * s, (40, 20), Material::Part(2));
}

/// Suite scene object 'chair' at size factor `s`: a seat on four thin legs, a back of three
/// slats between two posts, and a ball under the seat (seen only between the legs).
pub(crate) fn chair(b: &mut Builder, s: f64) {
    let (hx, hy, seat, st) = (0.28 * s, 0.26 * s, 0.42 * s, 0.04 * s);
    b.aabox(v(-hx, -hy, seat), v(hx, hy, seat + st), Material::Part(0));
    let leg = scaled(&[[0.0, 0.0], [0.022, 0.0], [0.022, 0.42], [0.0, 0.42]], s);
    for (sx, sy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
        b.lathe(v(sx * (hx - 0.04 * s), sy * (hy - 0.04 * s), 0.0), &leg, 20, Material::Part(1));
    }
    // The back: two posts at the seat's +y edge and three horizontal slats between them.
    let (post, top) = (0.025 * s, seat + st + 0.5 * s);
    for sx in [-1.0, 1.0] {
        let x = sx * (hx - 0.03 * s);
        b.aabox(v(x - post, hy - 2.0 * post, seat + st), v(x + post, hy, top), Material::Part(0));
    }
    for k in 0..3 {
        let z = seat + st + (0.14 + 0.15 * k as f64) * s;
        b.aabox(v(-hx + 0.03 * s, hy - 0.035 * s, z), v(hx - 0.03 * s, hy - 0.015 * s, z + 0.06 * s), Material::Part(0));
    }
    b.sphere(v(0.05 * s, -0.05 * s, 0.14 * s), 0.14 * s, (40, 20), Material::Part(2));
}
