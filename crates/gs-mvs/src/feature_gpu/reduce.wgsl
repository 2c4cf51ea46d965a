// L_f's sums on the device, after `align_pair` (docs/method.md §L_f): the twin of the host's
// `add_source`, one source at a time (`pass_.p1`), so that only each source's totals of the
// row sums (totals.wgsl) and the gradient image come back, not every pair's result.
// - `align_rows`, one thread per row of the source: its pairs in V and the sums of υω·|1 − cos|
//   and of cos over its terms in order (`kahan_add`).
// - `align_scale`, one thread: 1 / (|V|·N) of the source (0 without pairs in V).
// - `align_gradient`, one thread per reference pixel: the source's υω·∂|1 − cos|/∂z_r times
//   its scale added to the pixel's gradient, sources in order as the host adds them.
//
// Generated before this file: `struct AlignFrame` (binding 0), `struct AlignResult`,
// `struct AlignRowSums`, and the storage bindings `results` (the source's pairs, row-major),
// `row_sums` (source-major), `scales` (one per source) and `grads` (one per pixel).

@group(0) @binding(0) var<uniform> frame: AlignFrame;

const NOT_IN_V: u32 = 0u;
const TERM: u32 = 2u;

@compute @workgroup_size(256)
fn align_rows(ids: Ids) {
    let y = thread_1d(ids);
    if (y >= frame.height) {
        return;
    }
    var valid = 0u;
    var weighted = vec2<f32>(0.0);
    var cosines = vec2<f32>(0.0);
    for (var x = 0u; x < frame.width; x++) {
        let r = results[y * frame.width + x];
        if (r.status != NOT_IN_V) {
            valid += 1u;
        }
        if (r.status == TERM) {
            weighted = kahan_add(weighted, r.term);
            cosines = kahan_add(cosines, r.cos);
        }
    }
    row_sums[pass_.p1 * frame.height + y] = AlignRowSums(weighted.x, cosines.x, valid, 0u);
}

@compute @workgroup_size(256)
fn align_scale(ids: Ids) {
    if (thread_1d(ids) != 0u) {
        return;
    }
    let k = pass_.p1;
    var valid = 0u;
    for (var y = 0u; y < frame.height; y++) {
        valid += row_sums[k * frame.height + y].valid;
    }
    scales[k] = select(0.0, 1.0 / (f32(valid) * f32(frame.sources)), valid > 0u);
}

@compute @workgroup_size(256)
fn align_gradient(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.width * frame.height) {
        return;
    }
    let r = results[p];
    if (r.status == TERM) {
        grads[p] += r.grad * scales[pass_.p1];
    }
}
