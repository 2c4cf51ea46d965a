// Density control on the resident model (gpu/densify.rs), the twin of gs-train's
// `densify_and_prune`: the same tests on the same f32 values, one Gaussian (or one new row)
// per thread. Rows are Gaussians 0..n, then the born rows (clones in index order, then two
// children per split parent in index order), as the host appends them.

@group(0) @binding(0) var<uniform> rule: DensifyRule;

fn is_finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}

// The largest of the three scales, at least 0 (the host's fold from 0).
fn max_scale(log_scale: vec3<f32>) -> f32 {
    let s = exp(log_scale);
    return max(max(max(0.0, s.x), s.y), s.z);
}

fn log_scale_of(p: ParamRecord) -> vec3<f32> {
    return vec3<f32>(p.log_scale[0], p.log_scale[1], p.log_scale[2]);
}

// Whether a row with this opacity logit and log-scale survives the prune (`radius_big`: its
// statistics saw it larger on screen than the limit).
fn survives(logit: f32, log_scale: vec3<f32>, radius_big: bool) -> bool {
    let too_big = rule.prune_big != 0u && (radius_big || max_scale(log_scale) > rule.max_world);
    return !(sigmoid(logit) < rule.min_opacity || too_big);
}

// Whether bit `i` of a scanned flag array was set: the exclusive sums differ.
fn flagged(scanned_next: u32, scanned: u32) -> bool {
    return scanned_next > scanned;
}
