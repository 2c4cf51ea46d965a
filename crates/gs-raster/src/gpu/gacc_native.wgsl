@group(0) @binding(8) var<storage, read_write> gacc: array<atomic<f32>>;

fn add_grad(i: u32, v: f32) {
    atomicAdd(&gacc[i], v);
}
