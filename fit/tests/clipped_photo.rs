//! A photo whose brighter pixels are clipped: the fit must compare it with a render clipped the
//! same way, not leave the clipped pixels out. The photo is a textured library graph rendered
//! through the layer at an exposure that clips about 40% of its pixels; the candidate is the
//! same graph at another uv offset (a fitted texture never matches the photo's phase) and a
//! wrong albedo scale. The albedo scale whose render matches the photo's mean (what the fit's
//! last step sets) and the statistics loss must both find the true scale; with the clipped
//! pixels left out, as the fit did before, only the photo's darker pixels remain against the
//! candidate's whole range, and both come out too dark.
//!
//! `cargo test --release -p psc-fit --test clipped_photo -- --nocapture` prints the scales.

mod flat_view;

use flat_view::flat_view;
use psc_fit::features::{FeatureConfig, Scratch};
use psc_fit::layer::{MaterialState, PartView, Sampling, Workspace};
use psc_fit::loss::{LossWeights, PartLoss};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library, Material};

fn state(material: &Material, offset: [f32; 2], scale: f32) -> MaterialState {
    MaterialState {
        params: material.graph.info.default_params(),
        uv: UvTransform { rotation: 0.4, log_scale: 0.0, offset },
        albedo_scale: [scale; 3],
        roughness: 0.6,
    }
}

/// The mean-matching albedo scale (mean of the three channels) of the candidate at `offset`.
fn mean_matched(view: &PartView, material: &Material, offset: [f32; 2]) -> f32 {
    let start = state(material, offset, 0.5);
    let mut ws = Workspace::default();
    view.render(material, &start, Sampling::default(), &mut ws).unwrap();
    view.mean_matching_albedo_scale(&start, &ws).iter().sum::<f32>() / 3.0
}

/// The albedo scale, on a grid from 0.6 to 1.4, whose render has the lowest statistics loss.
fn statistics_best(view: &PartView, material: &Material, offset: [f32; 2]) -> f32 {
    let weights = LossWeights { statistics: 1.0, features: 0.0, contrast: 0.0 };
    let mut scratch = Scratch::default();
    let loss = PartLoss::new(view, weights, &FeatureConfig::default(), &mut scratch).unwrap();
    let mut ws = Workspace::default();
    let scales = (0..=40).map(|k| 0.6 + 0.02 * k as f32);
    let mut value = |s: f32, ws: &mut Workspace| {
        view.render(material, &state(material, offset, s), Sampling::default(), ws).unwrap();
        loss.value(&ws.image, &mut scratch).statistics
    };
    scales.map(|s| (value(s, &mut ws), s)).min_by(|a, b| a.0.total_cmp(&b.0)).unwrap().1
}

#[test]
fn clipped_photo_pixels_are_compared_with_a_render_clipped_the_same_way() {
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    for name in ["granite", "terrazzo", "oak_planks"] {
        let material = library.get(name).unwrap_or_else(|| panic!("{name} is in the library"));
        let mut view = flat_view(96, 1.0 / 48.0);
        let truth = state(material, [0.11, 0.23], 1.0);
        let mut ws = Workspace::default();
        view.render(material, &truth, Sampling::default(), &mut ws).unwrap();
        // The exposure that puts the 60th percentile of the brightest channel at full scale.
        let mut brightest: Vec<f32> = ws.linear.iter().map(|l| l[0].max(l[1]).max(l[2])).collect();
        brightest.sort_by(f32::total_cmp);
        view.exposure = [1.0 / brightest[brightest.len() * 6 / 10]; 3];
        view.render(material, &truth, Sampling::default(), &mut ws).unwrap();
        view.target = ws.image.clone();
        view.target_linear = ws.linear.iter().map(|l| [0, 1, 2].map(|c| (view.exposure[c] * l[c]).min(1.0))).collect();
        let clipped: Vec<bool> = view.target.iter().map(|p| p.iter().any(|&v| v >= 0.99)).collect();
        let share = clipped.iter().filter(|&&c| c).count() as f32 / clipped.len() as f32;
        assert!((0.3..0.6).contains(&share), "{name}: {share} of the photo clipped");

        let elsewhere = [0.62, 0.41];
        let (mean_counted, stats_counted) =
            (mean_matched(&view, material, elsewhere), statistics_best(&view, material, elsewhere));
        let mut left_out = view;
        for (w, &c) in left_out.weight.iter_mut().zip(&clipped) {
            if c {
                *w = 0.0;
            }
        }
        let (mean_left_out, stats_left_out) =
            (mean_matched(&left_out, material, elsewhere), statistics_best(&left_out, material, elsewhere));
        println!(
            "{name}: {:.0}% clipped; albedo scale by the mean {mean_counted:.3} counted, {mean_left_out:.3} left out; \
             by the statistics loss {stats_counted:.2} and {stats_left_out:.2}",
            100.0 * share
        );
        assert!((mean_counted - 1.0).abs() < 0.05, "{name}: the mean match gives {mean_counted}");
        assert!((stats_counted - 1.0).abs() < 0.07, "{name}: the statistics loss is lowest at {stats_counted}");
        assert!(mean_left_out < 0.92, "{name}: left out, the clipped pixels should darken the match: {mean_left_out}");
    }
}
