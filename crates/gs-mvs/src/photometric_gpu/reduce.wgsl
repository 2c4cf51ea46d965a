// L_p's sums on the device, after `ncc_patch` (docs/method.md §L_p): the twin of the host's
// `add_source`, so that only the sums come back, not every patch's result.
// - `ncc_rows`, one thread per (source, row): the row's patches inside the source and valid
//   ones, and the sums of υω·cost and of cost over its valid patches in order (`kahan_add`).
// - `ncc_scales`, one thread per source: 1 / |V| (0 without valid patches).
// - `ncc_gradient`, one thread per reference pixel: its patch of each source in source order
//   (found by binary search in the row's entries), υω·∂cost/∂(Ñ, D)·(1/|V|) added as the host
//   adds them.
//
// Generated before this file: `struct NccFrame` (binding 0), `struct NccResult`,
// `struct NccRowSums`, `struct PlaneGrad`, and the storage bindings `entries` (the reference pixel;
// row-major within each source, sources in order), `results` (one per entry), `weights` (υω of
// each entry), `row_starts` (per source, the first entry of each of its rows and one past its
// last: height + 1 values), `row_sums` (source-major), `scales` (one per source) and `grads`
// (one per pixel).

@group(0) @binding(0) var<uniform> frame: NccFrame;

const INSIDE: u32 = 1u;
const VALID: u32 = 2u;

fn row_start(k: u32, y: u32) -> u32 {
    return row_starts[k * (frame.height + 1u) + y];
}

@compute @workgroup_size(256)
fn ncc_rows(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= frame.sources * frame.height) {
        return;
    }
    let k = t / frame.height;
    let y = t % frame.height;
    var inside = 0u;
    var valid = 0u;
    var weighted = vec2<f32>(0.0);
    var cost = vec2<f32>(0.0);
    for (var i = row_start(k, y); i < row_start(k, y + 1u); i++) {
        let r = results[i];
        if (r.status >= INSIDE) {
            inside += 1u;
        }
        if (r.status == VALID) {
            valid += 1u;
            weighted = kahan_add(weighted, weights[i] * r.cost);
            cost = kahan_add(cost, r.cost);
        }
    }
    row_sums[t] = NccRowSums(weighted.x, cost.x, inside, valid);
}

@compute @workgroup_size(256)
fn ncc_scales(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= frame.sources) {
        return;
    }
    var valid = 0u;
    for (var y = 0u; y < frame.height; y++) {
        valid += row_sums[k * frame.height + y].valid;
    }
    scales[k] = select(0.0, 1.0 / f32(valid), valid > 0u);
}

@compute @workgroup_size(256)
fn ncc_gradient(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.pixels) {
        return;
    }
    let y = p / frame.width;
    var g = array<f32, 4>(0.0, 0.0, 0.0, 0.0);
    for (var k = 0u; k < frame.sources; k++) {
        let end = row_start(k, y + 1u);
        var lo = row_start(k, y);
        var hi = end;
        while (lo < hi) {
            let mid = (lo + hi) / 2u;
            if (entries[mid] < p) {
                lo = mid + 1u;
            } else {
                hi = mid;
            }
        }
        if (lo < end && entries[lo] == p) {
            let r = results[lo];
            if (r.status == VALID) {
                let wt = weights[lo];
                let s = scales[k];
                g[0] += wt * r.grad_n.x * s;
                g[1] += wt * r.grad_n.y * s;
                g[2] += wt * r.grad_n.z * s;
                g[3] += wt * r.grad_d * s;
            }
        }
    }
    grads[p] = PlaneGrad(array<f32, 3>(g[0], g[1], g[2]), g[3]);
}
