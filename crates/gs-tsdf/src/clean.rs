//! Mesh clean-up: degenerate and unreferenced elements, connected components, mask culling.

use crate::error::{Result, TsdfError};
use gs_core::{Camera, Image, TriangleMesh};
use serde::Serialize;

/// Which connected components [`filter_components`] keeps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ComponentFilter {
    /// Only the component with the most triangles (ties: the one with the lowest triangle index).
    Largest,
    /// Every component with at least this many triangles.
    MinTriangles(usize),
    /// Every component with at least `share` of the mesh's triangles and at least
    /// `min_triangles`: small pieces are judged relative to the scene, not by a fixed count
    /// that a finer voxel makes every speck pass.
    MinShare {
        /// Fraction of all triangles, in [0, 1].
        share: f64,
        /// Absolute floor.
        min_triangles: usize,
    },
}

/// What [`filter_components`] kept and removed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize)]
pub struct ComponentReport {
    /// Connected components before.
    pub components: usize,
    /// Components removed.
    pub removed: usize,
    /// Triangles of the removed components.
    pub triangles_removed: usize,
}

/// Drops vertices no triangle uses and renumbers the rest in their original order.
pub fn remove_unreferenced_vertices(mesh: &TriangleMesh) -> TriangleMesh {
    let n = mesh.positions.len();
    let mut remap = vec![u32::MAX; n];
    for t in &mesh.triangles {
        for &v in t {
            if (v as usize) < n {
                remap[v as usize] = 0;
            }
        }
    }
    let mut positions = Vec::new();
    let mut colors = mesh.colors.as_ref().map(|_| Vec::new());
    for (i, r) in remap.iter_mut().enumerate() {
        if *r == 0 {
            *r = positions.len() as u32;
            positions.push(mesh.positions[i]);
            if let (Some(out), Some(src)) = (colors.as_mut(), mesh.colors.as_ref()) {
                out.push(src[i]);
            }
        }
    }
    let triangles = mesh
        .triangles
        .iter()
        .filter(|t| t.iter().all(|&v| (v as usize) < n))
        .map(|t| t.map(|v| remap[v as usize]))
        .collect();
    TriangleMesh { positions, triangles, colors }
}

/// Drops triangles with repeated vertex indices or zero area (then unreferenced vertices).
pub fn remove_degenerate_triangles(mesh: &TriangleMesh) -> TriangleMesh {
    let keep: Vec<[u32; 3]> = mesh
        .triangles
        .iter()
        .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2] && mesh.triangle_area(t) > 0.0)
        .copied()
        .collect();
    remove_unreferenced_vertices(&TriangleMesh { triangles: keep, ..mesh.clone() })
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[parent[x as usize] as usize];
        parent[x as usize] = p;
        x = p;
    }
    x
}

/// Connected component label of each triangle (triangles sharing a vertex are connected),
/// labels numbered by first appearance; and the number of components.
pub fn triangle_components(mesh: &TriangleMesh) -> Result<(Vec<u32>, usize)> {
    mesh.validate()?;
    let mut parent: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    for t in &mesh.triangles {
        let mut a = find(&mut parent, t[0]);
        for &v in &t[1..] {
            let b = find(&mut parent, v);
            if a != b {
                let (lo, hi) = if a < b { (a, b) } else { (b, a) };
                parent[hi as usize] = lo;
                // The union's root: joining the third vertex to the old `a`, no longer a root,
                // would cut `a`'s tree off from `b`'s.
                a = lo;
            }
        }
    }
    let mut label_of_root = vec![u32::MAX; mesh.positions.len()];
    let mut next = 0u32;
    let labels = mesh
        .triangles
        .iter()
        .map(|t| {
            let r = find(&mut parent, t[0]) as usize;
            if label_of_root[r] == u32::MAX {
                label_of_root[r] = next;
                next += 1;
            }
            label_of_root[r]
        })
        .collect();
    Ok((labels, next as usize))
}

/// Keeps the connected components selected by `filter` (e.g. drops floating fragments).
pub fn filter_components(mesh: &TriangleMesh, filter: ComponentFilter) -> Result<(TriangleMesh, ComponentReport)> {
    if let ComponentFilter::MinShare { share, .. } = filter
        && !(0.0..=1.0).contains(&share)
    {
        return Err(TsdfError::InvalidParameter(format!("component share {share} is not a fraction in [0, 1]")));
    }
    let (labels, count) = triangle_components(mesh)?;
    let mut sizes = vec![0usize; count];
    for &l in &labels {
        sizes[l as usize] += 1;
    }
    let keep_label: Vec<bool> = match filter {
        ComponentFilter::Largest => {
            // max_by_key returns the last maximum; labels follow first appearance, so pick the first.
            let best = sizes.iter().enumerate().fold(None, |acc: Option<(usize, usize)>, (i, &s)| match acc {
                Some((_, bs)) if bs >= s => acc,
                _ => Some((i, s)),
            });
            (0..count).map(|i| Some(i) == best.map(|b| b.0)).collect()
        }
        ComponentFilter::MinTriangles(k) => sizes.iter().map(|&s| s >= k).collect(),
        ComponentFilter::MinShare { share, min_triangles } => {
            let k = ((share * labels.len() as f64).ceil() as usize).max(min_triangles);
            sizes.iter().map(|&s| s >= k).collect()
        }
    };
    let removed = keep_label.iter().filter(|k| !**k).count();
    let triangles_removed = sizes.iter().zip(&keep_label).filter(|(_, k)| !**k).map(|(s, _)| s).sum();
    let triangles =
        mesh.triangles.iter().zip(&labels).filter(|(_, l)| keep_label[**l as usize]).map(|(t, _)| *t).collect();
    let report = ComponentReport { components: count, removed, triangles_removed };
    Ok((remove_unreferenced_vertices(&TriangleMesh { triangles, ..mesh.clone() }), report))
}

/// The standard clean-up after marching cubes (docs/method.md §TSDF): keep the components selected by
/// `filter`, then drop degenerate triangles and unreferenced vertices.
pub fn clean_mesh(mesh: &TriangleMesh, filter: ComponentFilter) -> Result<(TriangleMesh, ComponentReport)> {
    let (kept, report) = filter_components(mesh, filter)?;
    Ok((remove_unreferenced_vertices(&remove_degenerate_triangles(&kept)), report))
}

/// DTU-style culling: drops every vertex that projects inside some view's image (in front of
/// the camera) onto a mask pixel < 0.5, with the triangles using it. Masks are 1-channel images
/// of the camera's size.
pub fn cull_by_masks(mesh: &TriangleMesh, views: &[(&Camera, &Image)]) -> Result<TriangleMesh> {
    mesh.validate()?;
    for (i, (cam, m)) in views.iter().enumerate() {
        if m.width() != cam.width as usize || m.height() != cam.height as usize || m.channels() != 1 {
            return Err(TsdfError::InvalidInput {
                view: i,
                problem: format!(
                    "mask is {}x{}x{}, camera is {}x{}",
                    m.width(),
                    m.height(),
                    m.channels(),
                    cam.width,
                    cam.height
                ),
            });
        }
    }
    use rayon::prelude::*;
    let drop: Vec<bool> = mesh
        .positions
        .par_iter()
        .map(|p| {
            let p = gs_core::glam::DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            views.iter().any(|(cam, m)| {
                cam.project(p).is_some_and(|(px, _)| {
                    cam.contains(px) && m.get(px.x as usize, px.y as usize, 0) < 0.5
                })
            })
        })
        .collect();
    let triangles = mesh.triangles.iter().filter(|t| t.iter().all(|&v| !drop[v as usize])).copied().collect();
    Ok(remove_unreferenced_vertices(&TriangleMesh { triangles, ..mesh.clone() }))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn two_pieces() -> TriangleMesh {
        // A quad (2 triangles) and a separate triangle, plus an unused vertex and a degenerate one.
        TriangleMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
                [50.0, 50.0, 5.0],
                [51.0, 50.0, 5.0],
                [50.0, 51.0, 5.0],
                [9.0, 9.0, 9.0],
            ],
            triangles: vec![[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 4, 5]],
            colors: None,
        }
    }

    #[test]
    fn components_and_degenerates() {
        let m = two_pieces();
        let (labels, count) = triangle_components(&m).unwrap();
        assert_eq!(count, 2);
        assert_eq!(labels, vec![0, 0, 1, 1]);
        let d = remove_degenerate_triangles(&m);
        assert_eq!(d.triangles.len(), 3);
        assert_eq!(d.positions.len(), 7);
        let (largest, r) = filter_components(&d, ComponentFilter::Largest).unwrap();
        assert_eq!(largest.triangles.len(), 2);
        assert_eq!(largest.positions.len(), 4);
        assert_eq!(r, ComponentReport { components: 2, removed: 1, triangles_removed: 1 });
        let (all, r) = filter_components(&d, ComponentFilter::MinTriangles(1)).unwrap();
        assert_eq!(all.triangles.len(), 3);
        assert_eq!(r.removed, 0);
        let (none, r) = filter_components(&d, ComponentFilter::MinTriangles(3)).unwrap();
        assert!(none.triangles.is_empty() && none.positions.is_empty());
        assert_eq!((r.removed, r.triangles_removed), (2, 3));
        assert!(filter_components(&TriangleMesh::default(), ComponentFilter::Largest).unwrap().0.triangles.is_empty());
        // Shares: the lone triangle is 1/3 of the mesh; a share above that drops it.
        let share = |s| filter_components(&d, ComponentFilter::MinShare { share: s, min_triangles: 1 }).unwrap();
        assert_eq!(share(0.33).0.triangles.len(), 3);
        assert_eq!(share(0.34).0.triangles.len(), 2);
        assert_eq!(share(0.34).1, ComponentReport { components: 2, removed: 1, triangles_removed: 1 });
        assert!(share(0.67).0.triangles.is_empty());
        let floor = filter_components(&d, ComponentFilter::MinShare { share: 0.0, min_triangles: 2 }).unwrap();
        assert_eq!(floor.0.triangles.len(), 2);
        for bad in [-0.1, 1.5, f64::NAN] {
            assert!(filter_components(&d, ComponentFilter::MinShare { share: bad, min_triangles: 1 }).is_err());
        }
    }

    #[test]
    fn mask_culling_drops_vertices_outside_the_mask() {
        use gs_core::Intrinsics;
        use gs_core::glam::DVec3;
        let cam = Camera::look_at(
            10,
            10,
            Intrinsics::new(10.0, 10.0, 5.0, 5.0),
            DVec3::new(0.5, 0.5, -5.0),
            DVec3::new(0.5, 0.5, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
        )
        .unwrap();
        let m = two_pieces();
        // Mask everything out: the quad near the optical axis projects inside and is dropped;
        // the far triangles at (50..51) project outside the image and survive.
        let mask = Image::filled(10, 10, 1, 0.0).unwrap();
        let out = cull_by_masks(&m, &[(&cam, &mask)]).unwrap();
        assert_eq!(out.triangles, vec![[0, 1, 2], [0, 0, 1]]);
        assert_eq!(out.positions.len(), 3);
        let full = Image::filled(10, 10, 1, 1.0).unwrap();
        assert_eq!(cull_by_masks(&m, &[(&cam, &full)]).unwrap().triangles.len(), 4);
        let wrong = Image::filled(5, 10, 1, 1.0).unwrap();
        assert!(cull_by_masks(&m, &[(&cam, &wrong)]).is_err());
    }

    #[test]
    fn a_triangle_joining_three_components_joins_them_all() {
        // [3, 0, 1] joins {2, 3, 4} (root 2) to {0} and then to {1}; a union that kept using 2
        // after it stopped being a root cut {0} off again, and [0, 5, 6] became a second component.
        let mesh = TriangleMesh {
            positions: (0..7).map(|i| [i as f32, (i * i) as f32, 0.0]).collect(),
            triangles: vec![[2, 3, 4], [3, 0, 1], [0, 5, 6]],
            colors: None,
        };
        let (labels, count) = triangle_components(&mesh).unwrap();
        assert_eq!((labels, count), (vec![0, 0, 0], 1));
    }
}
