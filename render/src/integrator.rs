//! The path tracer: unidirectional paths with next-event estimation on area lights and the
//! environment, multiple importance sampling (power heuristic), Russian roulette, Mitsuba 3's
//! depth convention (`max_depth` 1 = directly visible emitters only, 2 = direct light, ...).
//!
//! Radiance is accumulated per *light slot* (one per area light, then one for the environment)
//! at unit emission; an image is the slot images weighted by the light radiances, which gives
//! per-light renders for free and keeps them consistent with the combined one.
//!
//! Determinism: sample s of pixel i draws from `Rng::new(seed, i, s)` and pixels are reduced in a
//! fixed order, so the result does not depend on the thread count or scheduling.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;
use psc_base::progress::{self, NoProgress, Progress};
use rayon::prelude::*;

use crate::brdf::Karis;
use crate::camera::Camera;
use crate::emitters::{AreaLights, Distribution1D, EnvMap};
use crate::geometry::{SceneGeometry, Traced};
use crate::material::MaterialBinding;
use crate::rng::Rng;
use crate::scene::{LightRadiances, Scene};
use crate::RenderError;

mod options;

pub use options::{slot_file_names, PathConfig, RenderOptions, RenderOutput};

/// Everything needed to trace a scene with given materials and light radiances.
///
/// The light radiances decide how next-event estimation picks lights, so they change only
/// through [`Renderer::set_radiances`], which rebuilds that selection: a light solve that
/// re-renders with new radiances never samples with stale distributions.
pub struct Renderer {
    geometry: SceneGeometry,
    lights: AreaLights,
    env: Option<EnvMap>,
    materials: Vec<MaterialBinding>,
    part_names: Vec<String>,
    radiances: LightRadiances,
    /// Radiance per slot (lights, then environment scale).
    slot_radiance: Vec<Vec3>,
    slot_names: Vec<String>,
    /// Light selection for NEE weighted by power (area × luminance of radiance).
    select_power: Distribution1D,
    /// Light selection weighted by area only (per-light renders: every light gets samples).
    select_unit: Distribution1D,
}

#[inline]
fn luminance(c: Vec3) -> f32 {
    psc_base::color::luminance(c.to_array())
}

#[inline]
fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 > 0.0 {
        a2 / (a2 + b2)
    } else {
        0.0
    }
}

/// Per-thread counters and the slot accumulator of one estimate.
pub struct PathState<'a> {
    pub rng: Rng,
    pub rays: u64,
    pub out: &'a mut [Vec3],
}

impl Renderer {
    /// `materials` has one binding per model part (same order as `scene.mesh.part_names`).
    pub fn new(
        scene: &Scene,
        materials: Vec<MaterialBinding>,
        radiances: &LightRadiances,
    ) -> Result<Self, RenderError> {
        Self::new_with_progress(scene, materials, radiances, &NoProgress)
    }

    /// [`Renderer::new`], reporting the BVH build (the long part for large meshes; its length is
    /// not known in advance) to `progress`.
    pub fn new_with_progress(
        scene: &Scene,
        materials: Vec<MaterialBinding>,
        radiances: &LightRadiances,
        progress: &dyn Progress,
    ) -> Result<Self, RenderError> {
        if materials.len() != scene.mesh.part_names.len() {
            return Err(RenderError::Invalid(format!(
                "{} material bindings for {} parts",
                materials.len(),
                scene.mesh.part_names.len()
            )));
        }
        let lights = AreaLights::new(&scene.lights);
        let n_tris = scene.mesh.triangles.len() as u64;
        let geometry = progress::stage(progress, "building BVH", None, &format!("({n_tris} triangles)"), || {
            SceneGeometry::new(scene, &lights)
        });
        let mut slot_names = lights.names.clone();
        if scene.environment.is_some() {
            slot_names.push("environment".into());
        }
        let mut renderer = Renderer {
            geometry,
            lights,
            env: scene.environment.clone(),
            materials,
            part_names: scene.mesh.part_names.clone(),
            radiances: LightRadiances::unit(scene),
            slot_radiance: Vec::new(),
            slot_names,
            select_power: Distribution1D::new(&[]),
            select_unit: Distribution1D::new(&[]),
        };
        renderer.set_radiances(radiances)?;
        Ok(renderer)
    }

    /// Re-target the renderer to other light radiances (one per light, same order as the
    /// scene's, and the environment scale), rebuilding the light selection that depends on
    /// them. Refused (and nothing changes) when the count differs or a value is negative or
    /// not finite.
    pub fn set_radiances(&mut self, radiances: &LightRadiances) -> Result<(), RenderError> {
        radiances.validate(&self.lights.names)?;
        let mut slot_radiance: Vec<Vec3> = radiances.lights.iter().map(|&r| Vec3::from(r)).collect();
        if self.env.is_some() {
            slot_radiance.push(Vec3::from(radiances.environment));
        }
        let has_env = self.env.is_some();
        let lights = &self.lights;
        let mk = |unit: bool| {
            let mut w: Vec<f32> = (0..lights.len())
                .map(|k| lights.areas[k] * if unit { 1.0 } else { luminance(slot_radiance[k]).max(0.0) })
                .collect();
            if has_env {
                let s: f32 = w.iter().sum();
                let env_on = unit || luminance(slot_radiance[lights.len()]) > 0.0;
                w.push(if !env_on {
                    0.0
                } else if s > 0.0 {
                    s
                } else {
                    1.0
                });
            }
            Distribution1D::new(&w)
        };
        let (select_power, select_unit) = (mk(false), mk(true));
        self.select_power = select_power;
        self.select_unit = select_unit;
        self.slot_radiance = slot_radiance;
        self.radiances = radiances.clone();
        Ok(())
    }

    /// The radiances the renderer renders with.
    pub fn radiances(&self) -> &LightRadiances {
        &self.radiances
    }

    /// Radiance per light slot: the lights, then the environment scale if the scene has one.
    pub fn slot_radiance(&self) -> &[Vec3] {
        &self.slot_radiance
    }

    /// Names of the light slots: the lights, then "environment" if the scene has one.
    pub fn slot_names(&self) -> &[String] {
        &self.slot_names
    }

    pub fn n_slots(&self) -> usize {
        self.slot_radiance.len()
    }

    /// The traced geometry (model and emitters in one BVH).
    pub fn geometry(&self) -> &SceneGeometry {
        &self.geometry
    }

    /// The area lights (names, triangles, areas).
    pub fn lights(&self) -> &AreaLights {
        &self.lights
    }

    /// The environment map, if the scene has one.
    pub fn environment(&self) -> Option<&EnvMap> {
        self.env.as_ref()
    }

    /// One binding per model part, in the order of [`Renderer::part_names`].
    pub fn materials(&self) -> &[MaterialBinding] {
        &self.materials
    }

    /// Replace the material bindings (one per part, as in [`Renderer::new`]).
    pub fn set_materials(&mut self, materials: Vec<MaterialBinding>) -> Result<(), RenderError> {
        if materials.len() != self.part_names.len() {
            return Err(RenderError::Invalid(format!(
                "{} material bindings for {} parts",
                materials.len(),
                self.part_names.len()
            )));
        }
        self.materials = materials;
        Ok(())
    }

    pub fn part_names(&self) -> &[String] {
        &self.part_names
    }

    /// The G-buffer of `camera` at its resolution, with the materials' normal maps.
    pub fn gbuffer(&self, camera: &Camera) -> Result<crate::GBuffer, RenderError> {
        crate::gbuffer::render_gbuffer(
            &self.geometry,
            camera,
            &self.part_names,
            &self.lights.names,
            Some(&self.materials),
        )
    }

    fn selection(&self, per_light: bool) -> &Distribution1D {
        if per_light {
            &self.select_unit
        } else {
            &self.select_power
        }
    }

    /// Radiance arriving at `o` from direction `-d` (d unit, leaving `o`), accumulated per slot
    /// into `st.out` at unit emission. `prev_pdf` is the solid-angle pdf with which `d` was
    /// sampled (0 = not sampled by a BRDF: camera rays, light-grid rays; no MIS on emitter hits).
    pub fn li(&self, o: Vec3, d: Vec3, cfg: &PathConfig, st: &mut PathState) {
        self.li_inline(o, d, cfg, st)
    }

    /// [`Renderer::li`], inlined into the render loop (so that it is compiled for the CPU
    /// features the loop is compiled for).
    #[inline(always)]
    fn li_inline(&self, mut o: Vec3, mut d: Vec3, cfg: &PathConfig, st: &mut PathState) {
        let sel = self.selection(cfg.per_light);
        let n_lights = self.lights.len();
        let mut beta = Vec3::ONE;
        let mut prev_pdf = 0.0f32;
        let mut depth = 0u32;
        loop {
            st.rays += 1;
            let hit = match self.geometry.trace(o, d, f32::INFINITY) {
                Traced::Miss => {
                    if let Some(env) = &self.env {
                        let w = if prev_pdf > 0.0 {
                            power_heuristic(prev_pdf, sel.pmf(n_lights) * env.pdf(d))
                        } else {
                            1.0
                        };
                        st.out[n_lights] += beta * env.eval(d) * w;
                    }
                    return;
                }
                Traced::Emitter { light, n, t } => {
                    let cos_l = -n.dot(d);
                    if cos_l > 0.0 && !(cfg.skip_direct_emitters && depth == 0) {
                        let k = light as usize;
                        let w = if prev_pdf > 0.0 {
                            let pdf_l = sel.pmf(k) / self.lights.areas[k] * t * t / cos_l;
                            power_heuristic(prev_pdf, pdf_l)
                        } else {
                            1.0
                        };
                        st.out[k] += beta * w;
                    }
                    return; // emitters do not reflect
                }
                Traced::Surface(h) => h,
            };
            if depth + 1 >= cfg.max_depth {
                return;
            }
            let wo = -d;
            let binding = &self.materials[hit.part as usize];
            // The material's texels load while the shadow ray is traced: NEE is sampled and its
            // visibility tested before shading, with only the geometric tests; the shading-frame
            // test and the contribution wait for the BRDF (same random numbers, same estimate).
            binding.prefetch(hit.uv);
            let ng = if hit.ng.dot(wo) >= 0.0 { hit.ng } else { -hit.ng };
            let origin = self.geometry.offset(hit.p, ng);

            // Next-event estimation: (slot, wi, radiance, light pdf) of an unoccluded sample.
            let mut nee: Option<(usize, Vec3, Vec3, f32)> = None;
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

            let s = binding.eval(hit.uv);
            let sf = self.geometry.shading_frame(&hit, wo, s.normal);
            let mut brdf = Karis::new(Vec3::from(s.albedo), s.roughness);
            if cfg.diffuse_only {
                brdf = brdf.diffuse_only();
            }
            let wo_l = sf.frame.to_local(wo);
            if wo_l.z <= 0.0 {
                return;
            }
            let brdf = brdf.at(wo_l);
            if let Some((slot, wi, le, pdf_l)) = nee {
                let wi_l = sf.frame.to_local(wi);
                if wi_l.z > 0.0 {
                    let (f, pdf_b) = brdf.eval_pdf(wi_l);
                    let w = power_heuristic(pdf_l, pdf_b);
                    st.out[slot] += beta * f * le * (wi_l.z * w / pdf_l);
                }
            }

            // Continue the path.
            let u_lobe = st.rng.next_f32();
            let u = st.rng.next_2d();
            let Some(bs) = brdf.sample(u_lobe, u) else { return };
            let wi = sf.frame.to_world(bs.wi);
            if wi.dot(ng) <= 0.0 {
                return;
            }
            beta *= bs.weight;
            prev_pdf = bs.pdf;
            o = origin;
            d = wi;
            depth += 1;
            if depth >= cfg.rr_depth {
                let q = beta.max_element().min(0.95);
                let u = st.rng.next_f32();
                if u.is_nan() || u >= q {
                    return;
                }
                beta /= q;
            }
        }
    }

    /// Path-trace an image from `camera` (its resolution is overridden by the options' size).
    pub fn render(&self, camera: &Camera, opts: &RenderOptions) -> Result<RenderOutput, RenderError> {
        self.render_with_progress(camera, opts, &NoProgress)
    }

    /// [`Renderer::render`], reporting the stage "render" in samples to `progress`: per row and
    /// sample pass, with enough passes (at least 256 updates, at most one pass a sample) that a
    /// small image with many samples still moves. Passes add each pixel's samples in the same
    /// order as one pass would, so the image does not depend on them.
    pub fn render_with_progress(
        &self,
        camera: &Camera,
        opts: &RenderOptions,
        progress: &dyn Progress,
    ) -> Result<RenderOutput, RenderError> {
        let (w, h, ns) = (opts.width, opts.height, self.n_slots());
        opts.check(ns)?;
        let mut cam = camera.clone();
        if (cam.width, cam.height) != (opts.width, opts.height) {
            cam = rescale(camera, opts.width, opts.height)?;
        }
        let start = Instant::now();
        let rays = AtomicU64::new(0);
        let mut slots = vec![Vec3::ZERO; w * h * ns];
        let cfg = opts.path_config();
        let spp = opts.spp as usize;
        let passes = 256usize.div_ceil(h).clamp(1, spp);
        let body = |slots: &mut Vec<Vec3>| {
            if ns == 0 {
                return; // no lights and no environment: a black image
            }
            for p in 0..passes {
                let samples = (spp * p / passes) as u32..(spp * (p + 1) / passes) as u32;
                let last = p + 1 == passes;
                slots.par_chunks_mut(w * ns).enumerate().for_each(|(y, row)| {
                    let r = self.render_row(&cam, opts, &cfg, y, row, samples.clone(), last);
                    rays.fetch_add(r, Ordering::Relaxed);
                    progress.advance((w * samples.len()) as u64);
                });
            }
        };
        progress::stage(progress, "render", Some((w * h * spp) as u64), "samples", || {
            run_in_pool(opts.threads, || body(&mut slots))
        })?;
        let image: Vec<[f32; 3]> = slots
            .chunks_exact(ns.max(1))
            .map(|px| px.iter().zip(&self.slot_radiance).fold(Vec3::ZERO, |a, (v, r)| a + *v * *r).to_array())
            .collect();
        let image = if ns == 0 { vec![[0.0; 3]; w * h] } else { image };
        let per_light = if opts.per_light {
            (0..ns)
                .map(|k| (self.slot_names[k].clone(), (0..w * h).map(|i| slots[i * ns + k].to_array()).collect()))
                .collect()
        } else {
            Vec::new()
        };
        Ok(RenderOutput {
            width: w,
            height: h,
            image,
            per_light,
            rays: rays.into_inner(),
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// Adds samples `samples` of every pixel of row `y` to `row` (width × slots, zero before
    /// the first pass) and, on the `last` pass, divides by the sample count; returns the rays
    /// cast. Dispatches to a copy compiled for AVX2 where the CPU has it (VEX encoding, SSE4.1
    /// rounding and blends; no FMA contraction, so the results are bit-identical to the baseline
    /// copy).
    #[allow(clippy::too_many_arguments)]
    fn render_row(
        &self,
        cam: &Camera,
        opts: &RenderOptions,
        cfg: &PathConfig,
        y: usize,
        row: &mut [Vec3],
        samples: Range<u32>,
        last: bool,
    ) -> u64 {
        #[cfg(target_arch = "x86_64")]
        if std::arch::is_x86_feature_detected!("avx2") {
            // SAFETY: the CPU supports the features the function is compiled for.
            return unsafe { self.render_row_avx2(cam, opts, cfg, y, row, samples, last) };
        }
        self.render_row_impl(cam, opts, cfg, y, row, samples, last)
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx2")]
    #[allow(clippy::too_many_arguments)]
    fn render_row_avx2(
        &self,
        cam: &Camera,
        opts: &RenderOptions,
        cfg: &PathConfig,
        y: usize,
        row: &mut [Vec3],
        samples: Range<u32>,
        last: bool,
    ) -> u64 {
        self.render_row_impl(cam, opts, cfg, y, row, samples, last)
    }

    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn render_row_impl(
        &self,
        cam: &Camera,
        opts: &RenderOptions,
        cfg: &PathConfig,
        y: usize,
        row: &mut [Vec3],
        samples: Range<u32>,
        last: bool,
    ) -> u64 {
        let (w, ns) = (opts.width, self.n_slots());
        let mut row_rays = 0u64;
        for x in 0..w {
            let pixel = (y * w + x) as u64;
            let acc = &mut row[x * ns..(x + 1) * ns];
            for s in samples.clone() {
                let mut st = PathState { rng: Rng::new(opts.seed, pixel, s as u64), rays: 0, out: acc };
                let j = st.rng.next_2d();
                let d = cam.direction(x as f32 + j[0], y as f32 + j[1]);
                self.li_inline(cam.position, d, cfg, &mut st);
                row_rays += st.rays;
            }
            if last {
                let inv = 1.0 / opts.spp as f32;
                acc.iter_mut().for_each(|a| *a *= inv);
            }
        }
        row_rays
    }

    /// Cast `passes` jittered camera rays per pixel (closest hit only); returns (rays, seconds).
    pub fn primary_ray_benchmark(
        &self,
        camera: &Camera,
        passes: u32,
        threads: Option<usize>,
    ) -> Result<(u64, f64), RenderError> {
        let (w, h) = (camera.width, camera.height);
        let start = Instant::now();
        let hits = run_in_pool(threads, || {
            (0..h)
                .into_par_iter()
                .map(|y| {
                    let mut n = 0u64;
                    for x in 0..w {
                        for s in 0..passes {
                            let mut rng = Rng::new(7, (y * w + x) as u64, s as u64);
                            let j = rng.next_2d();
                            let d = camera.direction(x as f32 + j[0], y as f32 + j[1]);
                            if !matches!(self.geometry.trace(camera.position, d, f32::INFINITY), Traced::Miss) {
                                n += 1;
                            }
                        }
                    }
                    n
                })
                .sum::<u64>()
        })?;
        std::hint::black_box(hits);
        Ok(((w * h) as u64 * passes as u64, start.elapsed().as_secs_f64()))
    }
}

/// The same camera at another resolution (same vertical field of view); fails only for a size
/// that is zero or over the pixel limit.
pub fn rescale(camera: &Camera, width: usize, height: usize) -> Result<Camera, RenderError> {
    let fov = 2.0 * camera_tan_half_y(camera).atan().to_degrees();
    let spec = crate::camera::CameraSpec {
        position: camera.position.to_array(),
        look_at: (camera.position + camera.forward).to_array(),
        up: camera.up.to_array(),
        fov_y_deg: fov,
    };
    Camera::new(&spec, width, height, "camera")
}

fn camera_tan_half_y(c: &Camera) -> f32 {
    // direction through the top-centre raster point has slope tan(fov/2) along `up`.
    let d = c.direction(c.width as f32 * 0.5, 0.0);
    d.dot(c.up) / d.dot(c.forward)
}

pub(crate) fn run_in_pool<T: Send>(threads: Option<usize>, f: impl FnOnce() -> T + Send) -> Result<T, RenderError> {
    match threads {
        None => Ok(f()),
        Some(n) => {
            psc_base::limits::check_threads(n as u64)?;
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(n.max(1))
                .build()
                .map_err(|e| RenderError::Invalid(format!("cannot start {n} threads: {e}")))?;
            Ok(pool.install(f))
        }
    }
}
