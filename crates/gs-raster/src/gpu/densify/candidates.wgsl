// The candidates after the AbsGS limit (`abs_flags` scanned): clone and split flags (one more
// element, 0, so that their scans end in the totals) and the sort keys, the score descending
// (candidates first, ties by index: the sort is stable). With `pass_.mode` 1 only the rows
// `chosen` by the budget stay candidates.

@compute @workgroup_size(256)
fn densify_candidates(ids: Ids) {
    let i = thread_1d(ids);
    if (i > pass_.n) {
        return;
    }
    if (i == pass_.n) {
        clone_flags[i] = 0u;
        split_flags[i] = 0u;
        return;
    }
    let c = classes[i];
    var take = true;
    if (pass_.mode == 1u) {
        take = chosen[i] != 0u;
    }
    let clone = take && c == 1u;
    let split = take && (c == 2u || (c == 3u && abs_flags[i] < rule.max_abs_splits));
    clone_flags[i] = select(0u, 1u, clone);
    split_flags[i] = select(0u, 1u, split);
    if (pass_.mode == 0u) {
        keys[i] = select(0xffffffffu, 0x7fffffffu - (keys[i] & 0x7fffffffu), clone || split);
        vals[i] = i;
    }
}
