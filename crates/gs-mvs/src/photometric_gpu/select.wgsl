// L_p's pixel selection on the device (docs/method.md §L_p), after `visibility_pixels` and `visibility_rows`:
// the entries the patch kernel evaluates, in the host's order (row-major within each source,
// sources in order), each source's at `k · frame.slot` onwards.
// - `select_starts`, one thread per source, when no source can exceed the cap
//   (`frame.capped` 0): every candidate is evaluated, so each row's first entry is the sum of
//   the rows' candidates before it. A capped evaluation gets these from the host instead, which
//   draws the patches from the row counts with the seed (`photometric::drawn_candidates`).
// - `select_rows`, one thread per (source, row): the row's candidates in order, those drawn
//   (`masks`: a bit per candidate rank, when capped) written to `entries` with their υω.
//
// Generated before this file: `struct NccFrame` (binding 0), `struct VisPair`,
// `struct VisTexel`, `struct VisRow`, and the storage bindings `vis_pairs`, `vis`, `vis_rows`,
// `row_starts` (per source `height + 1` entry indices), `cand_starts` (per (source, row) the
// rank of its first candidate), `masks`, `entries` and `weights`.

@group(0) @binding(0) var<uniform> frame: NccFrame;

const CANDIDATE: u32 = 4u;

@compute @workgroup_size(256)
fn select_starts(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= frame.sources) {
        return;
    }
    let rows = frame.height + 1u;
    var at = k * frame.slot;
    for (var y = 0u; y < frame.height; y++) {
        row_starts[k * rows + y] = at;
        at += vis_rows[k * frame.height + y].candidates;
    }
    row_starts[k * rows + frame.height] = at;
}

@compute @workgroup_size(256)
fn select_rows(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= frame.sources * frame.height) {
        return;
    }
    let k = t / frame.height;
    let y = t % frame.height;
    var at = row_starts[k * (frame.height + 1u) + y];
    var rank = 0u;
    if (frame.capped != 0u) {
        rank = cand_starts[t];
    }
    let mask = vis_pairs[k].mask_offset;
    let first = y * frame.width;
    for (var x = 0u; x < frame.width; x++) {
        let v = vis[k * frame.pixels + first + x];
        if ((v.flags & CANDIDATE) == 0u) {
            continue;
        }
        if (frame.capped == 0u || ((masks[mask + rank / 32u] >> (rank % 32u)) & 1u) != 0u) {
            entries[at] = first + x;
            weights[at] = v.weight;
            at += 1u;
        }
        rank += 1u;
    }
}
