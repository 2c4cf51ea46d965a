// The born rows: a position sampled from the parent, μ + R·(s ⊙ n) with the host's normal
// draws n (3 per row, in row order), the parent's rotation, opacity and (halved by the split
// divisor for split children) log-scale; and whether each survives the prune (`keep` from row
// `rule.n` on; rows past the born count, up to the reserved `pass_.n`, are not kept).

@compute @workgroup_size(256)
fn densify_born(ids: Ids) {
    let b = thread_1d(ids);
    if (b > pass_.n) {
        return;
    }
    let clones = clone_ranks[rule.n];
    let count = clones + 2u * split_ranks[rule.n];
    if (b >= count) {
        keep[rule.n + b] = 0u;
        return;
    }
    var p = params[parents[b]];
    let s = exp(log_scale_of(p));
    let d = vec3<f32>(normals[3u * b] * s.x, normals[3u * b + 1u] * s.y, normals[3u * b + 2u] * s.z);
    let r = rotation_matrix(vec4<f32>(p.rot_w, p.rot_x, p.rot_y, p.rot_z));
    let m = vec3<f32>(p.mean[0], p.mean[1], p.mean[2]) + r * d;
    p.mean = array<f32, 3>(m.x, m.y, m.z);
    if (b >= clones) {
        p.log_scale = array<f32, 3>(p.log_scale[0] - rule.shrink, p.log_scale[1] - rule.shrink, p.log_scale[2] - rule.shrink);
    }
    born[b] = p;
    keep[rule.n + b] = select(0u, 1u, survives(p.opacity_logit, log_scale_of(p), false));
}
