// VGG16's 2×2 max pool with stride 2 (floor) on the device, the twin of gs-features'
// `max_pool2`: exact, so it gives the host's bits for the same input. Padded HWC tensors as
// in conv.wgsl; one invocation per (output pixel, 4 channels). Pass constants (`pool_pass`):
//   pass_.n     invocations (output width · output height · blocks)
//   pass_.p1    output interior width
//   pass_.p3    input interior width
//   pass_.mode  channels / 4 (blocks)

@compute @workgroup_size(256)
fn max_pool2(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= pass_.n) {
        return;
    }
    let width = pass_.p1;
    let in_row = pass_.p3 + 2u;
    let blocks = pass_.mode;
    let block = t % blocks;
    let p = t / blocks;
    let x = p % width;
    let y = p / width;
    let a = ((2u * y + 1u) * in_row + 2u * x + 1u) * blocks + block;
    let b = a + in_row * blocks;
    let top = max(act_below[a], act_below[a + blocks]);
    let bottom = max(act_below[b], act_below[b + blocks]);
    act_out[((y + 1u) * (width + 2u) + x + 1u) * blocks + block] = max(top, bottom);
}
