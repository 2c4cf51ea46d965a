// Shared by L_p's patch kernel (ncc.wgsl) and its visibility kernel (visibility.wgsl), both of
// which bind the arena of per-view images as `greys`.

// Finite without relying on NaN comparisons (which a driver may fold away).
fn finite(x: f32) -> bool {
    return (bitcast<u32>(x) & 0x7f800000u) != 0x7f800000u;
}

// Bilinear sample of the `gw × gh` image at offset `o` of the arena with (value, ∂/∂u, ∂/∂v),
// the convention of `geometry::sample_bilinear_grad`: taps floor(c − ½) and +1, clamped to the
// edge.
fn arena_sample(o: u32, gw: u32, gh: u32, u: f32, v: f32) -> vec3<f32> {
    let w = i32(gw);
    let h = i32(gh);
    let x = min(max(u - 0.5, -1.0), f32(w));
    let y = min(max(v - 0.5, -1.0), f32(h));
    let x0 = i32(floor(x));
    let y0 = i32(floor(y));
    let fx = x - f32(x0);
    let fy = y - f32(y0);
    let xa = u32(clamp(x0, 0, w - 1));
    let xb = u32(clamp(x0 + 1, 0, w - 1));
    let ya = u32(clamp(y0, 0, h - 1));
    let yb = u32(clamp(y0 + 1, 0, h - 1));
    let i00 = greys[o + ya * gw + xa];
    let i10 = greys[o + ya * gw + xb];
    let i01 = greys[o + yb * gw + xa];
    let i11 = greys[o + yb * gw + xb];
    let top = i00 + (i10 - i00) * fx;
    let bottom = i01 + (i11 - i01) * fx;
    let value = top + (bottom - top) * fy;
    let du = (i10 - i00) * (1.0 - fy) + (i11 - i01) * fy;
    let dv = bottom - top;
    return vec3<f32>(value, du, dv);
}
