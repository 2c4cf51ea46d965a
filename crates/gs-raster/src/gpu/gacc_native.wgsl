fn add_grad(i: u32, v: f32) {
    atomicAdd(&gacc[i], v);
}
