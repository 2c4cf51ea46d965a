// The SH coefficients of the active degree (`adam.nc` a Gaussian): coefficient 0 in the SH DC
// group, the others in the SH rest group.
@compute @workgroup_size(256)
fn adam_sh(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    for (var k = 0u; k < adam.nc; k++) {
        let r = i * adam.nc + k;
        var s = adam.step_sh_rest;
        var c = adam.bc2_sh_rest;
        if (k == 0u) {
            s = adam.step_sh_dc;
            c = adam.bc2_sh_dc;
        }
        var p = sh[r];
        var m = m_sh[r];
        var v = v_sh[r];
        let g = grads_sh[r];
        for (var ch = 0u; ch < 3u; ch++) {
            let a = adam_scalar(p.rgb[ch], m.rgb[ch], v.rgb[ch], g.rgb[ch], s, c);
            p.rgb[ch] = a.x;
            m.rgb[ch] = a.y;
            v.rgb[ch] = a.z;
        }
        sh[r] = p;
        m_sh[r] = m;
        v_sh[r] = v;
    }
}
