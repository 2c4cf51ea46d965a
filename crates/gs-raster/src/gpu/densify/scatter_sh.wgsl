// The surviving rows' SH coefficients (`rule.nc` each) into the next buffers: a Gaussian's
// with their moments, a born row's copied from its parent with zero moments.

@compute @workgroup_size(256)
fn densify_scatter_sh(ids: Ids) {
    let r = thread_1d(ids);
    if (r >= pass_.n || !flagged(dest[r + 1u], dest[r])) {
        return;
    }
    let nc = rule.nc;
    let d = dest[r] * nc;
    if (r < rule.n) {
        for (var k = 0u; k < nc; k++) {
            next_sh[d + k] = sh[r * nc + k];
            next_m_sh[d + k] = m_sh[r * nc + k];
            next_v_sh[d + k] = v_sh[r * nc + k];
        }
    } else {
        let src = parents[r - rule.n] * nc;
        for (var k = 0u; k < nc; k++) {
            next_sh[d + k] = sh[src + k];
            next_m_sh[d + k] = ShCoeff();
            next_v_sh[d + k] = ShCoeff();
        }
    }
}
