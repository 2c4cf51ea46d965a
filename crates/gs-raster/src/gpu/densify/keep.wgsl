// Whether each of the n Gaussians survives: not a split parent, and past the prune.

@compute @workgroup_size(256)
fn densify_keep(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    let p = params[i];
    let parent = flagged(split_ranks[i + 1u], split_ranks[i]);
    let ok = !parent && survives(p.opacity_logit, log_scale_of(p), stats[i].max_radius > rule.max_screen_radius);
    keep[i] = select(0u, 1u, ok);
}
