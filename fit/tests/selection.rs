//! Graph selection recovers the graph that made a photo: the target is a library graph at its
//! default parameters and a random UV transform, rendered through an evenly lit crop; the vote
//! ranks a panel of graphs, one per family, that includes it, and must place it among the
//! contenders (the pattern vote's top three and the whole-loss vote's winner); the contest
//! between them (a start of the fit each) must then
//! choose it. The panel holds the graphs that won on plain and faint parts of the dev scenes
//! (smooth leather, textured plastic, quartz, plaster) beside planks, bricks, stripes and tiles.
//!
//! `cargo test --release -p psc-fit --test selection -- --nocapture` prints the votes and the
//! contest.

mod flat_view;

use flat_view::{flat_view, photo_of};
use psc_base::SplitMix64;
use psc_fit::features::{FeatureConfig, Scratch};
use psc_fit::layer::{MaterialState, Sampling, Workspace};
use psc_fit::loss::{LossWeights, PartLoss};
use psc_fit::optim::Free;
use psc_fit::part_fit::{fit_contest, FitSettings, Problem};
use psc_fit::select::{select, SelectSettings};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library};

const PANEL: [&str; 8] = [
    "oak_planks",
    "english_bond",
    "striped_rug",
    "plaster",
    "smooth_leather",
    "textured_plastic",
    "quartz_surface",
    "subway_tiles",
];

#[test]
fn the_vote_proposes_and_the_contest_chooses_the_graph_that_made_the_photo() {
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    let panel: Vec<usize> =
        PANEL.iter().map(|name| library.index_of(name).unwrap_or_else(|| panic!("{name} is in the library"))).collect();
    // PhotoScene's 21 voters of 71 graphs, for a library of 24.
    let settings = SelectSettings { k: Some(7), ..SelectSettings::default() };
    // The contest alone: each contender's first start decides, and the winner stops there.
    let fit =
        FitSettings { starts: 1, max_iterations: FitSettings::default().start_iterations, ..FitSettings::default() };
    let mut wrong = Vec::new();
    for (target_index, &target_graph) in panel.iter().enumerate().take(3) {
        let material = &library.materials[target_graph];
        for seed in [1u64, 2] {
            let mut rng = SplitMix64::new(seed * 7919 + target_index as u64);
            let uv = UvTransform { rotation: rng.next_f32() * 3.0, log_scale: 1.0, offset: [0.31, 0.57] };
            let view = photo_of(material, uv, 96);
            let mut scratch = Scratch::default();
            let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
            let selection = select(&library, &view, &loss, settings, Sampling::default(), seed, Some(&panel)).unwrap();
            let (contenders, starts) = selection.entrants(&library, settings.contenders, fit.starts);
            let problems: Vec<(Problem, Vec<MaterialState>)> = contenders
                .iter()
                .zip(starts)
                .map(|(&g, s)| (Problem::on_one_view(&library.materials[g], &view, &loss), s))
                .collect();
            let contest = fit_contest(&problems, &fit, Free::ALL).unwrap();
            let standings: Vec<String> = contenders
                .iter()
                .zip(&contest.start_losses)
                .map(|(&g, l)| format!("{} (after the start {l:.4})", library.materials[g].name()))
                .collect();
            println!("{} (seed {seed}): {}", material.name(), standings.join(", "));
            if !contenders.contains(&target_graph) {
                wrong.push(format!("{} (seed {seed}): not among the contenders", material.name()));
            } else if contenders[contest.winner] != target_graph {
                wrong.push(format!(
                    "{} (seed {seed}): the contest chose {}",
                    material.name(),
                    library.materials[contenders[contest.winner]].name()
                ));
            }
        }
    }
    assert!(wrong.is_empty(), "selection missed the target's graph: {wrong:?}");
}

/// A crop too thin for any level of the feature descriptor still ranks its candidates, by the
/// statistics, rather than scoring every exemplar 0.
#[test]
fn a_region_too_thin_for_the_features_is_ranked_by_its_statistics() {
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    let mut view = flat_view(3, 1.0 / 96.0);
    view.target = vec![[0.5, 0.4, 0.3]; 9];
    view.target_linear = vec![[0.21, 0.13, 0.07]; 9];
    let mut scratch = Scratch::default();
    let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
    let material = library.get("striped_rug").unwrap();
    let state = MaterialState {
        params: material.graph.info.default_params(),
        uv: UvTransform { rotation: 0.0, log_scale: 0.0, offset: [0.0, 0.0] },
        albedo_scale: [1.0; 3],
        roughness: 0.5,
    };
    let mut ws = Workspace::default();
    view.render(material, &state, Sampling::default(), &mut ws).unwrap();
    let score = loss.selection_scores(&ws.image, &mut scratch).pattern;
    let statistics = loss.value(&ws.image, &mut scratch).statistics;
    assert!(score > 0.0 && score.is_finite(), "score {score}");
    assert_eq!(score, statistics);
}

/// The contenders are the pattern vote's top `n` and, once, the whole-loss vote's winner.
#[test]
fn the_contenders_are_the_pattern_votes_top_and_the_whole_loss_winner() {
    use psc_fit::select::{Ranked, Selection, Vote};
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    let ranked = |names: &[&str]| Vote {
        ranking: names
            .iter()
            .enumerate()
            .map(|(i, n)| Ranked { graph: n.to_string(), votes: 10.0 - i as f64, best_loss: 0.1, start_loss: None })
            .collect(),
        exemplars: Vec::new(),
    };
    let index = |name: &str| library.index_of(name).unwrap();
    let pattern = ["oak_planks", "english_bond", "striped_rug", "plaster"];
    let selection = Selection { pattern: ranked(&pattern), whole: ranked(&["plaster", "oak_planks"]), k: 3 };
    let got: Vec<usize> = selection.contenders(&library, 3).iter().map(|&(g, _)| g).collect();
    let want: Vec<usize> = ["oak_planks", "english_bond", "striped_rug", "plaster"].map(index).to_vec();
    assert_eq!(got, want, "the whole-loss winner joins after the pattern vote's top three");
    let selection = Selection { pattern: ranked(&pattern), whole: ranked(&["english_bond", "plaster"]), k: 3 };
    let got: Vec<usize> = selection.contenders(&library, 3).iter().map(|&(g, _)| g).collect();
    assert_eq!(got, ["oak_planks", "english_bond", "striped_rug"].map(index).to_vec(), "no contender twice");
    let got: Vec<usize> = selection.contenders(&library, 1).iter().map(|&(g, _)| g).collect();
    assert_eq!(got, ["oak_planks", "english_bond"].map(index).to_vec(), "one from each vote");
}

/// A graph's exemplars are drawn from a seed made of its name, not of its place in the library:
/// a graph added in front of it (here: the library without its first graphs, and with them)
/// leaves its exemplars, and so its votes, as they were.
#[test]
fn a_graphs_exemplars_do_not_move_when_graphs_are_added_before_it() {
    let full = Library::load(&default_library_root()).expect("the graph library compiles");
    let fewer = Library {
        materials: full.materials[5..].to_vec(),
        front_end_time: full.front_end_time,
        jit_time: full.jit_time,
    };
    let index_in = |library: &Library| library.index_of("oak_planks").unwrap();
    let view = photo_of(full.get("plaster").unwrap(), UvTransform::default(), 48);
    let mut scratch = Scratch::default();
    let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
    let settings = SelectSettings { exemplars: 3, scales: 2, ..SelectSettings::default() };
    let exemplars = |library: &Library| {
        let g = index_in(library);
        let selection = select(library, &view, &loss, settings, Sampling::default(), 11, Some(&[g])).unwrap();
        selection.pattern.exemplars_of(g).map(|e| (e.state.params.clone(), e.state.uv, e.loss)).collect::<Vec<_>>()
    };
    assert_ne!(index_in(&full), index_in(&fewer));
    assert_eq!(exemplars(&full), exemplars(&fewer));
}
