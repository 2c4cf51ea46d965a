// Each born row's parent and, as its record to start from, the parent's: clone k is row k of
// the born rows, split parent k's two children rows C + 2k and C + 2k + 1 (`clone_ranks`,
// `split_ranks` scanned; C their clone total).

@compute @workgroup_size(256)
fn densify_parents(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n) {
        return;
    }
    if (flagged(clone_ranks[i + 1u], clone_ranks[i])) {
        parents[clone_ranks[i]] = i;
        born[clone_ranks[i]] = params[i];
    }
    if (flagged(split_ranks[i + 1u], split_ranks[i])) {
        let b = clone_ranks[pass_.n] + 2u * split_ranks[i];
        parents[b] = i;
        parents[b + 1u] = i;
        born[b] = params[i];
        born[b + 1u] = params[i];
    }
}
