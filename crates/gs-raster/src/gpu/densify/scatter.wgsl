// The surviving rows into the next buffers at their scanned places (`dest`): a Gaussian's
// record and moments as they are, a born row's record with zero moments.

@compute @workgroup_size(256)
fn densify_scatter(ids: Ids) {
    let r = thread_1d(ids);
    if (r >= pass_.n || !flagged(dest[r + 1u], dest[r])) {
        return;
    }
    let d = dest[r];
    if (r < rule.n) {
        next_params[d] = params[r];
        next_m[d] = m_params[r];
        next_v[d] = v_params[r];
    } else {
        next_params[d] = born[r - rule.n];
        next_m[d] = ParamRecord();
        next_v[d] = ParamRecord();
    }
}
