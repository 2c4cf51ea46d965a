// The parameters other than SH: means, log-scales, rotation and opacity logit, each with its
// group's step, plus the parameter-space loss terms' own gradients (L_o's on the opacity logit,
// L_s's on the log-scales) when `adam.extra`.
@compute @workgroup_size(256)
fn adam_params(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let gr = grads[i];
    let g = gr.param;
    if (!(is_finite(g.mean[0]) && is_finite(g.mean[1]) && is_finite(g.mean[2]))) {
        atomicOr(&flags[0], 1u);
    }
    var gl = g.log_scale;
    var go = g.opacity_logit;
    if (adam.extra != 0u) {
        let e = extra[i];
        go += e.opacity_logit;
        for (var k = 0u; k < 3u; k++) {
            gl[k] += e.log_scale[k];
        }
    }
    var p = params[i];
    var m = m_params[i];
    var v = v_params[i];
    for (var k = 0u; k < 3u; k++) {
        let a = adam_scalar(p.mean[k], m.mean[k], v.mean[k], g.mean[k], adam.step_means, adam.bc2_means);
        p.mean[k] = a.x;
        m.mean[k] = a.y;
        v.mean[k] = a.z;
        let b = adam_scalar(p.log_scale[k], m.log_scale[k], v.log_scale[k], gl[k], adam.step_log_scales, adam.bc2_log_scales);
        p.log_scale[k] = b.x;
        m.log_scale[k] = b.y;
        v.log_scale[k] = b.z;
    }
    let s = adam.step_rotations;
    let c = adam.bc2_rotations;
    let w = adam_scalar(p.rot_w, m.rot_w, v.rot_w, g.rot_w, s, c);
    let x = adam_scalar(p.rot_x, m.rot_x, v.rot_x, g.rot_x, s, c);
    let y = adam_scalar(p.rot_y, m.rot_y, v.rot_y, g.rot_y, s, c);
    let z = adam_scalar(p.rot_z, m.rot_z, v.rot_z, g.rot_z, s, c);
    p.rot_w = w.x; m.rot_w = w.y; v.rot_w = w.z;
    p.rot_x = x.x; m.rot_x = x.y; v.rot_x = x.z;
    p.rot_y = y.x; m.rot_y = y.y; v.rot_y = y.z;
    p.rot_z = z.x; m.rot_z = z.y; v.rot_z = z.z;
    let o = adam_scalar(p.opacity_logit, m.opacity_logit, v.opacity_logit, go, adam.step_opacity, adam.bc2_opacity);
    p.opacity_logit = o.x;
    m.opacity_logit = o.y;
    v.opacity_logit = o.z;
    params[i] = p;
    m_params[i] = m;
    v_params[i] = v;
}
