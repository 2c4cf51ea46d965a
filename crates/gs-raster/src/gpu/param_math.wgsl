// The activations of a parameter record shared by the projection kernels and density control
// on the device (gs_core::gaussians' sigmoid and rotation_matrix, operation for operation).
// Needs `is_finite` from the sources it is composed with.

fn sigmoid(x: f32) -> f32 {
    if (x >= 0.0) {
        return 1.0 / (1.0 + exp(-x));
    }
    let e = exp(x);
    return e / (1.0 + e);
}

fn quat_norm(q: vec4<f32>) -> f32 {
    return sqrt(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w);
}

// Rotation matrix of (w, x, y, z) after normalisation (identity for a degenerate quaternion),
// glam's `Mat3::from_quat` formula.
fn rotation_matrix(q: vec4<f32>) -> mat3x3<f32> {
    let n = quat_norm(q);
    if (!(n > 1e-20) || !is_finite(n)) {
        return mat3x3<f32>(vec3<f32>(1.0, 0.0, 0.0), vec3<f32>(0.0, 1.0, 0.0), vec3<f32>(0.0, 0.0, 1.0));
    }
    let w = q.x / n;
    let x = q.y / n;
    let y = q.z / n;
    let z = q.w / n;
    let x2 = x + x;
    let y2 = y + y;
    let z2 = z + z;
    let xx = x * x2;
    let xy = x * y2;
    let xz = x * z2;
    let yy = y * y2;
    let yz = y * z2;
    let zz = z * z2;
    let wx = w * x2;
    let wy = w * y2;
    let wz = w * z2;
    return mat3x3<f32>(
        vec3<f32>(1.0 - (yy + zz), xy + wz, xz - wy),
        vec3<f32>(xy - wz, 1.0 - (xx + zz), yz + wx),
        vec3<f32>(xz + wy, yz - wx, 1.0 - (xx + yy)),
    );
}
