//! One path's steps, cut at the material lookup: [`Renderer::advance_to_surface`] traces a
//! segment and samples next-event estimation, [`Renderer::shade_and_continue`] takes the
//! material's sample there and extends the path. Between the two a caller evaluates the
//! material, one hit at a time ([`Renderer::li`]) or for the hits of a packet of paths that
//! share a part in one batch (the render loop), which is where the JIT's SIMD lanes pay.
//!
//! The cut changes no arithmetic: a path's random numbers and its additions to its pixel are
//! those of the uncut loop, in the same order.

use glam::Vec3;

use super::{power_heuristic, PathConfig, PathState, Renderer};
use crate::brdf::Karis;
use crate::emitters::Distribution1D;
use crate::geometry::{SurfaceHit, Traced};
use crate::material::SurfaceSample;

/// A path between segments: where its next ray starts and what it carries.
#[derive(Clone, Copy, Debug)]
pub(super) struct PathVertex {
    o: Vec3,
    d: Vec3,
    beta: Vec3,
    /// Solid-angle pdf of `d` (0: not sampled from a BRDF, so no MIS on what it hits).
    prev_pdf: f32,
    depth: u32,
}

impl PathVertex {
    /// A path leaving `o` along `d` (unit) with nothing sampled yet.
    pub(super) fn start(o: Vec3, d: Vec3) -> Self {
        PathVertex { o, d, beta: Vec3::ONE, prev_pdf: 0.0, depth: 0 }
    }
}

/// A path stopped on a surface, waiting for the material's sample there.
#[derive(Clone, Copy, Debug)]
pub(super) struct SurfaceStop {
    pub(super) hit: SurfaceHit,
    /// The face normal on the side the path arrived from.
    ng: Vec3,
    /// Where rays leave the surface (offset along `ng`).
    origin: Vec3,
    /// Next-event estimation, sampled and found unoccluded: (slot, wi, radiance, light pdf).
    nee: Option<(usize, Vec3, Vec3, f32)>,
}

impl Renderer {
    /// Traces the path's next segment. What it sees of emitters and the environment goes into
    /// `st.out`, and the path ends there (`None`), or at the depth limit; on a surface, samples
    /// next-event estimation (its visibility tested with the geometric tests only: the
    /// shading-frame test and the contribution wait for the material) and returns the stop.
    #[inline(always)]
    pub(super) fn advance_to_surface(
        &self,
        v: &PathVertex,
        sel: &Distribution1D,
        cfg: &PathConfig,
        st: &mut PathState,
    ) -> Option<SurfaceStop> {
        let n_lights = self.lights.len();
        let (d, prev_pdf) = (v.d, v.prev_pdf);
        st.rays += 1;
        let hit = match self.geometry.trace(v.o, d, f32::INFINITY) {
            Traced::Miss => {
                if let Some(env) = &self.env {
                    let w =
                        if prev_pdf > 0.0 { power_heuristic(prev_pdf, sel.pmf(n_lights) * env.pdf(d)) } else { 1.0 };
                    st.out[n_lights] += v.beta * env.eval(d) * w;
                }
                return None;
            }
            Traced::Emitter { light, n, t } => {
                let cos_l = -n.dot(d);
                if cos_l > 0.0 && !(cfg.skip_direct_emitters && v.depth == 0) {
                    let k = light as usize;
                    let w = if prev_pdf > 0.0 {
                        let pdf_l = sel.pmf(k) / self.lights.areas[k] * t * t / cos_l;
                        power_heuristic(prev_pdf, pdf_l)
                    } else {
                        1.0
                    };
                    st.out[k] += v.beta * w;
                }
                return None; // emitters do not reflect
            }
            Traced::Surface(h) => h,
        };
        if v.depth + 1 >= cfg.max_depth {
            return None;
        }
        let wo = -d;
        // The material's texels load while the shadow ray is traced.
        self.materials[hit.part as usize].prefetch(hit.uv);
        let ng = if hit.ng.dot(wo) >= 0.0 { hit.ng } else { -hit.ng };
        let origin = self.geometry.offset(hit.p, ng);

        let mut nee = None;
        if sel.total > 0.0 {
            let (slot, u_tri) = sel.sample(st.rng.next_f32());
            let p_sel = sel.pmf(slot);
            let u = st.rng.next_2d();
            if slot < n_lights {
                if let Some(lp) = self.lights.sample(slot, u_tri, u) {
                    let to = lp.p - origin;
                    let dist2 = to.length_squared();
                    let dist = dist2.sqrt();
                    let wi = to / dist;
                    let cos_l = -lp.n.dot(wi);
                    if cos_l > 0.0 && wi.dot(ng) > 0.0 {
                        st.rays += 1;
                        if !self.geometry.occluded(origin, wi, dist * (1.0 - 1e-4) - self.geometry.eps) {
                            nee = Some((slot, wi, Vec3::ONE, p_sel * lp.pdf_area * dist2 / cos_l));
                        }
                    }
                }
            } else if let Some(env) = &self.env {
                if let Some((wi, le, pdf)) = env.sample(u) {
                    if wi.dot(ng) > 0.0 && pdf > 0.0 {
                        st.rays += 1;
                        if !self.geometry.occluded(origin, wi, f32::INFINITY) {
                            nee = Some((slot, wi, le, p_sel * pdf));
                        }
                    }
                }
            }
        }
        Some(SurfaceStop { hit, ng, origin, nee })
    }

    /// Shades the stop with the material's sample `s` there: adds the next-event contribution
    /// and samples the BRDF for the path's next direction (with Russian roulette past
    /// `rr_depth`). `false` when the path ends.
    #[inline(always)]
    pub(super) fn shade_and_continue(
        &self,
        v: &mut PathVertex,
        stop: &SurfaceStop,
        s: SurfaceSample,
        cfg: &PathConfig,
        st: &mut PathState,
    ) -> bool {
        let wo = -v.d;
        let sf = self.geometry.shading_frame(&stop.hit, wo, s.normal);
        let mut brdf = Karis::new(Vec3::from(s.albedo), s.roughness);
        if cfg.diffuse_only {
            brdf = brdf.diffuse_only();
        }
        let wo_l = sf.frame.to_local(wo);
        if wo_l.z <= 0.0 {
            return false;
        }
        let brdf = brdf.at(wo_l);
        if let Some((slot, wi, le, pdf_l)) = stop.nee {
            let wi_l = sf.frame.to_local(wi);
            if wi_l.z > 0.0 {
                let (f, pdf_b) = brdf.eval_pdf(wi_l);
                let w = power_heuristic(pdf_l, pdf_b);
                st.out[slot] += v.beta * f * le * (wi_l.z * w / pdf_l);
            }
        }

        let u_lobe = st.rng.next_f32();
        let u = st.rng.next_2d();
        let Some(bs) = brdf.sample(u_lobe, u) else { return false };
        let wi = sf.frame.to_world(bs.wi);
        if wi.dot(stop.ng) <= 0.0 {
            return false;
        }
        v.beta *= bs.weight;
        v.prev_pdf = bs.pdf;
        v.o = stop.origin;
        v.d = wi;
        v.depth += 1;
        if v.depth >= cfg.rr_depth {
            let q = v.beta.max_element().min(0.95);
            let u = st.rng.next_f32();
            if u.is_nan() || u >= q {
                return false;
            }
            v.beta /= q;
        }
        true
    }
}
