//! What a fit decided, as plain data: per part its status, graph, fitted state, chosen view,
//! pixel counts, losses and timings; for the scene the light radiances, the solve rounds and
//! the per-view exposures; and [`PreviousFit`], what `--resume` and `--refit-only` read back
//! from `result.json`, checked against the scene and library it is applied to. Nothing here
//! fits or renders.

use psc_render::material::MaterialBinding;
use psc_render::scene::{LightRadiances, Scene};
use psc_runtime::library::Library;
use psc_runtime::material::ProceduralMaterial;
use psc_runtime::params::ParamSpace;
use serde::{Deserialize, Serialize};

use crate::align::{Dropped, Warp};
use crate::error::FitError;
use crate::layer::MaterialState;
use crate::light_solve::LightSolve;
use crate::loss::LossValue;
use crate::select::Ranked;
use crate::uvmap::LOG_SCALE_RANGE;
use crate::views::ViewScore;
use crate::working::WorkingRaster;

/// How a part got its material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PartStatus {
    /// Selected and fitted.
    Fitted,
    /// The graph was given with `--graph`.
    Forced,
    /// Too few usable pixels: a homogeneous material at the shading-normalised median colour.
    Homogeneous,
    /// No view shows it: the documented default (homogeneous mid grey, roughness 0.5).
    Unobserved,
}

/// Pixel counts of a part in its chosen view.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PixelCounts {
    /// Labelled in the photo (M_photo).
    pub photo: usize,
    /// Seen on the coarse model (M_geo).
    pub model: usize,
    pub usable: usize,
    pub fitted: usize,
    pub dropped: Dropped,
}

/// Seconds spent per stage for one part.
#[derive(Clone, Debug, Default, Serialize, Deserialize)]
pub struct PartTimings {
    pub targets: f64,
    pub selection: f64,
    pub fit: f64,
}

/// The check after a selected part's contest: a flat colour fitted to the same pixels against
/// the contest's winner, by their final losses; the lower one is the part's material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FlatCheck {
    pub contest_winner: String,
    pub contest_loss: f32,
    pub flat_loss: f32,
}

impl FlatCheck {
    /// Whether the flat colour replaced the contest's winner.
    pub fn flat_kept(&self) -> bool {
        self.flat_loss < self.contest_loss
    }
}

/// The fit of one part (saved whole in `result.json`, so `--refit-only` can start from it).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PartResult {
    pub name: String,
    pub status: PartStatus,
    pub graph: String,
    pub state: MaterialState,
    /// Scale of the graph's roughness map in the output, so that its mean over the part is the
    /// fitted roughness.
    pub roughness_scale: f32,
    /// The selection's best graphs with their votes (empty when not selected).
    pub top: Vec<Ranked>,
    /// The flat-colour check after the selection's contest (none when not selected; absent
    /// from the `result.json` of fits made before it was recorded).
    #[serde(default)]
    pub flat_check: Option<FlatCheck>,
    pub view: Option<String>,
    /// Index of the chosen view in the scene's views.
    pub view_index: Option<usize>,
    pub view_scores: Vec<ViewScore>,
    pub warp: Option<Warp>,
    pub iou: Option<(f32, f32)>,
    pub pixels: PixelCounts,
    pub loss: LossValue,
    pub history: Vec<f32>,
    pub iterations: u32,
    pub uv_candidates: usize,
    pub timings: PartTimings,
}

/// Everything a fit decided.
#[derive(Clone, Debug)]
pub struct FitResult {
    pub parts: Vec<PartResult>,
    /// Light slot names (scene lights, then "environment") and their fitted RGB radiance.
    pub slot_names: Vec<String>,
    pub radiance: Vec<[f32; 3]>,
    /// How the radiances were obtained.
    pub light_source: String,
    /// The global light solves of the re-fit rounds, in order (none with `--lights`).
    pub light_rounds: Vec<LightRound>,
    /// Per view (scene order), its RGB exposure: the factor between a render of the fitted
    /// scene and that view's photo. The last light solve's (1 for a single view, and until the
    /// first solve); with `--lights`, the previous fit's or 1.
    pub exposure: Vec<[f32; 3]>,
    /// Per view (scene order), the raster it was fitted at (see [`crate::working`]); the
    /// re-renders are made at it.
    pub rasters: Vec<WorkingRaster>,
    /// (stage, seconds) in order.
    pub timings: Vec<(String, f64)>,
}

impl FitResult {
    /// The fitted materials as renderer bindings, one per model part.
    pub fn bindings(&self, library: &Library) -> Result<Vec<MaterialBinding>, FitError> {
        self.parts.iter().map(|p| binding(library, &p.graph, &p.state, p.roughness_scale)).collect()
    }

    /// The radiances in the renderer's form.
    pub fn light_radiances(&self, scene: &Scene) -> LightRadiances {
        let n = scene.lights.len();
        LightRadiances {
            lights: self.radiance[..n].to_vec(),
            environment: self.radiance.get(n).copied().unwrap_or([1.0; 3]),
            source: self.light_source.clone(),
        }
    }
}

/// A renderer binding for a graph at a fitted state.
pub fn binding(
    library: &Library,
    graph: &str,
    state: &MaterialState,
    roughness_scale: f32,
) -> Result<MaterialBinding, FitError> {
    let material = library.get(graph).ok_or_else(|| FitError::Input(format!("no graph `{graph}` in the library")))?;
    let procedural = ProceduralMaterial::new(material.clone(), state.params.clone()).map_err(FitError::Input)?;
    Ok(MaterialBinding {
        material: std::sync::Arc::new(procedural),
        uv_transform: state.uv.matrix(),
        albedo_scale: state.albedo_scale,
        roughness_scale,
    })
}

/// One round's light solve and how much it moved the radiances.
#[derive(Clone, Debug, Serialize)]
pub struct LightRound {
    pub solve: LightSolve,
    /// Largest relative change of a slot's radiance or a view's exposure (luminance) against the
    /// previous round.
    pub change: f32,
}

/// What `--resume` and `--refit-only` start from: a previous fit's parts, radiances and
/// per-view exposures (its `result.json`).
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct PreviousFit {
    pub parts: Vec<PartResult>,
    pub radiance: Vec<[f32; 3]>,
    /// One per view in scene order; empty (every view at 1) in fits made before exposures.
    #[serde(default)]
    pub exposure: Vec<[f32; 3]>,
}

impl PreviousFit {
    /// The exposure of every view of a scene with `n_views` views (1 where none was saved).
    pub(crate) fn exposures(&self, n_views: usize) -> Vec<[f32; 3]> {
        (0..n_views).map(|v| self.exposure.get(v).copied().unwrap_or([1.0; 3])).collect()
    }

    /// Checks that the previous fit belongs to `scene` and `library`.
    pub(crate) fn check(&self, scene: &Scene, library: &Library, n_slots: usize) -> Result<(), FitError> {
        let names: Vec<&String> = self.parts.iter().map(|p| &p.name).collect();
        if names.len() != scene.mesh.part_names.len() || names.iter().zip(&scene.mesh.part_names).any(|(a, b)| *a != b)
        {
            return Err(FitError::Input(format!(
                "the previous fit is of other parts ({}) than the scene's ({})",
                names.iter().map(|n| n.as_str()).collect::<Vec<_>>().join(", "),
                scene.mesh.part_names.join(", ")
            )));
        }
        if self.radiance.len() != n_slots || self.radiance.iter().flatten().any(|c| !c.is_finite() || *c < 0.0) {
            return Err(FitError::Input(format!(
                "the previous fit has {} light radiances for the scene's {n_slots} (or a bad value)",
                self.radiance.len()
            )));
        }
        let n_views = scene.views.len();
        let bad_exposure = self.exposure.iter().flatten().any(|e| !e.is_finite() || *e <= 0.0);
        if (!self.exposure.is_empty() && self.exposure.len() != n_views) || bad_exposure {
            return Err(FitError::Input(format!(
                "the previous fit has {} view exposures for the scene's {n_views} views (or one not finite and positive)",
                self.exposure.len()
            )));
        }
        for p in &self.parts {
            let material = library
                .get(&p.graph)
                .ok_or_else(|| FitError::Input(format!("part `{}`: no graph `{}` in the library", p.name, p.graph)))?;
            if material.graph.info.default_params().len() != p.state.params.len() {
                return Err(FitError::Input(format!(
                    "part `{}`: the previous fit has {} parameter values for graph `{}`, which has {}",
                    p.name,
                    p.state.params.len(),
                    p.graph,
                    material.graph.info.default_params().len()
                )));
            }
            check_state(&p.name, &ParamSpace::new(&material.graph.info), &p.state, p.roughness_scale)?;
        }
        Ok(())
    }
}

/// A previous fit's state of one part is one the fit could have reached: parameters in their
/// declared ranges, a finite UV transform within the search's scales, positive albedo scales and
/// a roughness in (0, 1]. Anything else would be carried into outputs no reader accepts.
fn check_state(part: &str, space: &ParamSpace, state: &MaterialState, roughness_scale: f32) -> Result<(), FitError> {
    let bad = |what: String| Err(FitError::Input(format!("part `{part}`: the previous fit's {what}")));
    if let Err(e) = space.check(&state.params) {
        return bad(format!("parameters: {e}"));
    }
    let uv = &state.uv;
    let (lo, hi) = LOG_SCALE_RANGE;
    if !(uv.rotation.is_finite() && uv.offset.iter().all(|o| o.is_finite()) && (lo..=hi).contains(&uv.log_scale)) {
        return bad(format!(
            "UV transform (rotation {}, log-scale {} of [{lo}, {hi}], offset {:?}) is not one the fit makes",
            uv.rotation, uv.log_scale, uv.offset
        ));
    }
    if !state.albedo_scale.iter().all(|a| a.is_finite() && *a > 0.0) {
        return bad(format!("albedo scale {:?} is not finite and positive", state.albedo_scale));
    }
    if !(state.roughness > 0.0 && state.roughness <= 1.0) {
        return bad(format!("roughness {} is not in (0, 1]", state.roughness));
    }
    if !(roughness_scale.is_finite() && roughness_scale >= 0.0) {
        return bad(format!("roughness scale {roughness_scale} is not finite and non-negative"));
    }
    Ok(())
}
