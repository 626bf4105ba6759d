//! The loop after the per-part fit (PhotoScene Sec. 3.4): with every part's graph, parameters
//! and UV transform frozen, solve the lights (and each view's exposure) globally under the
//! fitted materials, re-render the light grids, and re-fit each part's albedo scale and
//! roughness against its view's photo at that view's exposure; then match each part's mean
//! colour over all its usable pixels.
//!
//! The whole-part mean match exists because the appearance fit sees a window of at most
//! `fit_pixels` pixels: on a large wall the window's light is not the part's light, and a scale
//! fitted there is biased on the rest of the part. The match is exact in the statistic the
//! photo shows (the mean sRGB value of the part), and cheap: one render of the part. It is
//! made in the shading layer, so the pipeline ends on a light solve applied without a re-fit,
//! to leave the parts' colours as the path tracer sees them.

use crate::render_noise::RenderNoise;
use psc_render::Renderer;
use psc_runtime::library::{Library, Material};

use crate::align::AlignedPart;
use crate::error::FitError;
use crate::features::Scratch;
use crate::layer::{MaterialState, Sampling, Workspace};
use crate::light_solve::{self, LightSolve};
use crate::lighting::{self, ShadingGrid};
use crate::loss::PartLoss;
use crate::observe::ViewObservation;
use crate::optim::Free;
use crate::part::{flat_colour, flat_state};
use crate::part_fit::{fit_part, FitSettings, Problem};
use crate::pipeline::FitOptions;
use crate::result::{PartResult, PartStatus};
use crate::targets::{part_view, Window};

/// Solves every emitter's radiance jointly with a factor on every part's albedo and an exposure
/// per view, under the renderer's current materials (see
/// [`light_solve::solve_with_part_scales`]), from two independent estimates of the unit renders
/// so that their Monte Carlo noise does not bias the radiances.
pub fn solve_lights(
    renderer: &Renderer,
    views: &[ViewObservation],
    aligned: &[Vec<AlignedPart>],
    seed: u64,
) -> Result<LightSolve, FitError> {
    let renders = lighting::unit_renders(renderer, views, seed)?;
    let independent = lighting::unit_renders(renderer, views, psc_base::mix64(seed ^ 0x1d_e9e4_de47))?;
    light_solve::solve_with_part_scales(views, aligned, &renders, &independent)
}

/// What a part's re-fit reads that stays the same through every round.
pub struct RoundInputs<'a> {
    pub library: &'a Library,
    pub homogeneous: &'a Material,
    pub views: &'a [ViewObservation],
    pub aligned: &'a [Vec<AlignedPart>],
    /// Per view, the render-noise check of its crops' noise estimates.
    pub render_noise: &'a [RenderNoise],
    pub options: &'a FitOptions,
}

/// What changes from round to round: the renderer's materials, the lighting and the views'
/// exposures.
pub struct RoundLighting<'a> {
    pub renderer: &'a Renderer,
    pub shading: &'a [ShadingGrid],
    /// Per view, the RGB exposure its photo is compared at (the last light solve's).
    pub exposure: &'a [[f32; 3]],
}

impl RoundLighting<'_> {
    fn exposure(&self, view: usize) -> [f32; 3] {
        self.exposure.get(view).copied().unwrap_or([1.0; 3])
    }
}

impl RoundInputs<'_> {
    fn aligned_part(&self, renderer: &Renderer, part: &PartResult) -> Option<(usize, &AlignedPart)> {
        let v = part.view_index?;
        let index = renderer.part_names().iter().position(|p| p == &part.name)?;
        self.aligned[v].iter().find(|a| a.part as usize == index).map(|a| (v, a))
    }
}

/// Re-fits a part's albedo scale and roughness under new lighting (graph, parameters and UV
/// transform frozen), as PhotoScene's re-fit; homogeneous parts get their colour anew.
pub fn refit_appearance(inputs: &RoundInputs, light: &RoundLighting, part: &mut PartResult) -> Result<(), FitError> {
    let Some((v, a)) = inputs.aligned_part(light.renderer, part) else { return Ok(()) };
    let (obs, options) = (&inputs.views[v], inputs.options);
    let geometry = light.renderer.geometry();
    let mut ws = Workspace::default();
    if part.status == PartStatus::Homogeneous {
        let exposure = light.exposure(v);
        if let Some(view) = part_view(
            obs,
            a,
            geometry,
            &obs.camera,
            &light.shading[v],
            options.search_window(),
            exposure,
            inputs.render_noise.get(v),
        ) {
            let colour = flat_colour(inputs.homogeneous, &view, &mut ws)?;
            part.state = flat_state(inputs.homogeneous, colour, part.state.roughness);
        }
        return Ok(());
    }
    let Some(fit_view) = part_view(
        obs,
        a,
        geometry,
        &obs.camera,
        &light.shading[v],
        options.fit_window(),
        light.exposure(v),
        inputs.render_noise.get(v),
    ) else {
        return Ok(());
    };
    let material = inputs.library.get(&part.graph).expect("fitted graphs come from the library");
    let mut scratch = Scratch::default();
    let fit_loss = PartLoss::new(&fit_view, options.loss, &options.features, &mut scratch)?;
    let problem =
        Problem { material, fit_view: &fit_view, fit_loss: &fit_loss, search_view: &fit_view, search_loss: &fit_loss };
    let settings =
        FitSettings { max_iterations: options.refit_iterations, starts: 1, start_iterations: 0, ..options.fit };
    let fit = fit_part(&problem, std::slice::from_ref(&part.state), &settings, Free::APPEARANCE)?;
    part.state = fit.state;
    part.loss = fit.loss;
    part.history.extend(fit.history);
    part.iterations += fit.iterations;
    Ok(())
}

/// Samples per axis when the whole part is rendered for its mean: the mean needs no detail.
const MEAN_SAMPLING: Sampling = Sampling { density: 160.0, max_per_axis: 2 };

/// Sets the part's albedo scale so that its render matches the photo's mean sRGB colour over
/// every usable pixel of its chosen view, and its roughness scale so that the output's
/// roughness map has the fitted mean. Returns the relative change of the scale (max channel).
pub fn match_whole_part(inputs: &RoundInputs, light: &RoundLighting, part: &mut PartResult) -> Result<f32, FitError> {
    let Some((v, a)) = inputs.aligned_part(light.renderer, part) else { return Ok(0.0) };
    if part.status == PartStatus::Unobserved {
        return Ok(0.0);
    }
    let obs = &inputs.views[v];
    let exposure = light.exposure(v);
    let Some(view) = part_view(
        obs,
        a,
        light.renderer.geometry(),
        &obs.camera,
        &light.shading[v],
        Window::WHOLE,
        exposure,
        inputs.render_noise.get(v),
    ) else {
        return Ok(0.0);
    };
    let material = inputs.library.get(&part.graph).expect("fitted graphs come from the library");
    let mut ws = Workspace::default();
    view.render(material, &part.state, MEAN_SAMPLING, &mut ws)?;
    let scale = view.mean_matching_albedo_scale(&part.state, &ws);
    let change = (0..3).map(|c| (scale[c] / part.state.albedo_scale[c].max(1e-6) - 1.0).abs()).fold(0.0f32, f32::max);
    part.state.albedo_scale = scale;
    part.roughness_scale = roughness_scale(&part.state, &ws);
    Ok(change)
}

/// The factor on the graph's roughness map whose mean over the last render in `ws` is the
/// part-wide fitted roughness.
pub fn roughness_scale(state: &MaterialState, ws: &Workspace) -> f32 {
    let map_mean = ws.channel_mean(psc_compiler::Channel::Roughness);
    if map_mean > 1e-4 {
        (state.roughness / map_mean).clamp(0.0, 50.0)
    } else {
        1.0
    }
}
