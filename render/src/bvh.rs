//! Ray casting: every triangle of the scene (model and emitters) in one obvhs CWBVH, with a
//! Möller–Trumbore test on precomputed edges stored in BVH order.

use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::cwbvh::builder::build_cwbvh_from_tris;
use obvhs::cwbvh::CwBvh;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;

#[derive(Clone, Copy)]
struct TriAccel {
    p0: Vec3A,
    e1: Vec3A,
    e2: Vec3A,
    prim: u32,
}

/// The closest hit of a ray.
#[derive(Clone, Copy, Debug)]
pub struct Hit {
    pub t: f32,
    /// Index into the triangle list given to [`Bvh::new`].
    pub prim: u32,
    /// Barycentric weights of vertices 1 and 2.
    pub b1: f32,
    pub b2: f32,
}

/// A BVH over triangles.
pub struct Bvh {
    bvh: CwBvh,
    tris: Vec<TriAccel>,
}

#[inline(always)]
fn intersect(tri: &TriAccel, o: Vec3A, d: Vec3A, tmax: f32) -> Option<(f32, f32, f32)> {
    let pvec = d.cross(tri.e2);
    let det = tri.e1.dot(pvec);
    if det.abs() < 1e-14 {
        return None;
    }
    let inv = 1.0 / det;
    let tvec = o - tri.p0;
    let u = tvec.dot(pvec) * inv;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(tri.e1);
    let v = d.dot(qvec) * inv;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = tri.e2.dot(qvec) * inv;
    (t > 0.0 && t < tmax).then_some((t, u, v))
}

#[inline(always)]
fn obvhs_ray(o: Vec3A, d: Vec3A, tmax: f32) -> Ray {
    Ray::new(o.to_array().into(), d.to_array().into(), 0.0, tmax)
}

impl Bvh {
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        let tris: Vec<Triangle> = triangles
            .iter()
            .map(|t| Triangle { v0: t[0].to_array().into(), v1: t[1].to_array().into(), v2: t[2].to_array().into() })
            .collect();
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::very_slow_build(), &mut Duration::default());
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| {
                let t = &triangles[i as usize];
                TriAccel { p0: t[0].into(), e1: (t[1] - t[0]).into(), e2: (t[2] - t[0]).into(), prim: i }
            })
            .collect();
        Bvh { bvh, tris }
    }

    /// Closest hit with `0 < t < tmax`; `d` must be unit length for `t` to be a distance.
    pub fn intersect(&self, o: Vec3, d: Vec3, tmax: f32) -> Option<Hit> {
        let (o, d) = (Vec3A::from(o), Vec3A::from(d));
        let mut hit = RayHit::none();
        let mut best = (0.0f32, 0.0f32);
        let found = self.bvh.ray_traverse(obvhs_ray(o, d, tmax), &mut hit, |ray, id| {
            let tri = &self.tris[id];
            match intersect(tri, o, d, ray.tmax) {
                Some((t, u, v)) => {
                    best = (u, v);
                    t
                }
                None => f32::INFINITY,
            }
        });
        found.then(|| Hit { t: hit.t, prim: self.tris[hit.primitive_id as usize].prim, b1: best.0, b2: best.1 })
    }

    /// Whether anything lies on the segment `0 < t < tmax`.
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        let (o, d) = (Vec3A::from(o), Vec3A::from(d));
        !self.bvh.ray_traverse_miss(obvhs_ray(o, d, tmax), |_, id| {
            intersect(&self.tris[id], o, d, tmax).map_or(f32::INFINITY, |h| h.0)
        })
    }
}
