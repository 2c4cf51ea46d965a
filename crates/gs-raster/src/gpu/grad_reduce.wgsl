// Per-Gaussian sum of its per-intersection partial gradients in a fixed order (its emission
// indices ascending), one thread per depth-sorted Gaussian: the same bits on every run, where
// float atomics would add the tiles' shares in whatever order the workgroups finish.
// Windows of emission entries [pass_.shift, pass_.nb) per dispatch (llvmpipe caps an
// invocation at 65535 loop iterations); later windows continue the sum in `gacc`. Culled
// Gaussians (no intersections) get zeros from the first window.

fn add_grad(a: ScreenGrad, b: ScreenGrad) -> ScreenGrad {
    var s = a;
    s.mean2d += b.mean2d;
    s.mean2d_abs += b.mean2d_abs;
    s.conic_a += b.conic_a;
    s.conic_b += b.conic_b;
    s.conic_c += b.conic_c;
    s.opacity += b.opacity;
    s.channels_lo += b.channels_lo;
    s.channels_hi += b.channels_hi;
    return s;
}

@compute @workgroup_size(256)
fn grad_reduce(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n) {
        return;
    }
    let lo = offsets[k];
    let count = offsets[k + 1u] - lo;
    if (pass_.shift > 0u && pass_.shift >= count) {
        return;
    }
    let gid = depth_ids[k];
    var s = ScreenGrad();
    if (pass_.shift > 0u) {
        s = gacc[gid];
    }
    let end = min(count, pass_.nb);
    for (var j = pass_.shift; j < end; j++) {
        s = add_grad(s, partials[isect_pos[lo + j]]);
    }
    gacc[gid] = s;
}
