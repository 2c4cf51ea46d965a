// The capture path's free space on the resident model (gpu/densify/region.rs), the twin of
// gs-core's `Capsule::contains` as gs-train's capture-path rule applies it:
// - `densify_mark_capsules`, one thread per Gaussian and one more: its mean against every
//   capsule in f32. A capsule decides only where the mean lies farther than a band from each
//   of its boundaries; the mark is IN where some capsule certainly holds it, else UNSURE where
//   some capsule is too close to call (or the mean is not finite), else OUT. `ranks` gets 1
//   for each UNSURE row and a last zero, for the scan.
// - `densify_unsure_list`, one thread per Gaussian: each UNSURE row's index and mean at its
//   scanned rank, for the host's f64 test.
// - `densify_settle_marks`, one thread per row the host found inside: its mark becomes IN.
// - `densify_outside_keep`, one thread per Gaussian and one more: the keep mask (1 where the
//   mark is not IN: the host left its UNSURE rows outside) and a last zero, for the scan.

const OUT: u32 = 0u;
const IN: u32 = 1u;
const UNSURE: u32 = 2u;
// The band, relative to the size of the numbers involved: f32 rounds each of them to within
// 2^-24 of itself, and a mark sums a few such errors, far below 2^-16 (docs/architecture.md §GPU).
const BAND: f32 = 1.52587890625e-5;

fn vec3_of(v: array<f32, 3>) -> vec3<f32> {
    return vec3<f32>(v[0], v[1], v[2]);
}

// Capsule `c`'s mark of point `p`.
fn capsule_mark(p: vec3<f32>, c: CapsuleRecord) -> u32 {
    let a = vec3_of(c.a);
    let ab = vec3_of(c.ab);
    let d = p - a;
    let tau = BAND * (length(p) + length(a) + length(ab) + c.radius);
    let front_a = dot(d, vec3_of(c.fa));
    let front_b = dot(d - ab, vec3_of(c.fb));
    let len2 = dot(ab, ab);
    var t = 0.0;
    if (len2 > 0.0) {
        t = clamp(dot(d, ab) / len2, 0.0, 1.0);
    }
    let dist = length(d - t * ab);
    if (front_a < -tau || front_b < -tau || dist > c.radius + tau) {
        return OUT;
    }
    if (front_a > tau && front_b > tau && dist < c.radius - tau) {
        return IN;
    }
    return UNSURE;
}

fn mean_of(i: u32) -> vec3<f32> {
    return vec3_of(params[i].mean);
}

@compute @workgroup_size(256)
fn densify_mark_capsules(ids: Ids) {
    let i = thread_1d(ids);
    if (i > pass_.n) {
        return;
    }
    if (i == pass_.n) {
        ranks[i] = 0u;
        return;
    }
    let p = mean_of(i);
    var mark = OUT;
    if (!(is_finite(p.x) && is_finite(p.y) && is_finite(p.z))) {
        mark = UNSURE;
    } else {
        for (var k = 0u; k < pass_.p1; k++) {
            let m = capsule_mark(p, capsules[k]);
            if (m == IN) {
                mark = IN;
                break;
            }
            if (m == UNSURE) {
                mark = UNSURE;
            }
        }
    }
    marks[i] = mark;
    ranks[i] = select(0u, 1u, mark == UNSURE);
}

@compute @workgroup_size(256)
fn densify_unsure_list(ids: Ids) {
    let i = thread_1d(ids);
    if (i >= pass_.n || marks[i] != UNSURE) {
        return;
    }
    unsure[ranks[i]] = UnsurePoint(i, params[i].mean);
}

@compute @workgroup_size(256)
fn densify_settle_marks(ids: Ids) {
    let k = thread_1d(ids);
    if (k >= pass_.n) {
        return;
    }
    marks[settled[k]] = IN;
}

@compute @workgroup_size(256)
fn densify_outside_keep(ids: Ids) {
    let i = thread_1d(ids);
    if (i > pass_.n) {
        return;
    }
    if (i == pass_.n) {
        dest[i] = 0u;
        return;
    }
    dest[i] = select(1u, 0u, marks[i] == IN);
}
