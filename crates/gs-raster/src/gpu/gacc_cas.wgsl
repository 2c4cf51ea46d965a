// f32 add as a compare-exchange loop on the bit pattern (adapters without f32 atomics).
fn add_grad(i: u32, v: f32) {
    var old = atomicLoad(&gacc[i]);
    loop {
        let r = atomicCompareExchangeWeak(&gacc[i], old, bitcast<u32>(bitcast<f32>(old) + v));
        if (r.exchanged) {
            break;
        }
        old = r.old_value;
    }
}
