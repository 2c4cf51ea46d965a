// Each Gaussian's candidacy (0 none, 1 clone, 2 split, 3 an AbsGS split, limited later to the
// first `max_abs_splits` in index order) and its score's bits.

fn mean_grad(sum: f32, count: u32) -> f32 {
    if (count > 0u) {
        return sum / f32(count);
    }
    return 0.0;
}

@compute @workgroup_size(256)
fn densify_classify(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let p = params[i];
    let st = stats[i];
    let grad = mean_grad(st.grad_sum, st.visible_count);
    let big = max_scale(log_scale_of(p)) > rule.small_limit;
    var kind = 0u;
    if (grad >= rule.grad_threshold && !big) {
        kind = 1u;
    } else if (grad >= rule.grad_threshold && big) {
        kind = 2u;
    } else if (big && mean_grad(st.abs_grad_sum, st.visible_count) >= rule.abs_grad_threshold && st.max_radius > rule.max_screen_radius) {
        kind = 3u;
    }
    classes[i] = kind;
    abs_flags[i] = select(0u, 1u, kind == 3u);
    let v = f32(max(st.visible_count, 1u));
    let g = st.grad_sum / v / max(rule.grad_threshold, 1.17549435e-38);
    let a = st.abs_grad_sum / v / max(rule.abs_grad_threshold, 1.17549435e-38);
    keys[i] = bitcast<u32>(max(g, a));
}
