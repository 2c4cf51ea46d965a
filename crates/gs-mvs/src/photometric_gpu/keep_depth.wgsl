// A rendered plane depth kept on the device (`depths.rs`): thread t copies texel t's z of the
// reference's surface into the arena slot starting at `pass_.base` (in floats), for `pass_.n`
// pixels; a later L_p evaluation reads it there as a source's depth.
//
// Generated before this file: `struct SurfaceTexel`, the storage bindings `surface` and
// `greys` (the arena).

@compute @workgroup_size(256)
fn keep_depth(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= pass_.n) {
        return;
    }
    greys[pass_.base + t] = surface[t].z;
}
