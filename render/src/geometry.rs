//! The scene as the tracer sees it: model triangles (with uv, normals, tangent frames and part
//! ids) and emitter triangles in one BVH, and the local shading frame at a hit.

use glam::Vec3;

use crate::brdf::Frame;
use crate::bvh::Bvh;
use crate::emitters::AreaLights;
use crate::scene::Scene;

/// A hit on the model.
#[derive(Clone, Copy, Debug)]
pub struct SurfaceHit {
    pub t: f32,
    pub p: Vec3,
    /// Unit face normal from the winding (not flipped).
    pub ng: Vec3,
    /// Unit interpolated vertex normal, or `ng` when the OBJ has none.
    pub ns: Vec3,
    /// Mesh uv (OBJ convention, before any uv transform).
    pub uv: [f32; 2],
    pub dpdu: Vec3,
    pub dpdv: Vec3,
    pub part: u32,
    pub prim: u32,
}

/// What a ray hit.
#[derive(Clone, Copy, Debug)]
pub enum Traced {
    Miss,
    Surface(SurfaceHit),
    /// An emitter triangle: light index, its unit emitting normal, distance.
    Emitter {
        light: u32,
        n: Vec3,
        t: f32,
    },
}

/// Oriented shading geometry at a hit, for an outgoing direction.
#[derive(Clone, Copy, Debug)]
pub struct ShadingFrame {
    /// Face normal flipped to the side of `wo`.
    pub ng: Vec3,
    /// The (possibly normal-mapped) shading frame, z = shading normal on the side of `wo`.
    pub frame: Frame,
    /// Unit tangent (along dp/du, orthogonal to the unperturbed normal).
    pub tangent: Vec3,
    /// Unit bitangent (± n × t, with the sign of dp/dv).
    pub bitangent: Vec3,
}

pub struct SceneGeometry {
    pub bvh: Bvh,
    pub n_surface: u32,
    tri_v: Vec<[u32; 3]>,
    tri_ng: Vec<Vec3>,
    tri_dpduv: Vec<(Vec3, Vec3)>,
    /// Unit tangent and bitangent of the face-normal frame (what [`Self::shading_frame`] builds
    /// when the mesh has no vertex normals; the same for both sides).
    tri_tb: Vec<(Vec3, Vec3)>,
    tri_part: Vec<u32>,
    positions: Vec<Vec3>,
    normals: Vec<Vec3>,
    uvs: Vec<[f32; 2]>,
    /// For emitter triangles (prim ≥ n_surface): light index and unit normal.
    emitter: Vec<(u32, Vec3)>,
    /// Ray origin offset (scene units).
    pub eps: f32,
}

impl SceneGeometry {
    pub fn new(scene: &Scene, lights: &AreaLights) -> Self {
        let mesh = &scene.mesh;
        let mut all: Vec<[Vec3; 3]> = Vec::with_capacity(mesh.triangles.len());
        let mut tri_ng = Vec::with_capacity(mesh.triangles.len());
        let mut tri_dpduv = Vec::with_capacity(mesh.triangles.len());
        let mut extent = 0.0f32;
        for tri in &mesh.triangles {
            let p = tri.map(|i| mesh.positions[i as usize]);
            let uv = tri.map(|i| mesh.uvs[i as usize]);
            for q in &p {
                extent = extent.max(q.abs().max_element());
            }
            let ng = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            let (d02, d12) = (p[0] - p[2], p[1] - p[2]);
            let (a, b) = ([uv[0][0] - uv[2][0], uv[0][1] - uv[2][1]], [uv[1][0] - uv[2][0], uv[1][1] - uv[2][1]]);
            let det = a[0] * b[1] - a[1] * b[0];
            let (dpdu, dpdv) = if det.abs() > 1e-12 {
                let inv = 1.0 / det;
                ((d02 * b[1] - d12 * a[1]) * inv, (d12 * a[0] - d02 * b[0]) * inv)
            } else {
                let f = Frame::from_normal(ng);
                (f.t, f.b)
            };
            all.push(p);
            tri_ng.push(ng);
            tri_dpduv.push((dpdu, dpdv));
        }
        let tri_tb = tri_ng.iter().zip(&tri_dpduv).map(|(&ng, &(dpdu, dpdv))| tangent_frame(ng, dpdu, dpdv)).collect();
        let n_surface = all.len() as u32;
        let mut emitter = Vec::new();
        for (k, tris) in lights.tris.iter().enumerate() {
            for t in tris {
                all.push([t.p0, t.p0 + t.e1, t.p0 + t.e2]);
                emitter.push((k as u32, t.n));
            }
        }
        SceneGeometry {
            bvh: Bvh::new(&all),
            n_surface,
            tri_v: mesh.triangles.clone(),
            tri_ng,
            tri_dpduv,
            tri_tb,
            tri_part: mesh.tri_part.clone(),
            positions: mesh.positions.clone(),
            normals: mesh.normals.clone(),
            uvs: mesh.uvs.clone(),
            emitter,
            eps: 2e-5 * (1.0 + extent),
        }
    }

    /// Closest hit along a unit direction.
    #[inline(always)]
    pub fn trace(&self, o: Vec3, d: Vec3, tmax: f32) -> Traced {
        let Some(h) = self.bvh.intersect(o, d, tmax) else { return Traced::Miss };
        if h.prim >= self.n_surface {
            let (light, n) = self.emitter[(h.prim - self.n_surface) as usize];
            return Traced::Emitter { light, n, t: h.t };
        }
        let i = h.prim as usize;
        let v = self.tri_v[i];
        let b0 = 1.0 - h.b1 - h.b2;
        let p = self.positions[v[0] as usize] * b0
            + self.positions[v[1] as usize] * h.b1
            + self.positions[v[2] as usize] * h.b2;
        let uvs = v.map(|k| self.uvs[k as usize]);
        let uv = [
            uvs[0][0] * b0 + uvs[1][0] * h.b1 + uvs[2][0] * h.b2,
            uvs[0][1] * b0 + uvs[1][1] * h.b1 + uvs[2][1] * h.b2,
        ];
        let ng = self.tri_ng[i];
        let ns = if self.normals.is_empty() {
            ng
        } else {
            let n = self.normals[v[0] as usize] * b0
                + self.normals[v[1] as usize] * h.b1
                + self.normals[v[2] as usize] * h.b2;
            n.try_normalize().unwrap_or(ng)
        };
        let (dpdu, dpdv) = self.tri_dpduv[i];
        Traced::Surface(SurfaceHit { t: h.t, p, ng, ns, uv, dpdu, dpdv, part: self.tri_part[i], prim: h.prim })
    }

    #[inline]
    pub fn occluded(&self, o: Vec3, d: Vec3, tmax: f32) -> bool {
        self.bvh.occluded(o, d, tmax)
    }

    /// Shading frame at `hit` seen from `wo` (unit, away from the surface), with a tangent-space
    /// normal `tn` from the material (`[0, 0, 1]` = unperturbed). Surfaces are two-sided: the
    /// frame is built on the side `wo` is on. A perturbed normal that would hide `wo` is ignored.
    #[inline(always)]
    pub fn shading_frame(&self, hit: &SurfaceHit, wo: Vec3, tn: [f32; 3]) -> ShadingFrame {
        let ng = if hit.ng.dot(wo) >= 0.0 { hit.ng } else { -hit.ng };
        let (n, t, b) = if self.normals.is_empty() && hit.prim < self.n_surface {
            // Flat shading: the tangent frame is per triangle and does not depend on the side.
            let (t, b) = self.tri_tb[hit.prim as usize];
            (ng, t, b)
        } else {
            let n = if hit.ns.dot(ng) >= 0.0 { hit.ns } else { -hit.ns };
            let (t, b) = tangent_frame(n, hit.dpdu, hit.dpdv);
            (n, t, b)
        };
        let mut ns = n;
        if tn != [0.0, 0.0, 1.0] {
            let m = (t * tn[0] + b * tn[1] + n * tn[2]).normalize_or_zero();
            if m.dot(wo) > 1e-4 && m.dot(ng) > 0.0 {
                ns = m;
            }
        }
        if ns.dot(wo) <= 0.0 {
            ns = ng;
        }
        // t is already orthogonal to n: only a perturbed normal needs a new tangent.
        let frame = if ns == n { Frame { t, b: n.cross(t), n } } else { Frame::new(ns, t) };
        ShadingFrame { ng, frame, tangent: t, bitangent: b }
    }

    /// Origin for a ray leaving `p` on the side of the (oriented) normal `n`.
    #[inline]
    pub fn offset(&self, p: Vec3, n: Vec3) -> Vec3 {
        p + n * self.eps
    }
}

/// Unit tangent along `dpdu` orthogonal to `n`, and the bitangent `± n × t` with the sign of
/// `dpdv` (both unchanged when `n` flips).
fn tangent_frame(n: Vec3, dpdu: Vec3, dpdv: Vec3) -> (Vec3, Vec3) {
    let base = Frame::new(n, dpdu);
    let sign = if base.b.dot(dpdv) < 0.0 { -1.0 } else { 1.0 };
    (base.t, base.b * sign)
}
