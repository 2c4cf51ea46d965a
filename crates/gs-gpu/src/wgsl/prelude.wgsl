// gs-gpu prelude, prepended to every kernel together with the generated `struct Pass` and the
// generated storage-binding declarations (slots 2..).

// Per-dispatch constants (a dynamic-offset slot of one uniform buffer, see `PassUniform`).
@group(0) @binding(1) var<uniform> pass_: Pass;

// Linear id of a 1D dispatch that was split into 2D (at most 65535 workgroups per dimension).
fn linear_group(wid: vec3<u32>, nwg: vec3<u32>) -> u32 {
    return wid.y * nwg.x + wid.x;
}

// The builtins of a 1D kernel: entry points take `ids: Ids`.
struct Ids {
    @builtin(workgroup_id) wid: vec3<u32>,
    @builtin(num_workgroups) nwg: vec3<u32>,
    @builtin(local_invocation_index) li: u32,
}

// Workgroup index within a (possibly 2D-split) 1D dispatch.
fn group_1d(ids: Ids) -> u32 {
    return linear_group(ids.wid, ids.nwg);
}

// Global thread index of a 1D dispatch of 256-thread workgroups (`Dispatcher::dispatch_1d`).
fn thread_1d(ids: Ids) -> u32 {
    return group_1d(ids) * 256u + ids.li;
}

// One step of a compensated (Kahan) f32 sum in a fixed order: `s` is (sum, compensation), the
// result s + v. The loss kernels sum each image row with it before the host adds the rows in
// f64, so a row of many values stays close to the f64 sum.
fn kahan_add(s: vec2<f32>, v: f32) -> vec2<f32> {
    let y = v - s.y;
    let t = s.x + y;
    return vec2<f32>(t, (t - s.x) - y);
}
