// L_f's totals on the device, after every source's reduction (feature_gpu/reduce.rs): one
// thread a source adds its rows' records in row order (the sums as double-f32 pairs,
// `wide_add`; the pairs in V as integers) and, where its υ/ω were made on the device
// (`pass_.p1` 1), the visibility counts of L_p's rows. One record a source comes back instead
// of one or two a (source, row).
//
// Generated before this file: `struct AlignFrame` (binding 0), `struct AlignRowSums`,
// `struct VisRow`, `struct AlignTotals`, and the storage bindings `row_sums` (source-major),
// `vis_rows` (the visibility's, source-major; any buffer where `pass_.p1` is 0) and `totals`.

@group(0) @binding(0) var<uniform> frame: AlignFrame;

@compute @workgroup_size(256)
fn align_totals(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= frame.sources) {
        return;
    }
    var weighted = vec2<f32>(0.0);
    var cosines = vec2<f32>(0.0);
    var omega = vec2<f32>(0.0);
    var counts = array<u32, 3>(0u, 0u, 0u);
    for (var y = 0u; y < frame.height; y++) {
        let r = row_sums[k * frame.height + y];
        weighted = wide_add(weighted, r.weighted);
        cosines = wide_add(cosines, r.cos);
        counts[0] += r.valid;
        if (pass_.p1 == 1u) {
            let v = vis_rows[k * frame.height + y];
            omega = wide_add(omega, v.omega_sum);
            counts[1] += v.upsilon;
            counts[2] += v.omega_positive;
        }
    }
    totals[k] = AlignTotals(weighted, cosines, omega, counts[0], counts[1], counts[2], 0u);
}
