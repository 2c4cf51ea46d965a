// D-SSIM on the device, the twin of `ssim::ssim_backward` over the whole image
// (docs/method.md §L_I): zero-padded separable 11-tap Gaussian blurs, the per-pixel SSIM and its
// partials, and the adjoint blurs, four passes of one thread per value. Every blur adds its taps
// in the CPU's order (left to right, top to bottom, skipping taps outside the image).
//
// Generated before this file: `struct SsimFrame` (binding 0) and the storage bindings `images`
// (a, then b), `moments` (5 planes), `partials` (3 planes), `blurred` (3 planes), `smap`, `grad`.

@group(0) @binding(0) var<uniform> frame: SsimFrame;

fn tap(k: u32) -> f32 {
    if (k < 4u) {
        return frame.g0[k];
    } else if (k < 8u) {
        return frame.g1[k - 4u];
    }
    return frame.g2[k - 8u];
}

fn product(plane: u32, i: u32) -> f32 {
    let a = images[i];
    let b = images[frame.n + i];
    switch plane {
        case 0u: { return a; }
        case 1u: { return b; }
        case 2u: { return a * a; }
        case 3u: { return b * b; }
        default: { return a * b; }
    }
}

// Horizontal blur of plane `plane` at value i: of the products of a and b (`from_images`), else
// of the partials.
fn blur_row(plane: u32, i: u32, from_images: bool) -> f32 {
    let c = frame.channels;
    let x = i32((i / c) % frame.width);
    var acc = 0.0;
    for (var k = 0u; k < 11u; k++) {
        let xx = x + i32(k) - 5;
        if (xx >= 0 && xx < i32(frame.width)) {
            let j = u32(i32(i) + (xx - x) * i32(c));
            if (from_images) {
                acc += tap(k) * product(plane, j);
            } else {
                acc += tap(k) * partials[plane * frame.n + j];
            }
        }
    }
    return acc;
}

// Pass 1: horizontal blur of a, b, a², b², ab into `moments`.
@compute @workgroup_size(256)
fn blur_rows(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    for (var plane = 0u; plane < 5u; plane++) {
        moments[plane * frame.n + i] = blur_row(plane, i, true);
    }
}

// Vertical blur of plane `plane` at value i (row stride w·c): of the moments, else of the
// blurred partials.
fn blur_column(plane: u32, i: u32, from_moments: bool) -> f32 {
    let row = frame.width * frame.channels;
    let y = i32(i / row);
    var acc = 0.0;
    for (var k = 0u; k < 11u; k++) {
        let yy = y + i32(k) - 5;
        if (yy >= 0 && yy < i32(frame.height)) {
            let j = u32(i32(i) + (yy - y) * i32(row));
            if (from_moments) {
                acc += tap(k) * moments[plane * frame.n + j];
            } else {
                acc += tap(k) * blurred[plane * frame.n + j];
            }
        }
    }
    return acc;
}

// Pass 2: the vertical blur of the moments, the SSIM value and its partials (scaled by wp).
@compute @workgroup_size(256)
fn ssim_values(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    let ma = blur_column(0u, i, true);
    let mb = blur_column(1u, i, true);
    let eaa = blur_column(2u, i, true);
    let ebb = blur_column(3u, i, true);
    let eab = blur_column(4u, i, true);
    let c1 = frame.c1;
    let c2 = frame.c2;
    let saa = eaa - ma * ma;
    let sbb = ebb - mb * mb;
    let sab = eab - ma * mb;
    let num1 = 2.0 * ma * mb + c1;
    let num2 = 2.0 * sab + c2;
    let den1 = ma * ma + mb * mb + c1;
    let den2 = saa + sbb + c2;
    let dd = den1 * den2;
    let sv = num1 * num2 / dd;
    smap[i] = sv;
    let ds_dmu = 2.0 * mb * num2 / dd - 2.0 * ma * sv / den1;
    let ds_dsab = 2.0 * num1 / dd;
    let ds_dsaa = -sv / den2;
    let wp = frame.wp;
    partials[i] = wp * (ds_dmu - 2.0 * ma * ds_dsaa - mb * ds_dsab);
    partials[frame.n + i] = wp * ds_dsaa;
    partials[2u * frame.n + i] = wp * ds_dsab;
}

// Pass 3: horizontal blur of the three partial planes (the blur is self-adjoint).
@compute @workgroup_size(256)
fn blur_partials(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    for (var plane = 0u; plane < 3u; plane++) {
        blurred[plane * frame.n + i] = blur_row(plane, i, false);
    }
}

// Pass 4: the vertical blur and the chain rule into ∂SSIM/∂a (times the weight).
@compute @workgroup_size(256)
fn ssim_gradient(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    let b_mu = blur_column(0u, i, false);
    let b_aa = blur_column(1u, i, false);
    let b_ab = blur_column(2u, i, false);
    grad[i] = b_mu + 2.0 * images[i] * b_aa + images[frame.n + i] * b_ab;
}
