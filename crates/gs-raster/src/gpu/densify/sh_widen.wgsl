// A rise of the SH degree on the resident model (gpu/densify/widen.rs): each Gaussian's
// `rule.nc` coefficients and their moments into rows of `rule.nc_next`, the new ones zero (as
// the host's coefficients above the active degree are).

@compute @workgroup_size(256)
fn sh_widen(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let was = rule.nc;
    let now = rule.nc_next;
    for (var k = 0u; k < now; k++) {
        var value = ShCoeff();
        var m = ShCoeff();
        var v = ShCoeff();
        if (k < was) {
            value = sh[i * was + k];
            m = m_sh[i * was + k];
            v = v_sh[i * was + k];
        }
        next_sh[i * now + k] = value;
        next_m_sh[i * now + k] = m;
        next_v_sh[i * now + k] = v;
    }
}
