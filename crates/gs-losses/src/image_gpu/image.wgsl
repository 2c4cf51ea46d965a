// L_I on the device, the twin of `image_loss::image_loss` (docs/method.md §L_I): L1, D-SSIM and
// the edge term with one gradient.
// - D-SSIM: zero-padded separable 11-tap Gaussian blurs, the per-value SSIM and its partials,
//   and the adjoint blurs, passes of one thread per value. Every blur adds its taps in the CPU's
//   order (left to right, top to bottom, skipping taps outside the image).
// - The edge term (`edge_*` passes, when it is on): PGSR's normalised gradient ∇Ĩ, its interior
//   min and max (exact in any order), |∇Ĩ − ∇I| and the coefficients of its backward.
// - `loss_gradient` adds the three gradients in the reference's order: L1's, then SSIM's, then
//   the edge term's.
//
// Generated before this file: `struct ImageFrame` (binding 0), the records `EdgeTexel` and
// `EdgeRange`, and the storage bindings: `images`, the executor's arena, holding a, b and the
// pixel plane ∇I at the frame's offsets; planes of `frame.n` values (or `frame.pixels` for pixel
// planes) in `moments` (5 planes), `partials` (3), `blurred` (3), `values` (SSIM, |a − b|, then
// the pixel plane |∇Ĩ − ∇I|, then three sums a row) and `grad` (1); `edge`, one `EdgeTexel` per
// pixel; `edge_ranges`, the interior's `EdgeRange`, then each range group's.

@group(0) @binding(0) var<uniform> frame: ImageFrame;

// The index of value (or pixel) i in plane k of a buffer of planes.
fn plane_at(k: u32, i: u32) -> u32 {
    return k * frame.n + i;
}

fn sign0(v: f32) -> f32 {
    return select(0.0, 1.0, v > 0.0) - select(0.0, 1.0, v < 0.0);
}

fn tap(k: u32) -> f32 {
    if (k < 4u) {
        return frame.g0[k];
    } else if (k < 8u) {
        return frame.g1[k - 4u];
    }
    return frame.g2[k - 8u];
}

fn product(plane: u32, i: u32) -> f32 {
    let a = images[frame.a_at + i];
    let b = images[frame.b_at + i];
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
                acc += tap(k) * partials[plane_at(plane, j)];
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
        moments[plane_at(plane, i)] = blur_row(plane, i, true);
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
                acc += tap(k) * moments[plane_at(plane, j)];
            } else {
                acc += tap(k) * blurred[plane_at(plane, j)];
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
    values[i] = sv;
    let ds_dmu = 2.0 * mb * num2 / dd - 2.0 * ma * sv / den1;
    let ds_dsab = 2.0 * num1 / dd;
    let ds_dsaa = -sv / den2;
    let wp = frame.wp;
    partials[i] = wp * (ds_dmu - 2.0 * ma * ds_dsaa - mb * ds_dsab);
    partials[plane_at(1u, i)] = wp * ds_dsaa;
    partials[plane_at(2u, i)] = wp * ds_dsab;
}

// Pass 3: horizontal blur of the three partial planes (the blur is self-adjoint).
@compute @workgroup_size(256)
fn blur_partials(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    for (var plane = 0u; plane < 3u; plane++) {
        blurred[plane_at(plane, i)] = blur_row(plane, i, false);
    }
}

fn inside(x: u32, y: u32) -> bool {
    return x >= 1u && y >= 1u && x + 1u < frame.width && y + 1u < frame.height;
}

fn value_at(x: u32, y: u32, k: u32) -> f32 {
    return images[frame.a_at + (y * frame.width + x) * frame.channels + k];
}

// Edge pass 1: the channel means of the central differences, g_x and g_y, of interior pixels.
@compute @workgroup_size(256)
fn edge_raw(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.pixels) {
        return;
    }
    let x = p % frame.width;
    let y = p / frame.width;
    var gx = 0.0;
    var gy = 0.0;
    if (inside(x, y)) {
        for (var k = 0u; k < frame.channels; k++) {
            gx += abs(value_at(x + 1u, y, k) - value_at(x - 1u, y, k));
            gy += abs(value_at(x, y + 1u, k) - value_at(x, y - 1u, k));
        }
    }
    edge[p].gx = gx * frame.inv_c;
    edge[p].gy = gy * frame.inv_c;
}

fn raw(p: u32) -> f32 {
    return max(edge[p].gx, edge[p].gy);
}

var<workgroup> rmin: array<f32, 256>;
var<workgroup> rmax: array<f32, 256>;

// Halves the workgroup's 256 (min, max) pairs down to thread 0's.
fn reduce_range(li: u32) {
    for (var s = 128u; s > 0u; s >>= 1u) {
        workgroupBarrier();
        if (li < s) {
            rmin[li] = min(rmin[li], rmin[li + s]);
            rmax[li] = max(rmax[li], rmax[li + s]);
        }
    }
}

// Edge pass 2: each of `frame.groups` workgroups takes the min and max of max(g_x, g_y) over
// its share of the interior (pixel (1, 1), which is interior, seeds every thread). Min and max
// are exact, so the result does not depend on the order.
@compute @workgroup_size(256)
fn edge_range_groups(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) li: u32) {
    let seed = raw(frame.width + 1u);
    var lo = seed;
    var hi = seed;
    for (var p = wid.x * 256u + li; p < frame.pixels; p += frame.groups * 256u) {
        if (inside(p % frame.width, p / frame.width)) {
            lo = min(lo, raw(p));
            hi = max(hi, raw(p));
        }
    }
    rmin[li] = lo;
    rmax[li] = hi;
    reduce_range(li);
    if (li == 0u) {
        edge_ranges[1u + wid.x] = EdgeRange(rmin[0], rmax[0]);
    }
}

// Edge pass 3: one workgroup folds the groups' ranges into the interior min and max.
@compute @workgroup_size(256)
fn edge_range(@builtin(local_invocation_index) li: u32) {
    var lo = edge_ranges[1u].lo;
    var hi = edge_ranges[1u].hi;
    for (var g = li; g < frame.groups; g += 256u) {
        lo = min(lo, edge_ranges[1u + g].lo);
        hi = max(hi, edge_ranges[1u + g].hi);
    }
    rmin[li] = lo;
    rmax[li] = hi;
    reduce_range(li);
    if (li == 0u) {
        edge_ranges[0] = EdgeRange(rmin[0], rmax[0]);
    }
}

// Edge pass 4: ∇Ĩ = (max(g_x, g_y) − min) / (max − min + ε) inside (1 on the border), the value
// |∇Ĩ − ∇I| and the backward's coefficient on the larger axis (g_x at a tie).
@compute @workgroup_size(256)
fn edge_terms(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.pixels) {
        return;
    }
    let x = p % frame.width;
    let y = p / frame.width;
    let range = edge_ranges[0];
    let inv = 1.0 / (range.hi - range.lo + frame.grad_eps);
    let gx = edge[p].gx;
    let gy = edge[p].gy;
    var grad_map = 1.0;
    if (inside(x, y)) {
        grad_map = (max(gx, gy) - range.lo) * inv;
    }
    let d = grad_map - images[frame.guide_at + p];
    values[plane_at(2u, p)] = abs(d);
    let up = frame.w_edge * sign0(d);
    var cx = 0.0;
    var cy = 0.0;
    if (inside(x, y) && up != 0.0) {
        let scale = inv * frame.inv_c;
        if (gx >= gy) {
            cx = up * scale;
        } else {
            cy = up * scale;
        }
    }
    edge[p].cx = cx;
    edge[p].cy = cy;
}

// ∂(edge term)/∂a at value (x, y, k): the four neighbours whose central differences hold it.
fn edge_backward(x: u32, y: u32, k: u32, v: f32) -> f32 {
    let w = frame.width;
    let p = y * w + x;
    var g = 0.0;
    if (x >= 2u) {
        g += edge[p - 1u].cx * sign0(v - value_at(x - 2u, y, k));
    }
    if (x + 2u < w) {
        g -= edge[p + 1u].cx * sign0(value_at(x + 2u, y, k) - v);
    }
    if (y >= 2u) {
        g += edge[p - w].cy * sign0(v - value_at(x, y - 2u, k));
    }
    if (y + 2u < frame.height) {
        g -= edge[p + w].cy * sign0(value_at(x, y + 2u, k) - v);
    }
    return g;
}

// Last pass: the vertical blur and the chain rule into ∂SSIM/∂a (times its weight), added to
// L1's gradient, then the edge term's; and |a − b| for the host's L1 sum.
@compute @workgroup_size(256)
fn loss_gradient(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= frame.n) {
        return;
    }
    let a = images[frame.a_at + i];
    let b = images[frame.b_at + i];
    values[plane_at(1u, i)] = abs(a - b);
    let b_mu = blur_column(0u, i, false);
    let b_aa = blur_column(1u, i, false);
    let b_ab = blur_column(2u, i, false);
    var g = frame.w_l1 * sign0(a - b) + (b_mu + 2.0 * a * b_aa + b * b_ab);
    if (frame.edge != 0u) {
        let c = frame.channels;
        let p = i / c;
        g += edge_backward(p % frame.width, p / frame.width, i % c, a);
    }
    grad[i] = g;
}

// Compensated f32 sum of `count` entries of `values` from `start`, in order (`kahan_add`).
fn row_sum(start: u32, count: u32) -> f32 {
    var s = vec2<f32>(0.0);
    for (var i = 0u; i < count; i++) {
        s = kahan_add(s, values[start + i]);
    }
    return s.x;
}

// After `loss_gradient`, one thread per image row: the sums of its SSIM values, its |a − b|
// values and (when a guide was given) its pixels' |∇Ĩ − ∇I|, each along the row in order, written
// after the planes, for `image_totals`.
@compute @workgroup_size(256)
fn row_sums(ids: Ids) {
    let y = thread_1d(ids);
    if (y >= frame.height) {
        return;
    }
    let row = frame.width * frame.channels;
    let at = plane_at(2u, frame.pixels) + 3u * y;
    values[at] = row_sum(y * row, row);
    values[at + 1u] = row_sum(plane_at(1u, y * row), row);
    var edge = 0.0;
    if (frame.edge_values != 0u) {
        edge = row_sum(plane_at(2u, y * frame.width), frame.width);
    }
    values[at + 2u] = edge;
}

// Last, one thread: the three sums of every row added in row order as double-f32 pairs
// (`wide_add`), written after the rows' sums as (hi, lo) each. The host reads these six values
// alone (`gs_gpu::wide_value`), not a value a row.
@compute @workgroup_size(256)
fn image_totals(ids: Ids) {
    if (thread_1d(ids) != 0u) {
        return;
    }
    let rows = plane_at(2u, frame.pixels);
    var totals = array<vec2<f32>, 3>(vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0));
    for (var y = 0u; y < frame.height; y++) {
        for (var k = 0u; k < 3u; k++) {
            totals[k] = wide_add(totals[k], values[rows + 3u * y + k]);
        }
    }
    let at = rows + 3u * frame.height;
    for (var k = 0u; k < 3u; k++) {
        values[at + 2u * k] = totals[k].x;
        values[at + 2u * k + 1u] = totals[k].y;
    }
}
