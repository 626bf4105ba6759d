//! A photo larger than `--max-photo-pixels` is fitted at a working raster (`psc_fit::working`).
//! The bundled example room with its photo and label image blown up ×2 by pixel repetition is
//! the exact case: averaged over 2×2 blocks it is the original photo again, so the observation
//! of the large scene at the original's size must be the original's observation, and a whole
//! `psc fit` of it must write its re-renders at that size and a report whose difference image
//! compares like with like.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use psc_fit::observe::ViewObservation;
use psc_fit::working::WorkingRaster;
use psc_render::scene::Scene;

#[path = "../../tests/src/folders.rs"]
mod folders;
use folders::copy_tree;

fn repo() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// The example room with every pixel of its photo and label image repeated 2×2, in `dir`.
fn doubled_example(dir: &Path) -> PathBuf {
    let scene = dir.join("room");
    copy_tree(&repo().join("examples/room"), &scene, &[]);
    for name in ["views/view0.png", "views/view0_parts.png"] {
        let path = scene.join(name);
        let img = image::open(&path).unwrap();
        let (w, h) = (img.width(), img.height());
        img.resize_exact(2 * w, 2 * h, image::imageops::FilterType::Nearest).save(&path).unwrap();
    }
    scene
}

fn scratch(test: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-working-raster-{test}-")).tempdir().unwrap()
}

#[test]
fn a_doubled_photo_observed_within_the_originals_pixels_is_the_original() {
    let tmp = scratch("observe");
    let dir = tmp.path();
    let original = Scene::load(&repo().join("examples/room")).unwrap();
    let doubled = Scene::load(&doubled_example(dir)).unwrap();
    let (w, h) = (original.views[0].width, original.views[0].height);
    assert_eq!((doubled.views[0].width, doubled.views[0].height), (2 * w, 2 * h));
    let observe = |scene: &Scene, max_pixels: usize| {
        let renderer = psc_render::Renderer::new(
            scene,
            scene.mtl_materials(&mut Vec::new()),
            &psc_render::LightRadiances::unit(scene),
        )
        .unwrap();
        ViewObservation::new(&scene.views[0], &scene.mesh.part_names, renderer.geometry(), max_pixels).unwrap()
    };
    let a = observe(&original, 0);
    let b = observe(&doubled, w * h);
    assert_eq!(b.raster, WorkingRaster { factor: 2, origin: [0, 0], width: w, height: h });
    assert_eq!((b.camera.width, b.camera.height), (w, h));
    assert_eq!(a.photo.linear, b.photo.linear, "a block of four equal pixels averages to that pixel");
    let worst =
        a.photo.encoded.iter().zip(&b.photo.encoded).flat_map(|(p, q)| (0..3).map(move |c| (p[c] - q[c]).abs()));
    assert!(worst.fold(0.0f32, f32::max) < 1e-5, "encoded values are the sRGB encoding of the linear average");
    assert!((0..w * h).all(|i| a.photo.clipped(i) == b.photo.clipped(i)));
    assert_eq!(a.labels, b.labels);
    // The windowed camera shoots the rays through the blocks' centres: the original's rays.
    assert_eq!(a.geo.part, b.geo.part);
    let depth = a.geo.depth.iter().zip(&b.geo.depth).map(|(p, q)| (p - q).abs()).fold(0.0f32, f32::max);
    assert!(depth < 1e-4, "depths differ by {depth}");
    // Within a budget of the doubled photo's own pixels it is observed as it is.
    let full = observe(&doubled, 4 * w * h);
    assert!(full.raster.is_identity() && full.photo.width == 2 * w);
}

#[test]
fn a_fit_at_a_working_raster_renders_and_reports_at_it() {
    let tmp = scratch("fit");
    let dir = tmp.path();
    let scene = doubled_example(dir);
    let out = dir.join("fit");
    let original = Scene::load(&repo().join("examples/room")).unwrap();
    let (w, h) = (original.views[0].width, original.views[0].height);
    let budget = (w * h).to_string();
    let mut args: Vec<String> = ["fit", scene.to_str().unwrap(), "--out", out.to_str().unwrap(), "--force"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    for part in ["floor", "ceiling", "walls", "rug", "crate_crate", "barrel_barrelRing", "barrel_barrelS_D"] {
        args.extend(["--graph".into(), format!("{part}=homogeneous")]);
    }
    args.extend(
        ["--iterations", "10", "--texture-size", "16", "--render-spp", "2", "--refit-rounds", "0"].map(String::from),
    );
    args.extend(["--max-photo-pixels".to_string(), budget]);
    let o = Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let said = format!("the {}x{} photo is fitted at {w}x{h} (blocks of 2x2 pixels", 2 * w, 2 * h);
    assert!(text(&o).contains(&said), "no word of the working raster: {}", text(&o));
    for (file, size) in [("view0.png", (w, h)), ("view0_beside_photo.png", (2 * w, h))] {
        let (iw, ih) = image::image_dimensions(out.join("renders").join(file)).unwrap();
        assert_eq!((iw as usize, ih as usize), size, "{file}");
    }
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("result.json")).unwrap()).unwrap();
    let view = &result["views"][0];
    assert_eq!(view["photo_size"], serde_json::json!([2 * w, 2 * h]));
    assert_eq!(view["working_raster"], serde_json::json!({"factor": 2, "origin": [0, 0], "width": w, "height": h}));
    // The report compares the render with the photo at the render's raster.
    let o = Command::new(env!("CARGO_BIN_EXE_psc")).args(["report", out.to_str().unwrap()]).output().unwrap();
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("|photo − render| ×"), "no difference image in the report");
    assert!(!html.contains(&format!("the render {w}×{h}")), "the report compared images of different sizes");
    // Every part fitted in the view has its crop of the render beside the photo's.
    let (photo_crops, render_crops) =
        (html.matches("alt=\"photo crop\"").count(), html.matches("alt=\"render crop\"").count());
    assert!(photo_crops >= 7 && render_crops == photo_crops, "{photo_crops} photo crops, {render_crops} render crops");
}

#[test]
fn a_budget_too_small_to_fit_at_is_refused_before_any_work() {
    let tmp = scratch("refused");
    let out = tmp.path().join("fit");
    for (budget, says) in [("100", "too few to fit a room at"), ("16383", "at least 16384"), ("lots", "invalid")] {
        let o = Command::new(env!("CARGO_BIN_EXE_psc"))
            .args(["fit", repo().join("examples/room").to_str().unwrap(), "--out", out.to_str().unwrap()])
            .args(["--max-photo-pixels", budget])
            .output()
            .unwrap();
        assert_eq!(o.status.code(), Some(2), "{budget}: {}", text(&o));
        assert!(text(&o).contains(says) && text(&o).contains("--max-photo-pixels"), "{budget}: {}", text(&o));
        assert!(!out.exists(), "{budget}: an output folder was made");
    }
}
