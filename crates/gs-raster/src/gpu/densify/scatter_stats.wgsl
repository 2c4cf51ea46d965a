// The surviving rows' densification statistics into the next buffer at their scanned places
// (`dest`): removing Gaussians keeps the others' statistics (a densification instead starts
// them again at zero).

@compute @workgroup_size(256)
fn densify_scatter_stats(ids: Ids) {
    let r = thread_1d(ids);
    if (r >= pass_.n || !flagged(dest[r + 1u], dest[r])) {
        return;
    }
    next_stats[dest[r]] = stats[r];
}
