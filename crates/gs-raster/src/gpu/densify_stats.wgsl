// The densification statistics of one view on the resident model (gpu/resident.rs), the twin
// of gs_core::DensifyStats::accumulate: the same f32 operations in the same order. Runs
// before the Adam kernels, on the backward's screen-space gradients (`grads`) and the last
// render's radii and pixel counts; one Gaussian per thread, chunked like `project`.

fn screen_norm(v: vec2<f32>) -> f32 {
    return sqrt(v.x * v.x + v.y * v.y);
}

// Adds the view's screen-space gradients of each visible Gaussian (radius > 0), counted once
// or, pixel-weighted (`adam.pixel_weighted`), once per pixel it was in front of.
@compute @workgroup_size(256)
fn densify_stats(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let r = radii[i];
    if (r == 0u) {
        return;
    }
    var weight = 1u;
    if (adam.pixel_weighted != 0u) {
        weight = observed[i];
    }
    let gr = grads[i];
    let w = f32(weight);
    var st = stats[i];
    st.grad_sum = st.grad_sum + w * screen_norm(vec2<f32>(gr.mean2d_x, gr.mean2d_y));
    st.abs_grad_sum = st.abs_grad_sum + w * screen_norm(vec2<f32>(gr.mean2d_abs_x, gr.mean2d_abs_y));
    st.visible_count = select(st.visible_count + weight, 0xffffffffu, st.visible_count > 0xffffffffu - weight);
    st.max_radius = max(st.max_radius, f32(r) * adam.radius_scale);
    stats[i] = st;
}
