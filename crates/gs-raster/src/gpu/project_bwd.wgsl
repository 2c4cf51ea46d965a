// Backward of the projection, one Gaussian per thread (chunked like `project`): reads the
// summed screen-space gradients (`ScreenGrad`, per Gaussian) and writes the parameter
// gradients.
// Output record per Gaussian: mean (3), log-scale (3), quaternion (4), opacity logit (1),
// mean2d (2, NDC), mean2d_abs (2, NDC), SH (3 * nc).

fn rotation_matrix_backward(q: vec4<f32>, g: mat3x3<f32>) -> vec4<f32> {
    let n = quat_norm(q);
    if (!(n > 1e-20) || !is_finite(n)) {
        return vec4<f32>(0.0);
    }
    let w = q.x / n;
    let x = q.y / n;
    let y = q.z / n;
    let z = q.w / n;
    // g[c][r] = dL/dR[r][c].
    let dw = 2.0 * (-z * g[1][0] + y * g[2][0] + z * g[0][1] - x * g[2][1] - y * g[0][2] + x * g[1][2]);
    let dx = 2.0 * (y * g[1][0] + z * g[2][0] + y * g[0][1] - 2.0 * x * g[1][1] - w * g[2][1]
        + z * g[0][2] + w * g[1][2] - 2.0 * x * g[2][2]);
    let dy = 2.0 * (-2.0 * y * g[0][0] + x * g[1][0] + w * g[2][0] + x * g[0][1] + z * g[2][1]
        - w * g[0][2] + z * g[1][2] - 2.0 * y * g[2][2]);
    let dz = 2.0 * (-2.0 * z * g[0][0] - w * g[1][0] + x * g[2][0] + w * g[0][1] - 2.0 * z * g[1][1]
        + y * g[2][1] + x * g[0][2] + y * g[1][2]);
    let gq = vec4<f32>(dw, dx, dy, dz);
    let qh = vec4<f32>(w, x, y, z);
    let d = gq.x * qh.x + gq.y * qh.y + gq.z * qh.z + gq.w * qh.w;
    return (gq - qh * d) / n;
}

fn sh_jacobian(k: u32, d: vec3<f32>) -> vec3<f32> {
    let x = d.x;
    let y = d.y;
    let z = d.z;
    let xx = x * x;
    let yy = y * y;
    let zz = z * z;
    switch k {
        case 1u: { return vec3<f32>(0.0, -SH_C1, 0.0); }
        case 2u: { return vec3<f32>(0.0, 0.0, SH_C1); }
        case 3u: { return vec3<f32>(-SH_C1, 0.0, 0.0); }
        case 4u: { return vec3<f32>(C20 * y, C20 * x, 0.0); }
        case 5u: { return vec3<f32>(0.0, C21 * z, C21 * y); }
        case 6u: { return vec3<f32>(-2.0 * C22 * x, -2.0 * C22 * y, 4.0 * C22 * z); }
        case 7u: { return vec3<f32>(C23 * z, 0.0, C23 * x); }
        case 8u: { return vec3<f32>(2.0 * C24 * x, -2.0 * C24 * y, 0.0); }
        case 9u: { return vec3<f32>(C30 * 6.0 * x * y, C30 * (3.0 * xx - 3.0 * yy), 0.0); }
        case 10u: { return vec3<f32>(C31 * y * z, C31 * x * z, C31 * x * y); }
        case 11u: { return vec3<f32>(-2.0 * C32 * x * y, C32 * (4.0 * zz - xx - 3.0 * yy), 8.0 * C32 * y * z); }
        case 12u: { return vec3<f32>(-6.0 * C33 * x * z, -6.0 * C33 * y * z, C33 * (6.0 * zz - 3.0 * xx - 3.0 * yy)); }
        case 13u: { return vec3<f32>(C34 * (4.0 * zz - 3.0 * xx - yy), -2.0 * C34 * x * y, 8.0 * C34 * x * z); }
        case 14u: { return vec3<f32>(2.0 * C35 * x * z, -2.0 * C35 * y * z, C35 * (xx - yy)); }
        case 15u: { return vec3<f32>(C36 * (3.0 * xx - 3.0 * yy), -6.0 * C36 * x * y, 0.0); }
        default: { return vec3<f32>(0.0); }
    }
}

fn normalize_backward(v: vec3<f32>, g: vec3<f32>) -> vec3<f32> {
    let len = sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
    if (len <= 0.0 || !is_finite(len)) {
        return vec3<f32>(0.0);
    }
    let n = v / len;
    let d = n.x * g.x + n.y * g.y + n.z * g.z;
    return (g - n * d) / len;
}

@compute @workgroup_size(256)
fn project_bwd(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    gout[i] = ParamGrad();
    for (var k = 0u; k < cam.nc; k++) {
        gout_sh[i * cam.nc + k] = ShCoeff();
    }
    if (proj[i].radius == 0u) {
        return;
    }
    let r = gacc[i];
    var sg = array<f32, 16>(
        r.mean2d.x, r.mean2d.y, r.conic_a, r.conic_b, r.conic_c, r.opacity,
        r.channels_lo.x, r.channels_lo.y, r.channels_lo.z, r.channels_lo.w,
        r.channels_hi.x, r.channels_hi.y, r.channels_hi.z, r.channels_hi.w,
        r.mean2d_abs.x, r.mean2d_abs.y,
    );
    var nonzero = false;
    for (var k = 0u; k < 16u; k++) {
        nonzero = nonzero || sg[k] != 0.0;
    }
    if (!nonzero) {
        return;
    }
    let pr = read_param(i);
    let it = internals(i, pr);
    if (!it.ok) {
        return;
    }
    let rc = rot_c();
    let t = it.t;
    let inv_z = 1.0 / t.z;
    var g_t = vec3<f32>(0.0);
    g_t.x += sg[0] * cam.fx * inv_z;
    g_t.y += sg[1] * cam.fy * inv_z;
    g_t.z -= (sg[0] * cam.fx * t.x + sg[1] * cam.fy * t.y) * inv_z * inv_z;
    g_t.z += sg[13];
    let g_d = sg[12];
    var g_nc = vec3<f32>(sg[9], sg[10], sg[11]);
    g_nc -= g_d * t;
    g_t -= g_d * it.n_c;
    let g_op = sg[5];
    let g_oraw = g_op * it.comp;
    let g_logit = g_oraw * it.o_raw * (1.0 - it.o_raw);
    let qa = it.conic.x;
    let qb = it.conic.y;
    let qc = it.conic.z;
    let ga = sg[2];
    let gb = 0.5 * sg[3];
    let gc = sg[4];
    let m00 = qa * ga + qb * gb;
    let m01 = qa * gb + qb * gc;
    let m10 = qb * ga + qc * gb;
    let m11 = qb * gb + qc * gc;
    var gcov_a = -(m00 * qa + m01 * qb);
    var gcov_b = -(m00 * qb + m01 * qc);
    var gcov_c = -(m10 * qb + m11 * qc);
    if (cam.antialiased != 0u && !it.comp_floored) {
        let g_comp = g_op * it.o_raw;
        let a = it.cov.x;
        let b = it.cov.y;
        let c = it.cov.z;
        let det_b = it.det;
        let lp = cam.low_pass;
        let det_o = (a - lp) * (c - lp) - b * b;
        let k = 0.5 / it.comp / (det_b * det_b);
        gcov_a += g_comp * k * ((c - lp) * det_b - det_o * c);
        gcov_c += g_comp * k * ((a - lp) * det_b - det_o * a);
        gcov_b += 0.5 * g_comp * k * (-2.0 * b * det_b + 2.0 * b * det_o);
    }
    let gv0 = 2.0 * (gcov_a * it.v0 + gcov_b * it.v1);
    let gv1 = 2.0 * (gcov_b * it.v0 + gcov_c * it.v1);
    let p = it.p;
    let g_j0 = p * gv0;
    let g_j1 = p * gv1;
    let g_p = mat3x3<f32>(
        it.j0 * gv0.x + it.j1 * gv1.x,
        it.j0 * gv0.y + it.j1 * gv1.y,
        it.j0 * gv0.z + it.j1 * gv1.z,
    );
    let g_m = transpose(rc) * g_p;
    var g_rot = mat3x3<f32>(g_m[0] * it.s.x, g_m[1] * it.s.y, g_m[2] * it.s.z);
    let g_log_scale = vec3<f32>(
        dot(g_m[0], it.rot[0]) * it.s.x,
        dot(g_m[1], it.rot[1]) * it.s.y,
        dot(g_m[2], it.rot[2]) * it.s.z,
    );
    let z2 = inv_z * inv_z;
    g_t.z += -g_j0.x * cam.fx * z2 - g_j1.y * cam.fy * z2;
    if (it.clamped_x) {
        let cxz = clamp(t.x * inv_z, -cam.lim_x, cam.lim_x);
        g_t.z += g_j0.z * cam.fx * cxz * z2;
    } else {
        g_t.x += -g_j0.z * cam.fx * z2;
        g_t.z += g_j0.z * 2.0 * cam.fx * t.x * z2 * inv_z;
    }
    if (it.clamped_y) {
        let cyz = clamp(t.y * inv_z, -cam.lim_y, cam.lim_y);
        g_t.z += g_j1.z * cam.fy * cyz * z2;
    } else {
        g_t.y += -g_j1.z * cam.fy * z2;
        g_t.z += g_j1.z * 2.0 * cam.fy * t.y * z2 * inv_z;
    }
    let g_nw = transpose(rc) * g_nc * it.flip;
    g_rot[it.axis] = g_rot[it.axis] + g_nw;
    let g_q = rotation_matrix_backward(pr.quat, g_rot);
    var g_col = vec3<f32>(sg[6], sg[7], sg[8]);
    g_col = select(g_col, vec3<f32>(0.0), it.clamped);
    let len = sqrt(dot(it.dir_raw, it.dir_raw));
    var dir = vec3<f32>(0.0);
    if (len > 0.0) {
        dir = it.dir_raw / len;
    }
    let bs = sh_basis(dir);
    var g_dir = vec3<f32>(0.0);
    for (var k = 0u; k < cam.nc; k++) {
        let c = read_sh(i, k);
        let gs = bs[k] * g_col;
        gout_sh[i * cam.nc + k] = ShCoeff(array<f32, 3>(gs.x, gs.y, gs.z));
        let s = c.x * g_col.x + c.y * g_col.y + c.z * g_col.z;
        g_dir += s * sh_jacobian(k, dir);
    }
    let g_dir_raw = normalize_backward(it.dir_raw, g_dir);
    g_t += rc * g_dir_raw;
    let g_mean = transpose(rc) * g_t;
    let sx = 0.5 * f32(cam.width);
    let sy = 0.5 * f32(cam.height);
    let g_param = ParamRecord(
        array<f32, 3>(g_mean.x, g_mean.y, g_mean.z),
        array<f32, 3>(g_log_scale.x, g_log_scale.y, g_log_scale.z),
        g_q.x, g_q.y, g_q.z, g_q.w,
        g_logit,
    );
    gout[i] = ParamGrad(g_param, sg[0] * sx, sg[1] * sy, sg[14] * sx, sg[15] * sy);
}
