//! Supersampling within each pixel's uv footprint keeps a material's statistics stable when the
//! fit zooms it in and out: a fine pattern seen through coarse pixels averages out as it does
//! in a photo, instead of aliasing to full contrast.
//!
//! For several graphs and log-scales, the rendered image's standard deviation is compared with
//! a reference that takes 12×12 samples per pixel (a box filter, as the dev photos' renderer
//! uses), once with the layer's adaptive sampling and once with one sample per pixel.
//! `cargo test --release -p psc-fit --test supersampling -- --nocapture` prints the table.

mod flat_view;

use flat_view::flat_view;
use psc_fit::layer::{MaterialState, PartView, Sampling, Workspace};
use psc_fit::loss::Moments;
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library, Material};

fn std_at(view: &PartView, material: &Material, log_scale: f32, sampling: Sampling) -> f32 {
    let state = MaterialState {
        params: material.graph.info.default_params(),
        uv: UvTransform { rotation: 0.3, log_scale, offset: [0.0, 0.0] },
        albedo_scale: [1.0; 3],
        roughness: 0.5,
    };
    let mut ws = Workspace::default();
    view.render(material, &state, sampling, &mut ws).unwrap();
    let m = Moments::of(&ws.image, &view.weight);
    (m.std[0] + m.std[1] + m.std[2]) / 3.0
}

#[test]
fn adaptive_supersampling_tracks_a_box_filtered_reference_across_zoom() {
    let library = Library::load(&default_library_root()).unwrap();
    // One pixel covers 1/96 of a uv unit (a 1 m wall seen 1 cm per pixel).
    let view = flat_view(48, 1.0 / 96.0);
    let reference = Sampling { density: 1e6, max_per_axis: 12 };
    let adaptive = Sampling::default();
    let single = Sampling { density: 0.0, max_per_axis: 1 };
    let (mut err_adaptive, mut err_single, mut n) = (0.0f64, 0.0f64, 0);
    eprintln!("graph              log-scale  std: reference  adaptive  1 sample");
    for name in ["granite", "terrazzo", "boucle", "speckled_vinyl", "twill", "red_brick"] {
        let Some(material) = library.get(name) else { continue };
        for k in [0.0f32, 1.5, 3.0, 4.25] {
            let r = std_at(&view, material, k, reference);
            let a = std_at(&view, material, k, adaptive);
            let s = std_at(&view, material, k, single);
            eprintln!("{name:<18} {k:>9.2}  {r:>14.4}  {a:>8.4}  {s:>8.4}");
            err_adaptive += f64::from((a - r).abs() / r.max(1e-3));
            err_single += f64::from((s - r).abs() / r.max(1e-3));
            n += 1;
        }
    }
    let (ea, es) = (err_adaptive / n as f64, err_single / n as f64);
    eprintln!("mean relative error of the std: adaptive {ea:.3}, one sample {es:.3} ({n} cases)");
    assert!(n >= 16, "too few graphs found");
    // Measured: adaptive 0.41 (at most 4×4 samples: the std of a mean of 16 independent texels
    // cannot fall below a quarter of one texel's, while the reference keeps falling), one
    // sample 3.13; at most 3×3 samples 0.63, 6×6 0.24.
    assert!(
        ea < 0.25 * es,
        "adaptive sampling ({ea:.3}) is not much closer to the reference than one sample ({es:.3})"
    );
    assert!(ea < 0.5, "adaptive sampling is {ea:.3} off the reference on average");
}
