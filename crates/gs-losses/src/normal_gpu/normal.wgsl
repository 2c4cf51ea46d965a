// L_nc and L_ns on the device, the twin of `normal_loss::normal_losses` (docs/method.md §L_nc,
// §L_ns): four passes of one thread per pixel. Each pass does the reference's arithmetic in
// the reference's order, so that the host can sum the per-pixel values as the reference does.
//
// Generated before this file: `struct NormalFrame` (binding 0), the records `SurfaceTexel`,
// `PixelVec3`, `PixelTerms` and `DiffGrad`, and the storage bindings, one record per pixel:
// `surface` (z, Ñ, A), `nhat` (N̂), `values` (δ·‖N̂ − Ñ‖₁, the right and the down pair's
// δ_k·ReLU(‖N̂_k − N̂_p‖₁ − τ²) where the pair is active, the number of active pairs; after the
// n pixels' records one record a row with the row's sums, `row_sums`), `gnhat`
// (∂/∂N̂), `gnt` (∂/∂Ñ), `gab` (∂/∂dx and ∂/∂dy), `gz` (∂/∂z); and `consts`, an arena holding
// the view's δ plane from `frame.delta_at` and the rays from `frame.rays_at`: x of each column's
// ray, then y of each row's (`ray_x`, `ray_y`).

@group(0) @binding(0) var<uniform> frame: NormalFrame;

fn sign0(v: f32) -> f32 {
    return select(0.0, 1.0, v > 0.0) - select(0.0, 1.0, v < 0.0);
}

fn sign3(v: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(sign0(v.x), sign0(v.y), sign0(v.z));
}

// The reference's cross product, written out (the builtin may round differently).
fn cross3(a: vec3<f32>, b: vec3<f32>) -> vec3<f32> {
    return vec3<f32>(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}

fn l1(a: vec3<f32>, b: vec3<f32>) -> f32 {
    let d = abs(b - a);
    return d.x + d.y + d.z;
}

// A record's packed `array<f32, 3>` as a vector, and back.
fn to_vec(a: array<f32, 3>) -> vec3<f32> {
    return vec3<f32>(a[0], a[1], a[2]);
}

fn to_array(v: vec3<f32>) -> array<f32, 3> {
    return array<f32, 3>(v.x, v.y, v.z);
}

fn ray_x(i: u32) -> f32 {
    return consts[frame.rays_at + i];
}

fn ray_y(j: u32) -> f32 {
    return consts[frame.rays_at + frame.width + j];
}

fn point(i: u32, j: u32) -> vec3<f32> {
    let d = surface[j * frame.width + i].z;
    return vec3<f32>(ray_x(i) * d, ray_y(j) * d, d);
}

fn ntilde(p: u32) -> vec3<f32> {
    return to_vec(surface[p].normal);
}

fn nh(p: u32) -> vec3<f32> {
    return to_vec(nhat[p].v);
}

fn delta(p: u32) -> f32 {
    return consts[frame.delta_at + p];
}

fn alpha(p: u32) -> f32 {
    if (frame.has_alpha != 0u) {
        return surface[p].alpha;
    }
    return 1.0;
}

fn inside(i: u32, j: u32) -> bool {
    return i >= 1u && j >= 1u && i + 1u < frame.width && j + 1u < frame.height;
}

fn on_border(i: u32, j: u32) -> bool {
    return i == 0u || j == 0u || i + 1u == frame.width || j + 1u == frame.height;
}

// The raw cross product of the two central differences at an interior pixel.
fn raw_normal(i: u32, j: u32) -> vec3<f32> {
    return cross3(point(i + 1u, j) - point(i - 1u, j), point(i, j - 1u) - point(i, j + 1u));
}

fn len3(n: vec3<f32>) -> f32 {
    return sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
}

// Pass 1: N̂ = A · normalise(cross(dx, dy)) inside, 0 on the border.
@compute @workgroup_size(256)
fn depth_normals(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.n) {
        return;
    }
    let i = p % frame.width;
    let j = p / frame.width;
    var out = vec3<f32>(0.0);
    if (inside(i, j)) {
        let n = raw_normal(i, j);
        out = n * (alpha(p) / max(len3(n), frame.eps));
    }
    nhat[p] = PixelVec3(to_array(out));
}

// Whether the L_ns pair (p, k) counts: the pair rule and the gate on ‖Ñ_k − Ñ_p‖₁.
fn pair_on(i: u32, j: u32, ki: u32, kj: u32) -> bool {
    if (frame.interior != 0u && (on_border(i, j) || on_border(ki, kj))) {
        return false;
    }
    let dt = l1(ntilde(j * frame.width + i), ntilde(kj * frame.width + ki));
    if (frame.gate == 0u) {
        return dt > frame.tau;
    }
    return dt < frame.tau;
}

// The L_ns pair (p, k): whether it counts, and its hinge ‖N̂_k − N̂_p‖₁ − τ².
struct Pair {
    on: bool,
    r: f32,
}

fn pair(i: u32, j: u32, ki: u32, kj: u32) -> Pair {
    return Pair(pair_on(i, j, ki, kj), l1(nh(j * frame.width + i), nh(kj * frame.width + ki)) - frame.tau2);
}

// The gradient coefficient of a pair whose second pixel is k: s·δ_k where it is active and
// its hinge positive.
fn coef(pr: Pair, k: u32) -> f32 {
    if (!pr.on || !(pr.r > 0.0)) {
        return 0.0;
    }
    return frame.s_ns * delta(k);
}

// Pass 2: the per-pixel values of both terms, ∂/∂Ñ of L_nc and ∂/∂N̂ of both.
@compute @workgroup_size(256)
fn normal_terms(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.n) {
        return;
    }
    let w = frame.width;
    let i = p % w;
    let j = p / w;
    let np = nh(p);
    let diff = np - ntilde(p);
    let d = abs(diff);
    let dp = delta(p);
    let nc = dp * (d.x + d.y + d.z);
    // The pairs (p, right) and (p, down), each evaluated once for its value and its gradient.
    var right = Pair(false, 0.0);
    if (i + 1u < w) {
        right = pair(i, j, i + 1u, j);
    }
    var down = Pair(false, 0.0);
    if (j + 1u < frame.height) {
        down = pair(i, j, i, j + 1u);
    }
    var count = 0.0;
    var ns = vec2<f32>(0.0);
    if (right.on) {
        count += 1.0;
        if (right.r > 0.0) {
            ns.x = delta(p + 1u) * right.r;
        }
    }
    if (down.on) {
        count += 1.0;
        if (down.r > 0.0) {
            ns.y = delta(p + w) * down.r;
        }
    }
    values[p] = PixelTerms(nc, ns.x, ns.y, count);
    let gnc = frame.s_nc * dp * sign3(diff);
    gnt[p] = PixelVec3(to_array(-gnc));
    // L_ns: p as the first pixel of (p, right) and (p, down), then as the neighbour of
    // (left, p) and (up, p), in the reference's order.
    var acc = vec3<f32>(0.0);
    let c_right = coef(right, p + 1u);
    if (c_right != 0.0) {
        acc += (-c_right) * sign3(nh(p + 1u) - np);
    }
    let c_down = coef(down, p + w);
    if (c_down != 0.0) {
        acc += (-c_down) * sign3(nh(p + w) - np);
    }
    if (i >= 1u) {
        let c = coef(pair(i - 1u, j, i, j), p);
        if (c != 0.0) {
            acc += c * sign3(np - nh(p - 1u));
        }
    }
    if (j >= 1u) {
        let c = coef(pair(i, j - 1u, i, j), p);
        if (c != 0.0) {
            acc += c * sign3(np - nh(p - w));
        }
    }
    gnhat[p] = PixelVec3(to_array(gnc + acc));
}

// Pass 3: ∂/∂dx and ∂/∂dy of each interior pixel's normal (zero where ∂/∂N̂ is zero).
@compute @workgroup_size(256)
fn normal_chain(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.n) {
        return;
    }
    let i = p % frame.width;
    let j = p / frame.width;
    let g = to_vec(gnhat[p].v);
    var da = vec3<f32>(0.0);
    var db = vec3<f32>(0.0);
    if (inside(i, j) && !(g.x == 0.0 && g.y == 0.0 && g.z == 0.0)) {
        let a = alpha(p);
        let dx = point(i + 1u, j) - point(i - 1u, j);
        let dy = point(i, j - 1u) - point(i, j + 1u);
        let n = cross3(dx, dy);
        let len = len3(n);
        var gn: vec3<f32>;
        if (len > frame.eps) {
            let inv = 1.0 / len;
            let u = n * inv;
            let ug = u.x * g.x + u.y * g.y + u.z * g.z;
            gn = (g - u * ug) * (a * inv);
        } else {
            gn = g * (a / frame.eps);
        }
        da = cross3(dy, gn);
        db = cross3(gn, dx);
    }
    gab[p] = DiffGrad(to_array(da), to_array(db));
}

fn ga(p: u32) -> vec3<f32> {
    return to_vec(gab[p].dx);
}

fn gb(p: u32) -> vec3<f32> {
    return to_vec(gab[p].dy);
}

// Pass 4: ∂/∂z, each pixel's share of its neighbours' differences along its ray.
@compute @workgroup_size(256)
fn depth_gradient(ids: Ids) {
    let p = thread_1d(ids);
    if (p >= frame.n) {
        return;
    }
    let w = frame.width;
    let i = p % w;
    let j = p / w;
    var s = vec3<f32>(0.0);
    if (i >= 1u) {
        s += ga(p - 1u);
    }
    if (i + 1u < w) {
        s -= ga(p + 1u);
    }
    if (j + 1u < frame.height) {
        s += gb(p + w);
    }
    if (j >= 1u) {
        s -= gb(p - w);
    }
    gz[p] = s.x * ray_x(i) + s.y * ray_y(j) + s.z;
}

// One thread per row: the row's L_nc values, its L_ns values (each pixel's right, then down
// pair) and its active pairs, each summed along the row in order (`kahan_add`; the counts are
// exact integers in f32), written as record n + y of `values`, for `normal_totals`.
@compute @workgroup_size(256)
fn row_sums(ids: Ids) {
    let y = thread_1d(ids);
    if (y >= frame.height) {
        return;
    }
    var nc = vec2<f32>(0.0);
    var ns = vec2<f32>(0.0);
    var pairs = 0.0;
    for (var x = 0u; x < frame.width; x++) {
        let t = values[y * frame.width + x];
        nc = kahan_add(nc, t.nc);
        ns = kahan_add(kahan_add(ns, t.ns_right), t.ns_down);
        pairs += t.pairs;
    }
    values[frame.n + y] = PixelTerms(nc.x, ns.x, 0.0, pairs);
}

// Last, one thread: the rows' sums added in row order as double-f32 pairs (`wide_add`),
// written after them as two records: (L_nc's hi, lo, L_ns's hi, lo), (the active pairs' hi,
// lo, 0, 0). The host reads these two records alone (`gs_gpu::wide_value`).
@compute @workgroup_size(256)
fn normal_totals(ids: Ids) {
    if (thread_1d(ids) != 0u) {
        return;
    }
    var nc = vec2<f32>(0.0);
    var ns = vec2<f32>(0.0);
    var pairs = vec2<f32>(0.0);
    for (var y = 0u; y < frame.height; y++) {
        let r = values[frame.n + y];
        nc = wide_add(nc, r.nc);
        ns = wide_add(ns, r.ns_right);
        pairs = wide_add(pairs, r.pairs);
    }
    let at = frame.n + frame.height;
    values[at] = PixelTerms(nc.x, nc.y, ns.x, ns.y);
    values[at + 1u] = PixelTerms(pairs.x, pairs.y, 0.0, 0.0);
}
