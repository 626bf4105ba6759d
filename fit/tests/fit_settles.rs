//! The fit settles: with its learning rate falling over the run, a part's loss ends near the
//! minimum instead of oscillating around it at a fixed rate's step size.
//!
//! The photo is a library graph at its default parameters through a known UV transform; the
//! fit starts from perturbed parameters, UV and colour, without a global search (the local
//! searches still run). Each case is fitted twice, with the learning rate falling (the
//! default) and held fixed, so the baseline is computed in the same test.
//!
//! `cargo test --release -p psc-fit --test fit_settles -- --nocapture` prints the histories'
//! figures.

mod flat_view;

use flat_view::photo_of;
use psc_fit::features::{FeatureConfig, Scratch};
use psc_fit::layer::MaterialState;
use psc_fit::loss::{LossWeights, PartLoss};
use psc_fit::optim::Free;
use psc_fit::part_fit::{fit_part, FitSettings, PartFit, Problem};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library, Material};

/// The photo's state moved off: every continuous parameter a fifth of its range towards the
/// far end, the UV rotated, scaled and shifted, the colour scaled unevenly.
fn perturbed(material: &Material, uv: UvTransform) -> MaterialState {
    let info = &material.graph.info;
    let mut params = info.default_params();
    for p in info.params.iter().filter(|p| p.is_continuous()) {
        let (lo, hi) = p.bounds();
        for x in &mut params[p.slot..p.slot + p.width()] {
            *x = if *x - lo < hi - *x { *x + 0.2 * (hi - lo) } else { *x - 0.2 * (hi - lo) };
        }
    }
    MaterialState {
        params,
        uv: UvTransform { rotation: uv.rotation + 0.12, log_scale: uv.log_scale + 0.3, offset: [0.45, 0.1] },
        albedo_scale: [0.8, 1.1, 0.9],
        roughness: 0.5,
    }
}

struct Figures {
    best: f32,
    /// The median loss of the last 100 iterations: where the fit is, rather than the lowest
    /// point it passed.
    tail_median: f32,
}

fn figures(fit: &PartFit) -> Figures {
    let h = &fit.history;
    let mut tail = h[h.len().saturating_sub(100)..].to_vec();
    tail.sort_by(f32::total_cmp);
    Figures { best: fit.loss.total, tail_median: tail[tail.len() / 2] }
}

#[test]
fn the_fit_settles_near_its_minimum() {
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    for (name, uv) in [
        ("oak_planks", UvTransform { rotation: 0.4, log_scale: 0.8, offset: [0.31, 0.57] }),
        ("linen", UvTransform { rotation: 1.1, log_scale: -0.5, offset: [0.12, 0.66] }),
    ] {
        let material = &library.materials[library.index_of(name).unwrap()];
        let view = photo_of(material, uv, 64);
        let mut scratch = Scratch::default();
        let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
        let problem = Problem::on_one_view(material, &view, &loss);
        let start = perturbed(material, uv);
        let settled = FitSettings {
            starts: 1,
            max_iterations: 400,
            stall_window: 0,
            global_uv_search: false,
            ..FitSettings::default()
        };
        let fixed = FitSettings { final_learning_rate: 1.0, ..settled };
        let a = figures(&fit_part(&problem, std::slice::from_ref(&start), &settled, Free::ALL).unwrap());
        let b = figures(&fit_part(&problem, &[start], &fixed, Free::ALL).unwrap());
        println!(
            "{name}: best {:.5} (fixed rate {:.5}), median of the last 100 iterations {:.5} ({:.5})",
            a.best, b.best, a.tail_median, b.tail_median
        );
        assert!(a.tail_median < 0.5 * b.tail_median, "{name}: the falling rate did not settle the fit");
        assert!(a.best <= b.best, "{name}: settling lost the minimum the fixed rate found");
    }
}
