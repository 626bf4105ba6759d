//! The path tracer: unidirectional paths with next-event estimation on area lights and the
//! environment, multiple importance sampling (power heuristic), Russian roulette, Mitsuba 3's
//! depth convention (`max_depth` 1 = directly visible emitters only, 2 = direct light, ...).
//!
//! Radiance is accumulated per *light slot* (one per area light, then one for the environment)
//! at unit emission; an image is the slot images weighted by the light radiances, which gives
//! per-light renders for free and keeps them consistent with the combined one.
//!
//! The render loop traces the paths of neighbouring pixels in lockstep (a path is cut at the
//! material lookup, `path.rs`), so that the hits of a packet on one part are shaded in one batch
//! through the material's SIMD kernel rather than one lane at a time.
//!
//! Determinism: sample s of pixel i draws from `Rng::new(seed, i, s)` and pixels are reduced in a
//! fixed order, so the result does not depend on the thread count or scheduling.

use std::ops::Range;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;
use psc_base::progress::{self, NoProgress, Progress};
use rayon::prelude::*;

use crate::camera::Camera;
use crate::emitters::{AreaLights, Distribution1D, EnvMap};
use crate::geometry::{SceneGeometry, Traced};
use crate::material::{MaterialBinding, SurfaceSample};
use crate::rng::Rng;
use crate::scene::{LightRadiances, Scene};
use crate::RenderError;

mod options;
mod path;

pub use options::{slot_file_names, PathConfig, RenderOptions, RenderOutput};
use path::{PathVertex, SurfaceStop};

/// Paths traced together by the render loop: neighbouring pixels of a row at one sample
/// index. Past the first bounce paths scatter over the parts, so a packet must be several SIMD
/// widths wide for its hits on one part to fill a kernel's 4 lanes; 16 is also the most points
/// the JIT's stack-only entry takes at once.
const PACKET: usize = 16;

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

    /// [`Renderer::li`], inlined where it is called (so that it is compiled for the CPU
    /// features of its caller).
    #[inline(always)]
    fn li_inline(&self, o: Vec3, d: Vec3, cfg: &PathConfig, st: &mut PathState) {
        let sel = self.selection(cfg.per_light);
        let mut v = PathVertex::start(o, d);
        while let Some(stop) = self.advance_to_surface(&v, sel, cfg, st) {
            let s = self.materials[stop.hit.part as usize].eval(stop.hit.uv);
            if !self.shade_and_continue(&mut v, &stop, s, cfg, st) {
                return;
            }
        }
    }

    /// Traces the paths of a packet in lockstep, a segment at a time, so that the hits that
    /// land on the same part are shaded in one batch (one SIMD lane each in a compiled graph's
    /// kernel). `paths[k]` is `None` past the packet's end. Each path draws its own random
    /// numbers and adds to its own pixel, so a path's result is the one it has alone.
    #[inline(always)]
    fn trace_packet(&self, paths: &mut [Option<(PathVertex, PathState)>; PACKET], cfg: &PathConfig) {
        let sel = self.selection(cfg.per_light);
        let mut stops: [Option<SurfaceStop>; PACKET] = [None; PACKET];
        let mut alive: [bool; PACKET] = std::array::from_fn(|k| paths[k].is_some());
        loop {
            // A stop is `Some` exactly for the paths still alive on a surface.
            for ((path, stop), alive) in paths.iter_mut().zip(&mut stops).zip(&mut alive) {
                *stop = match (path, *alive) {
                    (Some((v, st)), true) => self.advance_to_surface(v, sel, cfg, st),
                    _ => None,
                };
                *alive = stop.is_some();
            }
            if !alive.contains(&true) {
                return;
            }
            let samples = self.shade_stops(&stops);
            for (((path, stop), alive), s) in paths.iter_mut().zip(&stops).zip(&mut alive).zip(samples) {
                if let (Some((v, st)), Some(stop)) = (path, stop) {
                    *alive = self.shade_and_continue(v, stop, s, cfg, st);
                }
            }
        }
    }

    /// The material's sample at every stop of a packet, the stops on one part evaluated
    /// together.
    #[inline(always)]
    fn shade_stops(&self, stops: &[Option<SurfaceStop>; PACKET]) -> [SurfaceSample; PACKET] {
        let mut samples = [SurfaceSample::default(); PACKET];
        let mut done = [false; PACKET];
        for k in 0..PACKET {
            let part = match &stops[k] {
                Some(stop) if !done[k] => stop.hit.part,
                _ => continue,
            };
            let (mut members, mut uvs, mut n) = ([0usize; PACKET], [[0.0f32; 2]; PACKET], 0);
            for j in k..PACKET {
                match &stops[j] {
                    Some(stop) if !done[j] && stop.hit.part == part => {
                        (members[n], uvs[n]) = (j, stop.hit.uv);
                        done[j] = true;
                        n += 1;
                    }
                    _ => {}
                }
            }
            let mut out = [SurfaceSample::default(); PACKET];
            self.materials[part as usize].eval_batch(&uvs[..n], &mut out[..n]);
            for (&j, s) in members[..n].iter().zip(out) {
                samples[j] = s;
            }
        }
        samples
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
        // A packet is PACKET neighbouring pixels at the same sample index: their camera rays
        // mostly hit the same part, and each pixel's samples still add up in sample order.
        for x0 in (0..w).step_by(PACKET) {
            let pixels = &mut row[x0 * ns..(x0 + PACKET).min(w) * ns];
            for s in samples.clone() {
                let mut accs = pixels.chunks_mut(ns);
                let mut paths: [Option<(PathVertex, PathState)>; PACKET] = std::array::from_fn(|k| {
                    let out = accs.next()?;
                    let (x, pixel) = (x0 + k, (y * w + x0 + k) as u64);
                    let mut rng = Rng::new(opts.seed, pixel, s as u64);
                    let j = rng.next_2d();
                    let d = cam.direction(x as f32 + j[0], y as f32 + j[1]);
                    Some((PathVertex::start(cam.position, d), PathState { rng, rays: 0, out }))
                });
                self.trace_packet(&mut paths, cfg);
                row_rays += paths.iter().flatten().map(|(_, st)| st.rays).sum::<u64>();
            }
            if last {
                let inv = 1.0 / opts.spp as f32;
                pixels.iter_mut().for_each(|a| *a *= inv);
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
