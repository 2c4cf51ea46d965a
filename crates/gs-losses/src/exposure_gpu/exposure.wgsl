// Exposure compensation on the device (exposure_gpu/mod.rs), the twin of `exposure::apply_exposure`
// and `exposure::exposure_backward`, on `[H][W][3]` f32 images:
// - `exposure_apply`, one thread per value: out = gain·c + bias of its channel.
// - `exposure_chain`, one thread per value: out = ∂L/∂c' · gain of its channel (∂L/∂c).
// - `exposure_rows`, one thread per image row: the row's sums of ∂L/∂c'·gain·c and of ∂L/∂c'
//   per channel, along the row in compensated f32; the host adds the rows in order in f64.
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
