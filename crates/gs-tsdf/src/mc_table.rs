//! Marching-cubes triangle table, generated at first use by walking the cube's faces.
//!
//! Instead of a hand-typed 256-entry table, every sign configuration is triangulated by
//! tracing the iso-contour segments on the six cube faces into closed loops and fanning each
//! loop. A face with two diagonally opposite negative corners (the ambiguous face) always
//! separates the negative corners; since that decision depends only on the face's four signs,
//! the two cubes sharing the face agree, so the surface has no cracks and every surface edge is
//! shared by exactly two triangles. Triangles are wound counter-clockwise seen from the
//! positive (free-space) side, i.e. their normals point out of the negative region.

use std::sync::OnceLock;

/// Corner `c` (0..8) sits at offset `(c & 1, (c >> 1) & 1, (c >> 2) & 1)`.
pub(crate) fn corner_offset(c: usize) -> [usize; 3] {
    [c & 1, (c >> 1) & 1, (c >> 2) & 1]
}

/// The 12 cube edges as `(lower corner, axis)`; edge `e` joins corner `lower` and
/// `lower | (1 << axis)`.
pub(crate) const EDGES: [(usize, usize); 12] = [
    (0, 0),
    (2, 0),
    (4, 0),
    (6, 0),
    (0, 1),
    (1, 1),
    (4, 1),
    (5, 1),
    (0, 2),
    (1, 2),
    (2, 2),
    (3, 2),
];

fn edge_between(a: usize, b: usize) -> usize {
    let (lo, hi) = if a < b { (a, b) } else { (b, a) };
    let axis = (hi ^ lo).trailing_zeros() as usize;
    EDGES.iter().position(|&(c, ax)| c == lo && ax == axis).expect("corners are adjacent")
}

/// Marching-cubes lookup: for each configuration (bit `c` set ⇔ corner `c` is negative), the
/// triangles as triples of edge ids.
pub(crate) struct McTable {
    pub tris: [[[u8; 3]; 12]; 256],
    pub count: [u8; 256],
}

/// The table, built once.
pub(crate) fn table() -> &'static McTable {
    static TABLE: OnceLock<McTable> = OnceLock::new();
    TABLE.get_or_init(build)
}

/// The loops of edge ids for one configuration.
pub(crate) fn loops(config: usize) -> Vec<Vec<usize>> {
    let inside = |c: usize| config & (1 << c) != 0;
    // next[e] = the edge that follows e along the contour.
    let mut next = [usize::MAX; 12];
    for axis in 0..3 {
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        for side in 0..2 {
            // Face corners counter-clockwise seen from outside the cube.
            let at = |a: usize, b: usize| (side << axis) | (a << u) | (b << v);
            let mut cyc = [at(0, 0), at(1, 0), at(1, 1), at(0, 1)];
            if side == 0 {
                cyc.reverse();
            }
            // Crossing edges in cyclic order with their direction (true = in→out).
            let mut crossings = Vec::with_capacity(4);
            for k in 0..4 {
                let (a, b) = (cyc[k], cyc[(k + 1) % 4]);
                if inside(a) != inside(b) {
                    crossings.push((edge_between(a, b), inside(a)));
                }
            }
            let n = crossings.len();
            for k in 0..n {
                let (e, in_to_out) = crossings[k];
                if in_to_out {
                    // Segment to the previous out→in crossing: negative corners stay separated.
                    let (prev, _) = crossings[(k + n - 1) % n];
                    next[e] = prev;
                }
            }
        }
    }
    let mut seen = [false; 12];
    let mut out = Vec::new();
    for start in 0..12 {
        if next[start] == usize::MAX || seen[start] {
            continue;
        }
        let mut lp = Vec::new();
        let mut e = start;
        while !seen[e] {
            seen[e] = true;
            lp.push(e);
            e = next[e];
        }
        out.push(lp);
    }
    out
}

fn build() -> McTable {
    let mut t = McTable { tris: [[[0; 3]; 12]; 256], count: [0; 256] };
    for config in 0..256 {
        let mut n = 0;
        for lp in loops(config) {
            for k in 1..lp.len() - 1 {
                // Face segments run counter-clockwise around the negative region seen from outside
                // the cube, which makes the loop clockwise seen from the positive side: reverse it.
                t.tris[config][n] = [lp[0] as u8, lp[k + 1] as u8, lp[k] as u8];
                n += 1;
            }
        }
        t.count[config] = n as u8;
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    fn edge_midpoint(e: usize) -> [f64; 3] {
        let (c, axis) = EDGES[e];
        let o = corner_offset(c);
        let mut p = [o[0] as f64, o[1] as f64, o[2] as f64];
        p[axis] += 0.5;
        p
    }

    fn normal(tri: [u8; 3]) -> [f64; 3] {
        let [a, b, c] = tri.map(|e| edge_midpoint(e as usize));
        let u = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
        let v = [c[0] - a[0], c[1] - a[1], c[2] - a[2]];
        [u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]]
    }

    #[test]
    fn single_negative_corner_gives_one_outward_triangle() {
        let t = table();
        for c in 0..8 {
            let config = 1 << c;
            assert_eq!(t.count[config], 1);
            let n = normal(t.tris[config][0]);
            let o = corner_offset(c);
            // Away from the negative corner = towards the cube centre.
            let d: f64 = (0..3).map(|k| n[k] * (0.5 - o[k] as f64)).sum();
            assert!(d > 0.0, "corner {c}: normal {n:?}");
            // Complement: same edges, opposite orientation.
            let m = normal(t.tris[255 ^ config][0]);
            let d2: f64 = (0..3).map(|k| m[k] * (0.5 - o[k] as f64)).sum();
            assert!(d2 < 0.0);
        }
    }

    #[test]
    fn every_crossing_edge_used_exactly_once_and_counts_bounded() {
        let t = table();
        assert_eq!(t.count[0], 0);
        assert_eq!(t.count[255], 0);
        for config in 0..256usize {
            let crossing: Vec<usize> = (0..12)
                .filter(|&e| {
                    let (c, axis) = EDGES[e];
                    ((config >> c) & 1) != ((config >> (c | (1 << axis))) & 1)
                })
                .collect();
            let lps = loops(config);
            let mut used: Vec<usize> = lps.iter().flatten().copied().collect();
            used.sort();
            assert_eq!(used, crossing, "config {config}");
            assert!(lps.iter().all(|l| l.len() >= 3));
            let tri_count: usize = lps.iter().map(|l| l.len() - 2).sum();
            assert_eq!(tri_count, t.count[config] as usize);
        }
    }

    #[test]
    fn two_cube_faces_have_opposite_segments() {
        // Half-space x < 0.5: corners with x = 0 negative. One quad, normal along +x.
        let config = (0..8).filter(|c| c & 1 == 0).fold(0, |acc, c| acc | (1 << c));
        let t = table();
        assert_eq!(t.count[config], 2);
        for k in 0..2 {
            let n = normal(t.tris[config][k]);
            assert!(n[0] > 0.0 && n[1].abs() < 1e-12 && n[2].abs() < 1e-12, "{n:?}");
        }
    }
}
