// Adam on the resident parameters (gpu/resident.rs), the twin of gs_core::Adam::step_strided
// element for element: m = β1·m + (1 − β1)·g, v = β2·v + (1 − β2)·g², p −= s·m / (√v / c + ε)
// with each group's bias-corrected s and c computed on the host (gs_core::ParamGroup::begin_step).
// One Gaussian per thread, chunked like `project` (the per-Gaussian arrays bound from
// `pass_.base` on). No atomics but the divergence flag (an OR: the same bits in any order).

@group(0) @binding(0) var<uniform> adam: AdamStep;

// One scalar's step: (new parameter, new m, new v).
fn adam_scalar(p: f32, m: f32, v: f32, g: f32, step_size: f32, bc2_sqrt: f32) -> vec3<f32> {
    let m1 = adam.beta1 * m + (1.0 - adam.beta1) * g;
    let v1 = adam.beta2 * v + (1.0 - adam.beta2) * g * g;
    let denom = sqrt(v1) / bc2_sqrt + adam.eps;
    return vec3<f32>(p - step_size * m1 / denom, m1, v1);
}

fn is_finite(v: f32) -> bool {
    return (bitcast<u32>(v) & 0x7f800000u) != 0x7f800000u;
}
