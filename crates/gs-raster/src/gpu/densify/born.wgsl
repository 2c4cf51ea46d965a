// The born rows, from their parents' records (densify/parents.wgsl): the position the host
// sampled (`means`, 3 per row in row order), the split children's log-scales less the split
// divisor's log; and whether each survives the prune (`keep` from row `rule.n` on; rows past
// the born count, up to the reserved `pass_.n`, are not kept).

@compute @workgroup_size(256)
fn densify_born(ids: Ids) {
    let b = thread_1d(ids);
    if (b > pass_.n) {
        return;
    }
    let clones = clone_ranks[rule.n];
    let count = clones + 2u * split_ranks[rule.n];
    if (b >= count) {
        keep[rule.n + b] = 0u;
        return;
    }
    var p = born[b];
    p.mean = array<f32, 3>(means[3u * b], means[3u * b + 1u], means[3u * b + 2u]);
    if (b >= clones) {
        p.log_scale = array<f32, 3>(p.log_scale[0] - rule.shrink, p.log_scale[1] - rule.shrink, p.log_scale[2] - rule.shrink);
    }
    born[b] = p;
    keep[rule.n + b] = select(0u, 1u, survives(p.opacity_logit, log_scale_of(p), false));
}
