// Workgroup-wide exclusive prefix sum of one u32 per invocation (Hillis-Steele in workgroup
// memory), for workgroups of at most 256 invocations. Shared by the prefix scan and the radix
// scatter. Every invocation of the workgroup must call it (it contains barriers).

var<workgroup> scan_part: array<u32, 256>;

// The sum of `s` over the invocations with a smaller local index than `li`.
fn block_exclusive_scan(li: u32, s: u32) -> u32 {
    scan_part[li] = s;
    workgroupBarrier();
    for (var off = 1u; off < 256u; off <<= 1u) {
        var x = 0u;
        if (li >= off) {
            x = scan_part[li - off];
        }
        workgroupBarrier();
        scan_part[li] += x;
        workgroupBarrier();
    }
    return scan_part[li] - s;
}
