// L_f's gradient image added into the plane-depth gradient the backward reads, times λ4
// (`frame.weight`): `sum[p] += weight * gradient[p]`, the host's `x += w·y` of
// `GradientBuffers::add`, one thread per pixel (docs/architecture.md §GPU).
//
// Generated before this file: `struct AlignFrame` (binding 0) and the storage bindings
// `gradient` and `sum` (the plane-depth gradient added into; `target` is a WGSL keyword) (`[H][W]` f32 each).

@group(0) @binding(0) var<uniform> frame: AlignFrame;

@compute @workgroup_size(256)
fn align_apply(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= pass_.n) {
        return;
    }
    sum[p] += frame.weight * gradient[p];
}
