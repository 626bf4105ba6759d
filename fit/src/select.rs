//! Graph selection by k-nearest neighbours, as PhotoScene: for each part, N random exemplars of
//! every library graph are rendered through the part's own shading setup (its pixels, uv
//! footprints and lighting), colour-matched to the photo by their medians and scored by the
//! loss (see below); the k best exemplars vote for their graphs with weight 1/loss.
//!
//! A random exemplar at a random UV scale rarely shows its graph at the photo's scale, which
//! would make the vote about scale rather than pattern; each exemplar is therefore scored at a
//! few log-scales spread over the search range (its best counts), with a random rotation and
//! offset. The feature term is taken at the exemplar's best orientation (a cyclic shift of the
//! descriptor's orientation bands, no extra render): the random rotation would otherwise favour
//! isotropic graphs, which match at any turn, over oriented ones (planks, stripes), which the
//! fit's UV search would turn into place. k scales with the library: 21 for PhotoScene's 71
//! graphs.
//!
//! The score is the whole loss: the statistics (per-channel mean and spread after the median
//! match) beside the pattern. Scoring by the feature term alone, as PhotoScene scores by its
//! VGG loss, was tried: on the dev scenes it matched the truth's family on more judged parts
//! (5 and 4 of 6 over two seeds, against 3 and 2), but it chose graphs whose contrast the fit
//! could not bring down to the photo's (dev_1's walls a knit, its floor a textured plastic),
//! and the texture-contrast distance to the truth doubled on dev_1 (0.25 → 0.50 of the pixel
//! median's, input views) and grew on dev_2 (novel 0.34 → 0.50); on clean renders of
//! library graphs (`tests/selection.rs`) it also ranked planks below smooth leather once in
//! six, where the whole loss ranks every target first.

use psc_base::{mix64, SplitMix64};
use psc_runtime::library::{Library, Material};
use rayon::prelude::*;
use serde::Serialize;

use crate::error::FitError;
use crate::features::Scratch;
use crate::layer::{MaterialState, PartView, Sampling, Workspace};
use crate::loss::PartLoss;
use crate::uvmap::{UvTransform, LOG_SCALE_RANGE};

#[derive(Clone, Copy, Debug, PartialEq, Serialize, serde::Deserialize)]
pub struct SelectSettings {
    /// Random exemplars per graph (PhotoScene: 10).
    pub exemplars: usize,
    /// Log-scales each exemplar is scored at.
    pub scales: usize,
    /// Voters; None scales PhotoScene's 21 of 71 with the library's size.
    pub k: Option<usize>,
}

impl Default for SelectSettings {
    fn default() -> Self {
        SelectSettings { exemplars: 10, scales: 4, k: None }
    }
}

/// The roughness exemplars are rendered with.
const EXEMPLAR_ROUGHNESS: f32 = 0.5;

/// One scored exemplar.
#[derive(Clone, Debug)]
pub struct Exemplar {
    /// Index into the library's materials.
    pub graph: usize,
    pub state: MaterialState,
    pub loss: f32,
}

/// A graph's standing in the vote.
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
pub struct Ranked {
    pub graph: String,
    pub votes: f64,
    /// Its best exemplar's loss.
    pub best_loss: f32,
}

pub struct Selection {
    /// Every graph that received a vote, best first, then the others by best loss.
    pub ranking: Vec<Ranked>,
    /// Every exemplar, best first.
    pub exemplars: Vec<Exemplar>,
    pub k: usize,
}

impl Selection {
    /// The best exemplars of graph `graph` (library index), best first.
    pub fn exemplars_of(&self, graph: usize) -> impl Iterator<Item = &Exemplar> {
        self.exemplars.iter().filter(move |e| e.graph == graph)
    }
}

/// Random parameters and UV for exemplar `e` of graph `g` (deterministic in the seed).
fn exemplar_state(material: &Material, seed: u64) -> (MaterialState, f32) {
    let mut rng = psc_base::SplitMix64::new(seed);
    let params = psc_runtime::params::ParamSpace::new(&material.graph.info).random(&mut rng);
    let mut r = SplitMix64::new(mix64(seed ^ 0xa11ce));
    let uv = UvTransform {
        rotation: r.next_f32() * std::f32::consts::TAU,
        log_scale: 0.0,
        offset: [r.next_f32(), r.next_f32()],
    };
    (MaterialState { params, uv, albedo_scale: [1.0; 3], roughness: EXEMPLAR_ROUGHNESS }, r.next_f32())
}

/// Ranks the graphs of `library` (or only those listed in `only`) for `view`.
pub fn select(
    library: &Library,
    view: &PartView,
    loss: &PartLoss,
    settings: SelectSettings,
    sampling: Sampling,
    seed: u64,
    only: Option<&[usize]>,
) -> Result<Selection, FitError> {
    let graphs: Vec<usize> = match only {
        Some(list) => list.to_vec(),
        None => (0..library.materials.len()).collect(),
    };
    let jobs: Vec<(usize, usize)> =
        graphs.iter().flat_map(|&g| (0..settings.exemplars.max(1)).map(move |e| (g, e))).collect();
    let scales = settings.scales.max(1);
    let (lo, hi) = LOG_SCALE_RANGE;
    let mut exemplars: Vec<Exemplar> = jobs
        .par_iter()
        .map_init(
            || (Workspace::default(), Scratch::default()),
            |(ws, scratch), &(g, e)| -> Result<Exemplar, FitError> {
                let material = &library.materials[g];
                let (mut state, jitter) = exemplar_state(material, mix64(seed ^ ((g as u64) << 24) ^ e as u64));
                let mut best: Option<(f32, MaterialState)> = None;
                for s in 0..scales {
                    state.uv.log_scale = lo + (hi - lo) * (s as f32 + jitter) / scales as f32;
                    view.render(material, &state, sampling, ws)?;
                    let albedo_scale = view.matched_albedo_scale(&state, ws);
                    view.rescale(&state, albedo_scale, ws);
                    let value = loss.selection_score(&ws.image, scratch);
                    let value = if value.is_finite() { value } else { f32::INFINITY };
                    if best.as_ref().is_none_or(|b| value < b.0) {
                        best = Some((value, MaterialState { albedo_scale, ..state.clone() }));
                    }
                }
                let (loss, state) = best.expect("at least one scale");
                Ok(Exemplar { graph: g, state, loss })
            },
        )
        .collect::<Result<_, _>>()?;
    exemplars.sort_by(|a, b| a.loss.total_cmp(&b.loss).then(a.graph.cmp(&b.graph)));
    let n_graphs = graphs.len();
    let k =
        settings.k.unwrap_or_else(|| ((21.0 * n_graphs as f64 / 71.0).round() as usize).max(3)).min(exemplars.len());
    let mut votes = vec![0.0f64; library.materials.len()];
    for e in exemplars.iter().take(k) {
        votes[e.graph] += 1.0 / f64::from(e.loss.max(1e-6));
    }
    let mut ranking: Vec<Ranked> = graphs
        .iter()
        .map(|&g| Ranked {
            graph: library.materials[g].name().to_string(),
            votes: votes[g],
            best_loss: exemplars.iter().find(|e| e.graph == g).map_or(f32::INFINITY, |e| e.loss),
        })
        .collect();
    if std::env::var_os("PSC_FIT_DEBUG").is_some() {
        let mut seen = std::collections::BTreeSet::new();
        for e in &exemplars {
            if seen.insert(e.graph) {
                eprintln!("  {:<24} best exemplar loss {:.4}", library.materials[e.graph].name(), e.loss);
            }
        }
    }
    ranking.sort_by(|a, b| {
        b.votes.total_cmp(&a.votes).then(a.best_loss.total_cmp(&b.best_loss)).then(a.graph.cmp(&b.graph))
    });
    Ok(Selection { ranking, exemplars, k })
}
