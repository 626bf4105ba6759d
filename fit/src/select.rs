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
//! Two votes are taken over the same exemplars: one by the pattern alone (the feature term; the
//! statistics only where the region is too thin for the descriptor), as PhotoScene scores by
//! its VGG loss, and one by the whole loss (the statistics, per-channel mean and spread after
//! the median match, beside the pattern). Neither decides: the pattern vote's top
//! [`SelectSettings::contenders`] and the whole-loss vote's winner each run a start of the fit
//! (global UV search and a short run, `part_fit::fit_contest`), and the graph whose start
//! reaches the lowest loss is fitted. An exemplar judges a graph at random parameters and a
//! coarse scale; a start judges it at its searched UV and fitted parameters, colour and
//! contrast.
//!
//! Measured on the dev scenes, seed 0 (the truth's family on the six judged parts, and the
//! texture-contrast distance to the truth on the true geometry, fitted / pixel median, input
//! views of dev_1 / dev_2 / dev_3 / dev_4, `psc eval --spp 128`):
//!
//! | vote | then | family | contrast |
//! | --- | --- | --- | --- |
//! | whole loss | its winner (before) | 3 of 6 | 0.27 / 0.56 / 0.56 / 0.41 |
//! | whole loss | contest of its top three | 2 of 6 | — |
//! | pattern | its winner | 5 of 6 | dev_1 0.50 (measured a stop earlier) |
//! | pattern | contest of its top three | 5 of 6 | 0.33 / 0.59 / 0.59 / 0.47 |
//! | both | contest: pattern's top three + whole loss's winner | 5 of 6 | 0.32 / 0.61 / 0.46 / 0.47 |
//! | **both** | **the same, the loss with its contrast term and noise model** | **5 of 6** | **0.21 / 0.38 / 0.38 / 0.31** |
//!
//! The pattern vote alone chose graphs whose contrast the fit could not bring down to the
//! photo's (dev_1's walls a knit, its floor a textured plastic); the contest replaces them (an
//! oak grain and a brushed metal, whose starts reach half the loss). A contest among the
//! whole-loss vote's own top three only confirms what that loss likes (smooth leather for
//! dev_2's planks, a marble for dev_4's plaster). The whole-loss winner's place in the contest
//! gives plain parts their plain graphs back (dev_1's floor homogeneous, dev_3's walls a
//! painted wall). Adding the homogeneous material as a contender of its own was tried: it won
//! dev_1's gravel walls after 30 steps, where a flat colour loses the texture.
//!
//! Away from the rooms (`cargo bench -p psc-fit --bench selection_families`: every generated
//! texture of the dev scenes on a flat, evenly lit 96×96 crop at 160 and 64 pixels per tile,
//! with the photos' noise), the family matches the kind's on 13 of 20 crops: planks 6 of 8,
//! plaster 4 of 8 (the others to a marble or a metal), stripes 3 of 4. Before `printed_stripes`
//! and `limewash` (and with the seeding by library place), 9 of 20: planks 5, plaster 4, stripes
//! 0, for no graph had flat bands of several colours.
//!
//! Each exemplar's draw is seeded by its graph's name ([`psc_base::mix_name`]), not its place
//! in the library: seeded by place, two graphs inserted into the library reshuffled the draws
//! of every later graph and changed the graph of 27 parts on the dev scenes, 22 of them parts
//! neither new graph won. Seeded by name, the same two graphs (`printed_stripes`, `limewash`)
//! changed only the three parts that `limewash` won (two on dev_3, dev_4's bookcase trim), and
//! no graph on dev_1 or dev_2.
//!
//! Tried and not landed: one brightness change shared by all of an exemplar's colours (here
//! each colour takes its own, `ParamSpace::random`), so that a graph of several colours keeps
//! the contrast its author gave them. With a change per colour, dev_1's stripe rug ranks
//! `printed_stripes` seventh in its pattern vote (best exemplar 0.155 against a terracotta
//! tile's 0.022) and gets a damask or a terracotta tile at seeds 0 and 1 (final loss 0.061,
//! 0.055); with one change `printed_stripes` tops the vote (0.023) and wins the rug at both
//! seeds (0.0098, 0.0099). But the bench fell from 13 to 10 of 20 (planks 5, plaster 2: faint
//! plaster went to marble, metal or canvas; independent brightnesses also draw exemplars of
//! lower contrast, which a faint photo needs), and on the dev scenes at seed 0 dev_2's lights
//! went from 0.1% to 18.8% off the truth's ratio. A draw that keeps the palette's structure
//! (one brightness change, the colours' spread around their mean scaled by one factor in
//! 0.25–1.25, every other parameter drawn as here) was measured next: dev_1's rug got
//! `printed_stripes` at seeds 0 and 1, and the bench 15 of 20 (planks 7, plaster 5, stripes 3),
//! but the rest did not move beyond what a change of seed does. Texture contrast over the pixel
//! median's on the true geometry, dev_1 and dev_2, input / novel / relit, seeds 0 and 1: the
//! sum of the 12 cells 5.90 against 5.80 here (dev_2's relit views 0.97 and 0.94 against 0.73
//! and 0.85); the family of dev_2's three judged parts 4 of 6 against 5 of 6; dev_1's lights 35%
//! and 49% off against 13% and 38% (they follow the graph its gravel walls get: with a
//! polished concrete 13% and 18%, with a canvas 22%, with a cut pile, a speckled vinyl or a
//! perforated metal 35–49%), dev_2's 7.3% and 3.3% against 0.1% and 5.9%. On four rooms made
//! by a first draft of `tools/holdout_room.py` (seed 0) it went the same way: contrast summed
//! over their 12 cells 4.69 against 4.33, family 4 of 7 against 3, and the lights of the room
//! with dev_1's one view and three lights 32.4% off against 6.6%.
//!
//! Twenty exemplars per graph instead of PhotoScene's ten (selection is 3–4 s of a part's
//! 20–70 s), measured alone at seeds 0–2 against ten (sums over the true-geometry cells,
//! fitted / pixel median, input / novel / relit views):
//!
//! | rooms, seeds 0–2 | family | contrast, summed | RMSE, summed | cells over 0.5 | lights, worst room |
//! | --- | --- | --- | --- | --- | --- |
//! | hold-out g1–g4, ten | 9 of 21 | 12.59 | 18.55 | 5 | g1: 9.8 / 14.0 / 99.8% |
//! | hold-out g1–g4, twenty | 10 of 21 | 12.27 | 18.09 | 5 | g1: 10.3 / 13.8 / 13.9% |
//! | dev scenes, ten | 10 of 18 | 18.65 | 17.62 | 19 | dev_1: 13.1 / 37.6 / 38.5% |
//! | dev scenes, twenty | 11 of 18 | 19.17 | 17.95 | 19 | dev_1: 14.2 / 14.8 / 25.5% |
//!
//! More draws find graphs that fit the input views closer, not ones that hold elsewhere: on
//! dev_3 at seed 1 most parts' final losses fell (its floor 0.0167 to 0.0034, its stool 0.17 to
//! 0.033) while its marble cabinet got a subway tile and its bookcase trim and stool a brass,
//! and the contrast of its novel views went from 0.74 to 1.05 of the pixel median's; at seed 0
//! its bookcase lost an oak veneer (0.0036) to a plaster (0.033). The vote keeps its k voters
//! (PhotoScene's 21 of 71 graphs, not of 710 draws), so twice the draws leave only the luckiest
//! exemplars voting. A k that grows with the draws (doubled at twenty) was tried once, on the
//! hold-out rooms at seed 0: the family 2 of 7 (twenty alone 3, ten 2), contrast summed 4.22
//! against 3.94 and 3.82; not the fix on that evidence. Measured with two starts per contender
//! as well (`part_fit::fit_contest`, seed 0): the family 4 of 7 against 2 on the hold-out rooms,
//! 4 of 6 against 3 on the dev scenes, dev_1's lights 26.4% off. Left at ten.
//!
//! Stratified draws were measured in full fits and left out: each graph's ten exemplars on a
//! Latin hypercube (every parameter's range, each colour's brightness and shifts, the rotation
//! and the scales' jitter cut into ten strata, one exemplar in each), so that whether a graph
//! has an exemplar near the photo depends less on where ten independent draws fall. At seed 1
//! on the four dev scenes and the four hold-out rooms, against the independent draws (the
//! head's fits at that seed): the family 7 of 13 against 9 (dev_2's plaster rug a marble,
//! dev_4's plaster walls a brushed metal, g4's plaster walls a quartz surface; dev_1's stripe rug
//! a printed stripes, won), true-geometry texture contrast over the pixel median's summed over
//! each set's 12 cells 5.51 against 5.06 (dev_3's novel views 0.81 against 0.64) and 4.36
//! against 4.43, RMSE within 0.05 in every cell; the lights between two lights dev_1 40.1% off
//! (12.4%; walls a canvas), dev_2 4.1% (8.7%), g2 7.9% (2.4%), g1, g4 and dev_4 within a point.
//! dev_1 at seed 2: 74.2% off (15.2%; its walls a bouclé). The crop test of
//! `fit/tests/selection.rs` failed with them: oak planks at their defaults lost their contest
//! to subway tiles at seed 1 (0.0204 against 0.0187 after the start). Even coverage of the
//! parameters moved the choices as a change of seed does and did not steady them. Of the 13
//! misses among 20 judged parts' fits tabulated across seeds, 8 never had the expected family
//! among the contenders (faint parts, whose pattern vote near-flat graphs such as the textured
//! plastic lead) and 5 had it and lost the contest on their start.
//!
//! The pattern term with the exemplar's contrast left free (every descriptor energy of the
//! exemplar times the factor that minimises the feature loss, found by golden section at each
//! orientation shift), so that the vote judges the pattern's shape across scales and orientations
//! and not its amplitude, was measured on the bench and left out: 10 of 20 crops against 13 in
//! the same session. Plaster fell from 4 of 8 to 1: a faint plaster's energies, scaled up, match
//! a hexagon tile's, a glass mosaic's or a terrazzo's, and the contest then gave two marbles and
//! a frosted glass. Planks stayed at 6 of 8 (a dev_1 crop lost to a linoleum, a dev_3 crop won
//! back) and stripes at 3 of 4. A faint texture's amplitude is part of what tells its family.
//!
//! A contest that counts start losses within 10% of the best as ties, broken by the pattern vote's
//! order, changed no crop of the bench (13 of 20, the same winners). Recomputed from the contest
//! losses the stored dev and hold-out fits record (seeds 0 and 1), it would change 19 parts:
//! dev_2's plaster walls from a brushed metal to a stucco, dev_3's plank barrel at seed 1 from a
//! concrete to a smooth leather, and 17 parts of no judged kind. The battery of full fits
//! (true-geometry contrast cells, fitted over pixel median, summed per scene; against the fits of
//! this rule's absence, which are deterministic and were re-run for dev_2 and g1 to the digit): at
//! seed 0 the dev scenes 5.40 against 5.33 (the family 4 of 6 against 3: dev_2's walls a stucco),
//! at seed 1 5.27 against 5.49 (dev_1 0.69 / 0.77, dev_2 1.57 / 1.45, dev_3 1.46 / 1.72, dev_4
//! unchanged; the family 4 of 6 both), the four hold-out rooms at seed 0 3.81 against 3.80 (g1's
//! choices unchanged, g4's plank floor a flat colour where it had a concrete: a textured plastic
//! within 10% won the contest and lost to the flat check; the family 2 of 7 both); four cells above
//! half the baseline at either seed, either way. Every light ratio that moved moved away from the
//! truth: dev_2 4.6% off against 2.0% (seed 0) and 9.1% against 8.6% (seed 1), dev_4 0.9% against
//! 0.3%, dev_1 13.9% against 12.0%, g2 2.2% against 2.1%. What it changes is which of two
//! near-equal graphs a small or half-seen part gets (a crate's marble, a barrel's leather, a back
//! wall's cut pile); a gain of one family on one seed and 0.14 of contrast over 36 cells, within
//! what a seed moves, for lights that all got worse: left out.
//!
//! Contenders diverse by category (the pattern vote's top graph, then the best-voted graph of
//! each other category in the order of their graphs' summed votes, so that nineteen wood graphs
//! splitting a vote among themselves still send one) were measured in full fits at seed 0 and
//! left out. True-geometry contrast over the pixel median's, input / novel / relit, against the
//! landed rule: dev_2 0.46 / 0.29 / 0.62 (0.49 / 0.38 / 0.69), dev_3 0.46 / 0.76 / 0.51
//! (0.46 / 0.61 / 0.51), g1 0.23 / 0.25 / 0.24 (0.24 / 0.24 / 0.25), g2 0.23 / 0.20 / 0.29
//! (0.24 / 0.22 / 0.32); the four summed 4.54 against 4.65. The family moved on one part each
//! way (dev_2's plaster walls a plaster instead of a brushed metal; its plank floor a linoleum
//! instead of an oak veneer: with the oak grain standing for the wood category, the oak veneer,
//! whose start had won at 0.0098, no longer entered, and the linoleum's 0.0123 beat the oak
//! grain's 0.0159). dev_2's lights went from 2.0% to 10.6% off (past the 10% target), and dev_3's
//! novel views lost 0.16 to the categories that entered: its stool a stitched leather instead
//! of a flat colour, its cabinet trim a plaster instead of a frosted glass, each winning its
//! contest and further from the truth in the novel views (0.0059 against 0.0032, 0.0063 against
//! 0.0008); g2's lights moved from 2.1% to 1.5%, g1's not at all. The hold-out rooms' plank floors,
//! which the rule was for, stayed off wood: g1's wood entrant was a beadboard (start 0.0158
//! against the plaster's 0.0121), g2's floor went from a linoleum to a marble. The other four
//! rooms were not run.
//!
//! Those plank floors, probed one part at a time at seed 0 (the other parts forced to their fitted
//! graphs; the fit's loss before the light rounds): forced to a wide plank graph
//! (`--graph floor=wide_planks`), g1's floor reaches 0.0038 against the chosen plaster's 0.0090
//! and g4's 0.0071 against the chosen concrete's 0.0172; g2's 0.0100 against its linoleum's
//! 0.0062. But with more entrants the contest goes further from wood, not to it: sixteen
//! (`--contenders 16`) give g1's floor a linoleum (0.0022), and every one of the 94 graphs
//! running a start gives g4's a printed stripes (0.0046, its start 0.0124 the lowest), where the
//! wide planks' start ranks 83rd (0.0262; the oak planks 39th, the laminate 50th). The vote
//! does keep the planks out (on g1 the best of their ten exemplars scores 0.0073 on the pattern
//! term, 19th of the 94, where the plaster's scores 0.0010: a faint plank floor at a grazing
//! angle is, to the descriptor, mostly its noise, and a random draw of a plank graph's many
//! parameters rarely comes out faint; a default-parameter exemplar per graph left that ranking
//! as it was), but letting them in would not choose them: the loss itself fits a faint mottle or
//! a band pattern as closely as faint seams, or closer. The lead this leaves is in the loss (a
//! pattern term that tells a seam's long straight edges, broken at the board ends, from bands
//! and mottles), not in the vote or the contest.
//!
//! Selection and the UV search render each candidate on a window of at most `--search-pixels`
//! (1024) photo pixels with at most `--search-samples` (2) samples per pixel axis. On g1's plank
//! floor (a thin 81×24 window at a grazing angle) that aliases the oak grain into noise: the
//! oak planks' best exemplar ranks 81st of 92, though forced onto the floor they reach a total
//! loss of 0.0031 against the chosen plaster's 0.0112. With both raised (4096 pixels, 4 samples)
//! a wood graph (a beadboard) wins g1's floor; either alone does not (4096 pixels: a marble;
//! 4 samples: a plaster, the beadboard a contender). Measured in full fits at seed 0, true-geometry
//! texture contrast over the pixel median's, input / novel / relit, 1024 and 2 (the defaults)
//! against 4096 and 4:
//!
//! | room | defaults | 4096 pixels, 4 samples |
//! | --- | --- | --- |
//! | g1 | 0.24 / 0.23 / 0.24 | 0.29 / 0.34 / 0.29 |
//! | g2 | 0.26 / 0.22 / 0.31 | 0.23 / 0.21 / 0.26 |
//! | g3 | 0.29 / 0.34 / 0.40 | 0.37 / 0.41 / 0.56 |
//! | g4 | 0.50 / 0.50 / 0.49 | 0.32 / 0.48 / 0.34 |
//! | dev_1 | 0.26 / 0.32 / 0.29 | 0.28 / 0.40 / 0.25 |
//! | dev_2 | 0.47 / 0.28 / 0.66 | 0.51 / 0.33 / 0.67 |
//! | dev_3 | 0.45 / 0.59 / 0.48 | 0.49 / 0.65 / 0.53 |
//! | dev_4 | 0.25 / 0.76 / 0.22 | 0.19 / 0.74 / 0.24 |
//!
//! The hold-out rooms gained (contrast summed 4.11 against 4.01 but the family 4 of 7 against 2,
//! RMSE summed 5.53 against 6.04); the dev scenes lost (5.28 against 5.03, the family 1 of 6
//! against 3: dev_1's stripe rug a terracotta tile, dev_2's plaster rug and walls a marble, dev_3's
//! plank barrel a perforated metal, dev_4's plaster walls a frosted glass), and the
//! light ratios moved away from the truth (dev_1 107.9% off against 14.7%, dev_2 27.9% against
//! 13.2%, g1 121.7% against 8.0%; dev_1's and g1's on a pair their photos do not determine).
//! The fits took 1.4–2× as long (dev_4 360 s against under 180 s; its selection 210 s of 395 s
//! of part fits). Left at the defaults; the options stay for a user who trades time for a
//! finer look at a far, fine-grained part.

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
    /// Graphs at the top of the pattern vote that each run a start of the fit (global UV
    /// search and a short run), beside the whole-loss vote's winner; the one that reaches the
    /// lowest loss is fitted.
    #[serde(default = "default_contenders")]
    pub contenders: usize,
}

fn default_contenders() -> usize {
    SelectSettings::default().contenders
}

impl Default for SelectSettings {
    fn default() -> Self {
        SelectSettings { exemplars: 10, scales: 4, k: None, contenders: 3 }
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
    /// Its loss after a start of the fit, when it was a contender (see
    /// [`SelectSettings::contenders`]).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub start_loss: Option<f32>,
}

/// One vote: graphs ranked by the exemplars' scores of one kind.
pub struct Vote {
    /// Every graph that received a vote, best first, then the others by best loss.
    pub ranking: Vec<Ranked>,
    /// Every exemplar, best first.
    pub exemplars: Vec<Exemplar>,
}

impl Vote {
    /// The best exemplars of graph `graph` (library index), best first.
    pub fn exemplars_of(&self, graph: usize) -> impl Iterator<Item = &Exemplar> {
        self.exemplars.iter().filter(move |e| e.graph == graph)
    }
}

/// The two votes over the same exemplars: by pattern and by the whole loss.
pub struct Selection {
    pub pattern: Vote,
    pub whole: Vote,
    pub k: usize,
}

impl Selection {
    /// The contenders (library indices, most promising first, each with the vote whose
    /// exemplars start it): the pattern vote's top `n`, then the whole-loss vote's winner if it
    /// is not among them.
    pub fn contenders(&self, library: &Library, n: usize) -> Vec<(usize, &Vote)> {
        let index = |r: &Ranked| library.index_of(&r.graph);
        let mut out: Vec<(usize, &Vote)> =
            self.pattern.ranking.iter().take(n.max(1)).filter_map(index).map(|g| (g, &self.pattern)).collect();
        if let Some(g) = self.whole.ranking.first().and_then(index) {
            if out.iter().all(|(c, _)| *c != g) {
                out.push((g, &self.whole));
            }
        }
        out
    }

    /// The contest's entrants: [`Selection::contenders`] (library indices) and, for each, up to
    /// `starts` start states, its vote's best exemplars.
    pub fn entrants(&self, library: &Library, n: usize, starts: usize) -> (Vec<usize>, Vec<Vec<MaterialState>>) {
        self.contenders(library, n)
            .into_iter()
            .map(|(g, vote)| (g, vote.exemplars_of(g).take(starts).map(|e| e.state.clone()).collect::<Vec<_>>()))
            .unzip()
    }
}

/// Random parameters and UV for one exemplar (deterministic in the seed).
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
    let scored: Vec<(Exemplar, Exemplar)> = jobs
        .par_iter()
        .map_init(
            || (Workspace::default(), Scratch::default()),
            |(ws, scratch), &(g, e)| -> Result<(Exemplar, Exemplar), FitError> {
                let material = &library.materials[g];
                // Seeded by the graph's name, not its place in the library: adding a graph must
                // not redraw every other graph's exemplars.
                let graph_seed = psc_base::mix_name(seed, material.name());
                let (mut state, jitter) = exemplar_state(material, mix64(graph_seed ^ e as u64));
                let mut pattern: Option<Exemplar> = None;
                let mut whole: Option<Exemplar> = None;
                for s in 0..scales {
                    state.uv.log_scale = lo + (hi - lo) * (s as f32 + jitter) / scales as f32;
                    view.render(material, &state, sampling, ws)?;
                    let albedo_scale = view.matched_albedo_scale(&state, ws);
                    view.rescale(&state, albedo_scale, ws);
                    let scores = loss.selection_scores(&ws.image, scratch);
                    for (best, value) in [(&mut pattern, scores.pattern), (&mut whole, scores.whole)] {
                        if best.as_ref().is_none_or(|b| value < b.loss) {
                            let state = MaterialState { albedo_scale, ..state.clone() };
                            *best = Some(Exemplar { graph: g, state, loss: value });
                        }
                    }
                }
                Ok((pattern.expect("at least one scale"), whole.expect("at least one scale")))
            },
        )
        .collect::<Result<_, _>>()?;
    let (pattern, whole): (Vec<Exemplar>, Vec<Exemplar>) = scored.into_iter().unzip();
    let n_graphs = graphs.len();
    let k = settings.k.unwrap_or_else(|| ((21.0 * n_graphs as f64 / 71.0).round() as usize).max(3)).min(jobs.len());
    let pattern = vote(library, &graphs, pattern, k);
    let whole = vote(library, &graphs, whole, k);
    if std::env::var_os("PSC_FIT_DEBUG").is_some() {
        let mut seen = std::collections::BTreeSet::new();
        for e in &pattern.exemplars {
            if seen.insert(e.graph) {
                eprintln!("  {:<24} best exemplar pattern loss {:.4}", library.materials[e.graph].name(), e.loss);
            }
        }
    }
    Ok(Selection { pattern, whole, k })
}

/// The k best of `exemplars` vote for their graphs with weight 1/loss.
fn vote(library: &Library, graphs: &[usize], mut exemplars: Vec<Exemplar>, k: usize) -> Vote {
    exemplars.sort_by(|a, b| a.loss.total_cmp(&b.loss).then(a.graph.cmp(&b.graph)));
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
            start_loss: None,
        })
        .collect();
    ranking.sort_by(|a, b| {
        b.votes.total_cmp(&a.votes).then(a.best_loss.total_cmp(&b.best_loss)).then(a.graph.cmp(&b.graph))
    });
    Vote { ranking, exemplars }
}
