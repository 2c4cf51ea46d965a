// The multi-view trim on the resident model (gpu/densify/views.rs), the twin of gs-train's
// `views_observed` and `observed_enough`:
// - `densify_count_views`, one thread per Gaussian after a render: its count of training views
//   goes up by one where the render counted a pixel it was observed by (`observed` > 0).
// - `densify_observed_keep`, one thread per Gaussian and one more: the keep mask (1 where the
//   Gaussian was observed in at least `pass_.p1` views) and a last zero, for the scan.

@compute @workgroup_size(256)
fn densify_count_views(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    if (observed[i] > 0u) {
        views[i] += 1u;
    }
}

@compute @workgroup_size(256)
fn densify_observed_keep(ids: Ids) {
    let i = thread_1d(ids);
    if (i > pass_.n) {
        return;
    }
    dest[i] = select(0u, select(0u, 1u, views[i] >= pass_.p1), i < pass_.n);
}
