// Exposure compensation on the device (exposure_gpu/mod.rs), the twin of `exposure::apply_exposure`
// and `exposure::exposure_backward`, on `[H][W][3]` f32 images:
// - `exposure_apply`, one thread per value: out = gain·c + bias of its channel.
// - `exposure_chain`, one thread per value: out = ∂L/∂c' · gain of its channel (∂L/∂c).
// - `exposure_rows`, one thread per image row: the row's sums of ∂L/∂c'·gain·c and of ∂L/∂c'
//   per channel, along the row in compensated f32.
// - `exposure_totals`, one thread: the rows added in order (double-f32), what the host reads.
//
// Generated before this file: `struct ExposureFrame` (binding 0), `struct ExposureRow`, and
// the storage bindings `colour` (c), `grad` (∂L/∂c'), `out` and `rows`.

@group(0) @binding(0) var<uniform> frame: ExposureFrame;

@compute @workgroup_size(256)
fn exposure_apply(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n) {
        return;
    }
    let ch = k % 3u;
    out[k] = frame.gain[ch] * colour[k] + frame.bias[ch];
}

@compute @workgroup_size(256)
fn exposure_chain(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n) {
        return;
    }
    out[k] = grad[k] * frame.gain[k % 3u];
}

@compute @workgroup_size(256)
fn exposure_rows(ids: Ids) {
    let y = thread_1d(ids);
    if (y >= frame.height) {
        return;
    }
    var scaled = array<vec2<f32>, 3>(vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0));
    var plain = array<vec2<f32>, 3>(vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0));
    let first = y * frame.width * 3u;
    for (var i = 0u; i < frame.width * 3u; i++) {
        let k = first + i;
        let ch = i % 3u;
        let g = grad[k];
        scaled[ch] = kahan_add(scaled[ch], g * frame.gain[ch] * colour[k]);
        plain[ch] = kahan_add(plain[ch], g);
    }
    rows[y] = ExposureRow(vec4<f32>(scaled[0].x, scaled[1].x, scaled[2].x, 0.0), vec4<f32>(plain[0].x, plain[1].x, plain[2].x, 0.0));
}

// Last, one thread: the rows' six sums added in row order as double-f32 pairs (`wide_add`),
// written after the rows as two records: the pairs' high parts, then their low parts.
@compute @workgroup_size(256)
fn exposure_totals(ids: Ids) {
    if (thread_1d(ids) != 0u) {
        return;
    }
    var sums = array<vec2<f32>, 6>(vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0), vec2<f32>(0.0));
    for (var y = 0u; y < frame.height; y++) {
        let r = rows[y];
        for (var ch = 0u; ch < 3u; ch++) {
            sums[ch] = wide_add(sums[ch], r.scaled[ch]);
            sums[3u + ch] = wide_add(sums[3u + ch], r.plain[ch]);
        }
    }
    rows[frame.height] = ExposureRow(vec4<f32>(sums[0].x, sums[1].x, sums[2].x, 0.0), vec4<f32>(sums[3].x, sums[4].x, sums[5].x, 0.0));
    rows[frame.height + 1u] = ExposureRow(vec4<f32>(sums[0].y, sums[1].y, sums[2].y, 0.0), vec4<f32>(sums[3].y, sums[4].y, sums[5].y, 0.0));
}
