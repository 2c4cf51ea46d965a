// The budget's choice: the first `rule.room` of the candidates sorted by score are chosen.

@compute @workgroup_size(256)
fn densify_choose(ids: Ids) {
    let j = thread_1d(ids);
    if (j >= pass_.n) {
        return;
    }
    chosen[sorted[j]] = select(0u, 1u, j < rule.room);
}
