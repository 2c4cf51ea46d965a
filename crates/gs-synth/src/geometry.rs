//! The geometry of the built-in scene: tessellated primitives (UV sphere, box, torus) on a
//! square floor inside four open-top walls, as one [`TriangleMesh`] whose first triangles are
//! the objects.

use glam::{DMat3, DVec3};
use gs_core::TriangleMesh;

/// Half side of the square floor; the walls stand at x = ±ROOM_HALF and y = ±ROOM_HALF.
pub const ROOM_HALF: f64 = 4.0;
/// Height of the four walls (there is no ceiling).
pub const WALL_HEIGHT: f64 = 2.2;
/// Sphere centre and radius (it touches the floor at its south pole).
pub const SPHERE: ([f64; 3], f64) = ([-0.55, 0.30, 0.38], 0.38);
/// Box centre, half extents and yaw about +z in degrees (it stands on the floor).
pub const CUBOID: ([f64; 3], [f64; 3], f64) = ([0.52, 0.32, 0.26], [0.30, 0.21, 0.26], 30.0);
/// Torus major radius, minor radius, tilt about +x and yaw about +z (degrees), centre x, y.
pub const TORUS: (f64, f64, f64, f64, [f64; 2]) = (0.30, 0.11, 35.0, 20.0, [0.02, -0.52]);
/// Sphere tessellation: longitude × latitude segments.
const SPHERE_SEGMENTS: (usize, usize) = (64, 32);
/// Torus tessellation: segments around the major and the minor circle.
const TORUS_SEGMENTS: (usize, usize) = (72, 28);

/// What a triangle is made of; decides its texture and specular parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Material {
    /// The UV sphere.
    Sphere,
    /// The box.
    Cuboid,
    /// The torus.
    Torus,
    /// The floor square.
    Floor,
    /// One of the four walls: 0 = +x, 1 = −x, 2 = +y, 3 = −y.
    Wall(u8),
    /// Part `k` of a suite object (`crate::suite`); textured by the scene's texture style.
    Part(u8),
    /// Facade segment `k` of the street scene (`crate::street`): scored like an object.
    Facade(u8),
}

impl Material {
    /// Whether this is scored geometry (mask = 1, in the object mesh): the objects, and the
    /// street's facades.
    pub fn is_object(self) -> bool {
        matches!(
            self,
            Material::Sphere
                | Material::Cuboid
                | Material::Torus
                | Material::Part(_)
                | Material::Facade(_)
        )
    }
}

/// The scene geometry with per-triangle materials and per-vertex shading normals.
#[derive(Debug, Clone)]
pub struct Geometry {
    /// Everything that is rendered: objects first (triangles `0..object_triangles`), then the
    /// floor and the walls.
    pub mesh: TriangleMesh,
    /// Number of object triangles at the start of `mesh.triangles`.
    pub object_triangles: usize,
    /// Number of object vertices at the start of `mesh.positions`.
    pub object_vertices: usize,
    /// Material of every triangle.
    pub material: Vec<Material>,
    /// Whether a triangle is shaded with interpolated vertex normals (sphere, torus).
    pub smooth: Vec<bool>,
    /// Analytic unit normal of every vertex (used only on smooth triangles).
    pub vertex_normals: Vec<DVec3>,
}

/// Accumulates triangles with materials, smoothness flags and analytic vertex normals.
#[derive(Default)]
pub(crate) struct Builder {
    pub(crate) positions: Vec<[f32; 3]>,
    pub(crate) normals: Vec<DVec3>,
    pub(crate) triangles: Vec<[u32; 3]>,
    pub(crate) material: Vec<Material>,
    pub(crate) smooth: Vec<bool>,
}

impl Builder {
    pub(crate) fn vertex(&mut self, p: DVec3, n: DVec3) -> u32 {
        self.positions.push([p.x as f32, p.y as f32, p.z as f32]);
        self.normals.push(n.normalize());
        (self.positions.len() - 1) as u32
    }

    /// Adds a triangle wound counter-clockwise seen from the side `outward` points to.
    pub(crate) fn triangle(
        &mut self,
        mut t: [u32; 3],
        outward: DVec3,
        material: Material,
        smooth: bool,
    ) {
        let p = |i: u32| {
            let v = self.positions[i as usize];
            DVec3::new(v[0] as f64, v[1] as f64, v[2] as f64)
        };
        let n = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0]));
        if n.length_squared() == 0.0 {
            return; // degenerate (only possible at sphere poles with coincident vertices)
        }
        if n.dot(outward) < 0.0 {
            t.swap(1, 2);
        }
        self.triangles.push(t);
        self.material.push(material);
        self.smooth.push(smooth);
    }

    /// A quad `a b c d` (in order around its boundary) as two triangles.
    pub(crate) fn quad(
        &mut self,
        q: [u32; 4],
        outward: Option<DVec3>,
        material: Material,
        smooth: bool,
    ) {
        for t in [[q[0], q[1], q[2]], [q[0], q[2], q[3]]] {
            let out = outward
                .unwrap_or_else(|| t.iter().map(|&i| self.normals[i as usize]).sum::<DVec3>());
            self.triangle(t, out, material, smooth);
        }
    }

    pub(crate) fn sphere(
        &mut self,
        centre: DVec3,
        radius: f64,
        (n_lon, n_lat): (usize, usize),
        m: Material,
    ) {
        let mut rings: Vec<Vec<u32>> = Vec::with_capacity(n_lat + 1);
        for i in 0..=n_lat {
            let theta = std::f64::consts::PI * i as f64 / n_lat as f64;
            let count = if i == 0 || i == n_lat { 1 } else { n_lon };
            let ring = (0..count)
                .map(|j| {
                    let phi = std::f64::consts::TAU * j as f64 / n_lon as f64;
                    let n = if count == 1 {
                        DVec3::new(0.0, 0.0, theta.cos().signum())
                    } else {
                        DVec3::new(
                            theta.sin() * phi.cos(),
                            theta.sin() * phi.sin(),
                            theta.cos(),
                        )
                    };
                    self.vertex(centre + radius * n, n)
                })
                .collect();
            rings.push(ring);
        }
        for i in 0..n_lat {
            for j in 0..n_lon {
                let j1 = (j + 1) % n_lon;
                let (top, bottom) = (&rings[i], &rings[i + 1]);
                let a = top[j % top.len()];
                let b = top[j1 % top.len()];
                let c = bottom[j1 % bottom.len()];
                let d = bottom[j % bottom.len()];
                if top.len() == 1 {
                    let out = self.normals[c as usize] + self.normals[d as usize];
                    self.triangle([a, d, c], out, m, true);
                } else if bottom.len() == 1 {
                    let out = self.normals[a as usize] + self.normals[b as usize];
                    self.triangle([a, b, c], out, m, true);
                } else {
                    self.quad([a, b, c, d], None, m, true);
                }
            }
        }
    }

    #[allow(clippy::too_many_arguments)]
    pub(crate) fn torus(
        &mut self,
        centre: DVec3,
        rot: DMat3,
        major: f64,
        minor: f64,
        (nu, nv): (usize, usize),
        m: Material,
    ) {
        let mut idx = vec![0u32; nu * nv];
        for i in 0..nu {
            let u = std::f64::consts::TAU * i as f64 / nu as f64;
            for j in 0..nv {
                let v = std::f64::consts::TAU * j as f64 / nv as f64;
                let n = DVec3::new(v.cos() * u.cos(), v.cos() * u.sin(), v.sin());
                let p = DVec3::new(
                    (major + minor * v.cos()) * u.cos(),
                    (major + minor * v.cos()) * u.sin(),
                    minor * v.sin(),
                );
                idx[i * nv + j] = self.vertex(centre + rot * p, rot * n);
            }
        }
        for i in 0..nu {
            for j in 0..nv {
                let (i1, j1) = ((i + 1) % nu, (j + 1) % nv);
                let q = [
                    idx[i * nv + j],
                    idx[i1 * nv + j],
                    idx[i1 * nv + j1],
                    idx[i * nv + j1],
                ];
                self.quad(q, None, m, true);
            }
        }
    }

    pub(crate) fn cuboid(&mut self, centre: DVec3, half: DVec3, rot: DMat3, m: Material) {
        let mut corner = [0u32; 8];
        for (k, c) in corner.iter_mut().enumerate() {
            let s = DVec3::new(
                if k & 1 == 0 { -1.0 } else { 1.0 },
                if k & 2 == 0 { -1.0 } else { 1.0 },
                if k & 4 == 0 { -1.0 } else { 1.0 },
            );
            *c = self.vertex(centre + rot * (s * half), rot * s);
        }
        // Faces as corner-bit quads in boundary order, with their outward axis.
        let faces: [([usize; 4], DVec3); 6] = [
            ([0, 2, 6, 4], -DVec3::X),
            ([1, 3, 7, 5], DVec3::X),
            ([0, 1, 5, 4], -DVec3::Y),
            ([2, 3, 7, 6], DVec3::Y),
            ([0, 1, 3, 2], -DVec3::Z),
            ([4, 5, 7, 6], DVec3::Z),
        ];
        for (q, axis) in faces {
            self.quad(q.map(|k| corner[k]), Some(rot * axis), m, false);
        }
    }

    /// A flat rectangle with corners in boundary order facing `normal`.
    pub(crate) fn rectangle(&mut self, corners: [DVec3; 4], normal: DVec3, material: Material) {
        let q = corners.map(|c| self.vertex(c, normal));
        self.quad(q, Some(normal), material, false);
    }
}

fn deg(x: f64) -> f64 {
    x.to_radians()
}

/// Builds the built-in scene geometry (deterministic, independent of all options).
pub fn build() -> Geometry {
    let mut b = Builder::default();
    let (sc, sr) = SPHERE;
    b.sphere(DVec3::from_array(sc), sr, SPHERE_SEGMENTS, Material::Sphere);
    let (bc, bh, yaw) = CUBOID;
    b.cuboid(
        DVec3::from_array(bc),
        DVec3::from_array(bh),
        DMat3::from_rotation_z(deg(yaw)),
        Material::Cuboid,
    );
    let (major, minor, tilt, tyaw, [tx, ty]) = TORUS;
    let rot = DMat3::from_rotation_z(deg(tyaw)) * DMat3::from_rotation_x(deg(tilt));
    let tz = major * deg(tilt).sin() + minor;
    b.torus(
        DVec3::new(tx, ty, tz),
        rot,
        major,
        minor,
        TORUS_SEGMENTS,
        Material::Torus,
    );
    let object_triangles = b.triangles.len();
    let object_vertices = b.positions.len();

    b.room(ROOM_HALF, ROOM_HALF, WALL_HEIGHT);
    b.finish(object_triangles, object_vertices)
}

impl Builder {
    /// The floor `[−hx, hx] × [−hy, hy]` at z = 0 and four walls of height `h` facing into the
    /// room (0 = x = +hx, 1 = x = −hx, 2 = y = +hy, 3 = y = −hy); no ceiling.
    pub(crate) fn room(&mut self, hx: f64, hy: f64, h: f64) {
        let b = self;
        b.rectangle(
            [
                DVec3::new(-hx, -hy, 0.0),
                DVec3::new(hx, -hy, 0.0),
                DVec3::new(hx, hy, 0.0),
                DVec3::new(-hx, hy, 0.0),
            ],
            DVec3::Z,
            Material::Floor,
        );
        for (k, (axis, sign)) in [(0usize, 1.0), (0, -1.0), (1, 1.0), (1, -1.0)]
            .into_iter()
            .enumerate()
        {
            // Half length along the wall and the wall's distance from the centre.
            let (along, off) = if axis == 0 { (hy, hx) } else { (hx, hy) };
            let corners: [DVec3; 4] =
                [(-along, 0.0), (along, 0.0), (along, h), (-along, h)].map(|(s, z)| {
                    if axis == 0 {
                        DVec3::new(sign * off, s, z)
                    } else {
                        DVec3::new(s, sign * off, z)
                    }
                });
            let mut inward = DVec3::ZERO;
            inward[axis] = -sign;
            b.rectangle(corners, inward, Material::Wall(k as u8));
        }
    }

    /// The finished geometry; the first `object_triangles` triangles (and `object_vertices`
    /// vertices) are the objects.
    pub(crate) fn finish(self, object_triangles: usize, object_vertices: usize) -> Geometry {
        Geometry {
            mesh: TriangleMesh {
                positions: self.positions,
                triangles: self.triangles,
                colors: None,
            },
            object_triangles,
            object_vertices,
            material: self.material,
            smooth: self.smooth,
            vertex_normals: self.normals,
        }
    }
}

impl Geometry {
    /// The objects only (sphere, box, torus), with the same vertex and triangle indices as in
    /// the scene mesh.
    pub fn object_mesh(&self) -> TriangleMesh {
        TriangleMesh {
            positions: self.mesh.positions[..self.object_vertices].to_vec(),
            triangles: self.mesh.triangles[..self.object_triangles].to_vec(),
            colors: None,
        }
    }

    /// Unit shading normal at barycentrics `(u, v)` of triangle `tri` (interpolated vertex
    /// normals on smooth triangles, the face normal otherwise), not yet oriented.
    pub fn shading_normal(&self, tri: u32, u: f64, v: f64) -> (DVec3, DVec3) {
        let t = self.mesh.triangles[tri as usize];
        let p = |i: u32| {
            let q = self.mesh.positions[i as usize];
            DVec3::new(q[0] as f64, q[1] as f64, q[2] as f64)
        };
        let face = (p(t[1]) - p(t[0])).cross(p(t[2]) - p(t[0])).normalize();
        if !self.smooth[tri as usize] {
            return (face, face);
        }
        let n = self.vertex_normals[t[0] as usize] * (1.0 - u - v)
            + self.vertex_normals[t[1] as usize] * u
            + self.vertex_normals[t[2] as usize] * v;
        (n.normalize_or(face), face)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn triangles_are_wound_outward_and_valid() {
        let g = build();
        g.mesh.validate().unwrap();
        assert_eq!(g.material.len(), g.mesh.triangles.len());
        let centre_of = |m: Material| match m {
            Material::Cuboid => Some(DVec3::from_array(CUBOID.0)),
            _ => None,
        };
        for (k, t) in g.mesh.triangles.iter().enumerate() {
            let (n, face) = g.shading_normal(k as u32, 1.0 / 3.0, 1.0 / 3.0);
            // Smooth normals agree with the winding.
            assert!(
                n.dot(face) > 0.9,
                "triangle {k} ({:?}) wound against its normal",
                g.material[k]
            );
            if let Some(c) = centre_of(g.material[k]) {
                let p = DVec3::from_array(g.mesh.positions[t[0] as usize].map(|v| v as f64));
                assert!(face.dot(p - c) > 0.0);
            }
            if g.material[k] == Material::Floor {
                assert_eq!(face, DVec3::Z);
            }
            assert_eq!(g.material[k].is_object(), k < g.object_triangles);
        }
    }

    #[test]
    fn objects_rest_on_the_floor_inside_the_room() {
        let g = build();
        let (lo, hi) = g.object_mesh().bounds().unwrap();
        assert!(lo[2].abs() < 1e-6, "lowest object point {}", lo[2]);
        assert!(hi.iter().chain(lo.iter()).all(|v| v.abs() < 1.5));
        let (slo, shi) = g.mesh.bounds().unwrap();
        assert_eq!(slo, [-4.0, -4.0, 0.0]);
        assert_eq!(shi, [4.0, 4.0, 2.2]);
    }
}
