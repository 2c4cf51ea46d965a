// Per-Gaussian projection internals shared by `project` and `project_bwd` (the CPU backend's
// `internals` in project.rs, operation for operation).

const SH_C0: f32 = 0.282094777;
const SH_C1: f32 = 0.488602519;
const C20: f32 = 1.09254837;
const C21: f32 = -1.09254837;
const C22: f32 = 0.31539157;
const C23: f32 = -1.09254837;
const C24: f32 = 0.546274185;
const C30: f32 = -0.590043604;
const C31: f32 = 2.89061141;
const C32: f32 = -0.457045794;
const C33: f32 = 0.373176336;
const C34: f32 = -0.457045794;
const C35: f32 = 1.44530571;
const C36: f32 = -0.590043604;

struct Internals {
    ok: bool,
    t: vec3<f32>,
    rot: mat3x3<f32>,
    s: vec3<f32>,
    j0: vec3<f32>,
    j1: vec3<f32>,
    clamped_x: bool,
    clamped_y: bool,
    p: mat3x3<f32>,
    v0: vec3<f32>,
    v1: vec3<f32>,
    cov: vec3<f32>,
    det: f32,
    conic: vec3<f32>,
    o_raw: f32,
    comp: f32,
    comp_floored: bool,
    opacity: f32,
    dir_raw: vec3<f32>,
    color: vec3<f32>,
    clamped: vec3<bool>,
    axis: u32,
    flip: f32,
    n_c: vec3<f32>,
    dist: f32,
}

struct Param {
    mean: vec3<f32>,
    log_scale: vec3<f32>,
    quat: vec4<f32>,
    logit: f32,
}

fn smallest_axis(s: vec3<f32>) -> u32 {
    var k = 0u;
    var best = s.x;
    if (s.y < best) {
        k = 1u;
        best = s.y;
    }
    if (s.z < best) {
        k = 2u;
    }
    return k;
}

fn sh_basis(d: vec3<f32>) -> array<f32, 16> {
    var b = array<f32, 16>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    let x = d.x;
    let y = d.y;
    let z = d.z;
    b[0] = SH_C0;
    if (cam.sh_degree >= 1u) {
        b[1] = -SH_C1 * y;
        b[2] = SH_C1 * z;
        b[3] = -SH_C1 * x;
    }
    if (cam.sh_degree >= 2u) {
        let xx = x * x;
        let yy = y * y;
        let zz = z * z;
        let xy = x * y;
        let yz = y * z;
        let xz = x * z;
        b[4] = C20 * xy;
        b[5] = C21 * yz;
        b[6] = C22 * (2.0 * zz - xx - yy);
        b[7] = C23 * xz;
        b[8] = C24 * (xx - yy);
        if (cam.sh_degree >= 3u) {
            b[9] = C30 * y * (3.0 * xx - yy);
            b[10] = C31 * xy * z;
            b[11] = C32 * y * (4.0 * zz - xx - yy);
            b[12] = C33 * z * (2.0 * zz - 3.0 * xx - 3.0 * yy);
            b[13] = C34 * x * (4.0 * zz - xx - yy);
            b[14] = C35 * z * (xx - yy);
            b[15] = C36 * x * (xx - 3.0 * yy);
        }
    }
    return b;
}

fn read_sh(i: u32, k: u32) -> vec3<f32> {
    let c = sh[i * cam.nc + k].rgb;
    return vec3<f32>(c[0], c[1], c[2]);
}

fn read_param(i: u32) -> Param {
    let r = params[i];
    var p: Param;
    p.mean = vec3<f32>(r.mean[0], r.mean[1], r.mean[2]);
    p.log_scale = vec3<f32>(r.log_scale[0], r.log_scale[1], r.log_scale[2]);
    p.quat = vec4<f32>(r.rot_w, r.rot_x, r.rot_y, r.rot_z);
    p.logit = r.opacity_logit;
    return p;
}

// `i` indexes the (chunk-bound) parameter and SH arrays.
fn internals(i: u32, pr: Param) -> Internals {
    var it: Internals;
    it.ok = false;
    let rc = rot_c();
    let t = rc * pr.mean + cam.tc.xyz;
    it.t = t;
    if (!(finite3(t) && t.z > cam.near && t.z <= cam.far)) {
        return it;
    }
    let ls = pr.log_scale;
    let s = vec3<f32>(exp(ls.x), exp(ls.y), exp(ls.z));
    it.s = s;
    if (!finite3(s)) {
        return it;
    }
    let rot = rotation_matrix(pr.quat);
    it.rot = rot;
    let inv_z = 1.0 / t.z;
    let txz = t.x * inv_z;
    let tyz = t.y * inv_z;
    let cxz = clamp(txz, -cam.lim_x, cam.lim_x);
    let cyz = clamp(tyz, -cam.lim_y, cam.lim_y);
    it.clamped_x = cxz != txz;
    it.clamped_y = cyz != tyz;
    let j0 = vec3<f32>(cam.fx * inv_z, 0.0, -cam.fx * cxz * inv_z);
    let j1 = vec3<f32>(0.0, cam.fy * inv_z, -cam.fy * cyz * inv_z);
    it.j0 = j0;
    it.j1 = j1;
    let m = mat3x3<f32>(rot[0] * s.x, rot[1] * s.y, rot[2] * s.z);
    let p = rc * m;
    it.p = p;
    let v0 = vec3<f32>(dot(j0, p[0]), dot(j0, p[1]), dot(j0, p[2]));
    let v1 = vec3<f32>(dot(j1, p[0]), dot(j1, p[1]), dot(j1, p[2]));
    it.v0 = v0;
    it.v1 = v1;
    let cov = vec3<f32>(dot(v0, v0), dot(v0, v1), dot(v1, v1));
    let a = cov.x + cam.low_pass;
    let b = cov.y;
    let c = cov.z + cam.low_pass;
    let det = a * c - b * b;
    if (!(det > 0.0 && is_finite(det))) {
        return it;
    }
    it.cov = vec3<f32>(a, b, c);
    it.det = det;
    let o_raw = sigmoid(pr.logit);
    it.o_raw = o_raw;
    it.comp = 1.0;
    it.comp_floored = false;
    if (cam.antialiased != 0u) {
        let det_o = cov.x * cov.z - cov.y * cov.y;
        let ratio = det_o / det;
        let fl = MIN_COMPENSATION * MIN_COMPENSATION;
        if (ratio > fl) {
            it.comp = sqrt(ratio);
        } else {
            it.comp = MIN_COMPENSATION;
            it.comp_floored = true;
        }
    }
    let opacity = o_raw * it.comp;
    it.opacity = opacity;
    if (!(opacity >= cam.threshold)) {
        return it;
    }
    let inv_det = 1.0 / det;
    it.conic = vec3<f32>(c * inv_det, -b * inv_det, a * inv_det);
    let dir_raw = transpose(rc) * t;
    it.dir_raw = dir_raw;
    let len = sqrt(dot(dir_raw, dir_raw));
    var dir = vec3<f32>(0.0);
    if (len > 0.0) {
        dir = dir_raw / len;
    }
    let bs = sh_basis(dir);
    var raw = vec3<f32>(0.0);
    for (var k = 0u; k < cam.nc; k++) {
        raw += bs[k] * read_sh(i, k);
    }
    let v = raw + 0.5;
    it.clamped = v < vec3<f32>(0.0);
    it.color = max(v, vec3<f32>(0.0));
    let axis = smallest_axis(ls);
    it.axis = axis;
    let n0 = rc * rot[axis];
    it.flip = 1.0;
    if (dot(n0, t) > 0.0) {
        it.flip = -1.0;
    }
    let n_c = n0 * it.flip;
    it.n_c = n_c;
    it.dist = -dot(n_c, t);
    it.ok = true;
    return it;
}
