// L_p's totals on the device, after the reduction (photometric_gpu/reduce.rs): one thread a
// source adds its rows' records in row order (the sums as double-f32 pairs, `wide_add`; the
// counts as integers), and, where the device selected the patches (`frame.capped` 0), its
// rows' visibility counts too. One record a source comes back instead of one or two a
// (source, row).
//
// Generated before this file: `struct NccFrame` (binding 0), `struct NccRowSums`,
// `struct VisRow`, `struct NccTotals`, and the storage bindings `row_sums`, `vis_rows` and
// `totals`. `pass_.p1` is 1 where the visibility rows are read.

@group(0) @binding(0) var<uniform> frame: NccFrame;

@compute @workgroup_size(256)
fn ncc_totals(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= frame.sources) {
        return;
    }
    var weighted = vec2<f32>(0.0);
    var cost = vec2<f32>(0.0);
    var omega = vec2<f32>(0.0);
    var counts = array<u32, 5>(0u, 0u, 0u, 0u, 0u);
    for (var y = 0u; y < frame.height; y++) {
        let r = row_sums[k * frame.height + y];
        weighted = wide_add(weighted, r.weighted);
        cost = wide_add(cost, r.cost);
        counts[0] += r.inside;
        counts[1] += r.valid;
        if (pass_.p1 == 1u) {
            let v = vis_rows[k * frame.height + y];
            omega = wide_add(omega, v.omega_sum);
            counts[2] += v.upsilon;
            counts[3] += v.omega_positive;
            counts[4] += v.candidates;
        }
    }
    totals[k] = NccTotals(weighted, cost, omega, counts[0], counts[1], counts[2], counts[3], counts[4], 0u);
}
