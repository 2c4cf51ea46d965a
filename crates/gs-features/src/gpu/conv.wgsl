// One VGG16 layer on the device: 3×3 convolution (zero padding 1) + bias + ReLU, the twin of
// gs-features' `PreparedConv::forward` (docs/method.md §L_f). Tensors are HWC f32 with a
// one-pixel zero border, as the host's `Padded`; the border of `act_out` is cleared before
// the dispatch, only the interior is written here. One invocation per (pixel, 4 output
// channels). The pass constants are set by `layer_pass` in mod.rs:
//   pass_.n     invocations (width · height · blocks)
//   pass_.p1    interior width
//   pass_.p3    input channels
//   pass_.mode  output channels / 4 (blocks)

@compute @workgroup_size(256)
fn conv3x3(ids: Ids) {
    let t = thread_1d(ids);
    if (t >= pass_.n) {
        return;
    }
    let width = pass_.p1;
    let cin = pass_.p3;
    let blocks = pass_.mode;
    let block = t % blocks;
    let p = t / blocks;
    let x = p % width;
    let y = p / width;
    var acc = bias[block];
    for (var ky = 0u; ky < 3u; ky++) {
        for (var kx = 0u; kx < 3u; kx++) {
            let src = ((y + ky) * (width + 2u) + x + kx) * cin;
            let row = (ky * 3u + kx) * cin;
            for (var ci = 0u; ci < cin; ci++) {
                acc += act_in[src + ci] * weights[(row + ci) * blocks + block];
            }
        }
    }
    act_out[((y + 1u) * (width + 2u) + x + 1u) * blocks + block] = max(acc, vec4<f32>(0.0));
}
