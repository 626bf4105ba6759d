//! `psc eval` end to end on the smallest dev scene (dev_4) at a few samples per pixel: the whole
//! chain (truth, renders, relighting, metrics, outputs) and its errors on bad input.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use psc_fit::eval::{evaluate, write_outputs, EvalOptions, Evaluation, FitFiles, Geometry, Method, ViewKind};
use psc_runtime::library::{default_library_root, Library};

#[path = "../../tests/src/folders.rs"]
mod folders;
use folders::copy_tree;

fn scene() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes/dev_4")
}

fn library() -> &'static Library {
    static LIB: OnceLock<Library> = OnceLock::new();
    LIB.get_or_init(|| Library::load(&default_library_root()).expect("the library compiles"))
}

/// A fresh, empty folder for one test, removed when the guard is dropped.
fn temp_dir(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-eval-test-{name}-")).tempdir().unwrap()
}

fn truth_json(scene: &Path) -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(scene.join("truth/truth.json")).unwrap()).unwrap()
}

/// A stand-in fit: the true light radiances, and the homogeneous graph at each part's true mean
/// albedo (the test may read truth/).
fn write_fit(dir: &Path, scene: &Path) -> FitFiles {
    let t = truth_json(scene);
    let lights: Vec<serde_json::Value> = t["lights"]
        .as_array()
        .unwrap()
        .iter()
        .map(|l| serde_json::json!({"name": l["name"], "radiance_rgb": l["radiance_rgb"]}))
        .collect();
    let mut parts = serde_json::Map::new();
    for p in t["parts"].as_array().unwrap() {
        let rough = p["roughness"].as_f64().unwrap().max(0.02);
        parts.insert(
            p["name"].as_str().unwrap().to_string(),
            serde_json::json!({"graph": "homogeneous", "params": {"albedo_color": p["albedo_mean_linear"], "rough": rough}}),
        );
    }
    std::fs::write(dir.join("lights.json"), serde_json::json!({ "lights": lights }).to_string()).unwrap();
    std::fs::write(dir.join("materials.json"), serde_json::json!({ "parts": parts }).to_string()).unwrap();
    FitFiles::in_dir(dir)
}

fn quick(methods: &[Method], kinds: &[ViewKind], geometries: &[Geometry], spp: u32) -> EvalOptions {
    EvalOptions {
        spp,
        flat_spp: spp,
        flat_iterations: 1,
        methods: methods.to_vec(),
        kinds: kinds.to_vec(),
        geometries: geometries.to_vec(),
        threads: Some(2),
        ..Default::default()
    }
}

fn run(scene: &Path, fit: &FitFiles, opts: &EvalOptions) -> Result<Evaluation, String> {
    evaluate(scene, fit, library(), opts, &mut |_| {}).map_err(|e| e.0)
}

fn listing(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p.clone());
            }
            out.push(p);
        }
    }
    out.sort();
    out
}

#[test]
fn true_materials_beat_pixel_median_on_the_true_geometry() {
    let tmp = temp_dir("oracle");
    let dir = tmp.path();
    let fit = write_fit(dir, &scene());
    let opts = quick(&[Method::Oracle, Method::PixelMedian], &[ViewKind::Input], &[Geometry::Truth], 16);
    let e = run(&scene(), &fit, &opts).unwrap();
    let oracle = e.row(Geometry::Truth, ViewKind::Input, Method::Oracle).unwrap();
    let median = e.row(Geometry::Truth, ViewKind::Input, Method::PixelMedian).unwrap();
    assert!(oracle.parts >= 3 && oracle.parts == median.parts, "{oracle:?}");
    // The issue quotes 0.2–0.35× at the truth's 256 spp; 16 spp adds noise to the oracle.
    assert!(oracle.rmse < 0.5 * median.rmse, "oracle {} vs pixel median {}", oracle.rmse, median.rmse);
    assert!(oracle.mean_colour < 0.25 * median.mean_colour, "{oracle:?} vs {median:?}");
    assert!(oracle.ssim > median.ssim);
}

#[test]
fn every_row_image_and_render_is_written_whole() {
    let tmp = temp_dir("outputs");
    let dir = tmp.path();
    let fit = write_fit(dir, &scene());
    let lights = std::fs::read_to_string(&fit.lights).unwrap();
    let mut lights: serde_json::Value = serde_json::from_str(&lights).unwrap();
    lights["lights"][1]["radiance_rgb"] = serde_json::json!([0, 0, 0]);
    std::fs::write(&fit.lights, lights.to_string()).unwrap();
    let opts = EvalOptions {
        geometries: vec![Geometry::Model],
        ..quick(
            &[Method::Fitted, Method::FlatFitted, Method::PixelMedian],
            &[ViewKind::Input, ViewKind::Novel, ViewKind::Relit],
            &[Geometry::Model],
            2,
        )
    };
    let e = run(&scene(), &fit, &opts).unwrap();
    // dev_4: one input view, two novel, one relit (on the input view's camera, so 3 renders per
    // method) plus one flat-fit round.
    assert_eq!(e.renders, 3 * 3 + 1);
    assert_eq!(e.rows.len(), 3 * 3);
    assert_eq!(e.images.len(), 3 * 4);
    // The relit view shares the input view's renders, with each light's radiance times the
    // truth's relit/original ratio: with ceiling1 off, relit = ratio(ceiling0) × input per pixel.
    let img = |kind, m| e.images.iter().find(|i| i.kind == kind && i.method == m).unwrap();
    let (input, relit) = (img(ViewKind::Input, Method::PixelMedian), img(ViewKind::Relit, Method::PixelMedian));
    let l0 = &truth_json(&scene())["lights"][0];
    assert_eq!(l0["name"], "ceiling0");
    let ratio: Vec<f64> = (0..3)
        .map(|k| l0["relit_radiance_rgb"][k].as_f64().unwrap() / l0["radiance_rgb"][k].as_f64().unwrap())
        .collect();
    let mut lit = 0;
    for (p, q) in input.render.iter().zip(&relit.render) {
        for k in 0..3 {
            assert!(
                (q[k] as f64 - ratio[k] * p[k] as f64).abs() <= 1e-5 * (1.0 + p[k] as f64),
                "{p:?} {q:?} {ratio:?}"
            );
            lit += (p[k] > 0.0) as usize;
        }
    }
    assert!(lit > input.render.len(), "the view is lit");

    let eval_dir = dir.join("eval");
    // A folder that is not a previous evaluation is refused and left as it was.
    std::fs::create_dir_all(eval_dir.join("stale")).unwrap();
    let err = write_outputs(&e, &eval_dir, None).unwrap_err();
    assert!(err.to_string().contains("not a previous evaluation"), "{err}");
    assert!(eval_dir.join("stale").is_dir() && !eval_dir.join("eval.json").exists());
    // A previous evaluation is replaced whole.
    std::fs::write(eval_dir.join("eval.json"), "{}").unwrap();
    let copy = dir.join("copy.json");
    write_outputs(&e, &eval_dir, Some(&copy)).unwrap();
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(eval_dir.join("eval.json")).unwrap()).unwrap();
    assert_eq!(json, serde_json::from_str::<serde_json::Value>(&std::fs::read_to_string(&copy).unwrap()).unwrap());
    assert_eq!(json["rows"].as_array().unwrap().len(), 9);
    for im in json["images"].as_array().unwrap() {
        assert!(eval_dir.join(im["render"].as_str().unwrap()).is_file(), "{im}");
    }
    assert!(!eval_dir.join("stale").exists(), "the previous folder is replaced");
    let hidden: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().starts_with('.'))
        .collect();
    assert!(hidden.is_empty(), "temporaries left: {hidden:?}");
    let table = e.table();
    assert!(table.contains("fitted / pixel median") && table.contains("flat fitted"), "{table}");
}

#[test]
fn results_do_not_depend_on_the_thread_count() {
    let tmp = temp_dir("threads");
    let dir = tmp.path();
    let fit = write_fit(dir, &scene());
    let mut opts = quick(&[Method::FlatFitted], &[ViewKind::Input], &[Geometry::Model], 1);
    opts.threads = Some(1);
    let a = run(&scene(), &fit, &opts).unwrap();
    opts.threads = Some(3);
    let b = run(&scene(), &fit, &opts).unwrap();
    assert_eq!(a.rows, b.rows);
    assert_eq!(a.flat_albedo, b.flat_albedo);
}

/// The fit's exposure of an input view (result.json) multiplies the renders of that view under
/// the fit's lights, and nothing else: not the relit view on the same camera, not the oracle.
#[test]
fn input_views_are_rendered_at_the_fits_exposure() {
    let tmp = temp_dir("exposure");
    let dir = tmp.path();
    let fit = write_fit(dir, &scene());
    let opts = quick(&[Method::Oracle, Method::Fitted], &[ViewKind::Input, ViewKind::Relit], &[Geometry::Model], 1);
    let plain = run(&scene(), &fit, &opts).unwrap();
    let exposure = [2.0f32, 1.0, 0.5];
    std::fs::write(&fit.result, serde_json::json!({"lights": {"exposure_rgb": {"view0": exposure}}}).to_string())
        .unwrap();
    let exposed = run(&scene(), &fit, &opts).unwrap();
    assert_eq!(exposed.input_exposure, vec![("view0".to_string(), exposure)]);
    let mut compared = 0;
    for (a, b) in plain.images.iter().zip(&exposed.images) {
        assert_eq!((a.kind, a.method, &a.view), (b.kind, b.method, &b.view));
        let e = if (a.kind, a.method) == (ViewKind::Input, Method::Fitted) { exposure } else { [1.0; 3] };
        for (p, q) in a.render.iter().zip(&b.render) {
            assert_eq!(*q, [0, 1, 2].map(|k| p[k] * e[k]), "{:?} {:?}", a.kind, a.method);
        }
        compared += 1;
    }
    assert_eq!(compared, 4);
    let input = |e: &psc_fit::eval::Evaluation| e.row(Geometry::Model, ViewKind::Input, Method::Fitted).unwrap().rmse;
    assert!(input(&plain) != input(&exposed), "the metrics see the exposure");
}

/// Runs the evaluation expecting an error containing `needle`, and checks it wrote nothing.
fn expect_error(scene: &Path, fit: &FitFiles, opts: &EvalOptions, needle: &str) {
    let dir = fit.materials.parent().unwrap();
    let before = listing(dir);
    let err = run(scene, fit, opts).expect_err("bad input must fail");
    assert!(err.contains(needle), "error `{err}` lacks `{needle}`");
    assert_eq!(listing(dir), before, "nothing may be written on bad input");
}

#[test]
fn bad_fit_files_are_clear_errors() {
    let tmp = temp_dir("bad-fit");
    let dir = tmp.path();
    let fit = write_fit(dir, &scene());
    let opts = quick(&[Method::PixelMedian], &[ViewKind::Input], &[Geometry::Model], 1);
    let good_lights = std::fs::read_to_string(&fit.lights).unwrap();
    let good_materials = std::fs::read_to_string(&fit.materials).unwrap();

    for (text, needle) in [
        (
            r#"{"lights": [{"name": "ceiling0", "radiance_rgb": [NaN, 1, 1]}, {"name": "ceiling1", "radiance_rgb": 1}]}"#,
            "lights.json",
        ),
        (
            r#"{"lights": [{"name": "ceiling0", "radiance_rgb": [1e999, 1, 1]}, {"name": "ceiling1", "radiance_rgb": 1}]}"#,
            "lights.json",
        ),
        (
            r#"{"lights": [{"name": "ceiling0", "radiance_rgb": [-1, 1, 1]}, {"name": "ceiling1", "radiance_rgb": 1}]}"#,
            "negative",
        ),
        (r#"{"lights": [{"name": "ceiling0", "radiance_rgb": 1}]}"#, "ceiling1"),
    ] {
        std::fs::write(&fit.lights, text).unwrap();
        expect_error(&scene(), &fit, &opts, needle);
    }
    std::fs::write(&fit.lights, &good_lights).unwrap();

    for (text, needle) in [
        (r#"{"parts": {"sofa": {"graph": "homogeneous"}}}"#, "sofa"),
        (r#"{"parts": {"floor": {"graph": "no_such_graph"}}}"#, "no_such_graph"),
        (r#"{"parts": {"floor": {"graph": "homogeneous", "params": {"rough": 7}}}}"#, "rough"),
        (r#"{"parts": "#, "materials.json"),
    ] {
        std::fs::write(&fit.materials, text).unwrap();
        expect_error(&scene(), &fit, &opts, needle);
    }
    std::fs::write(&fit.materials, &good_materials).unwrap();

    for (text, needle) in [
        (r#"{"lights": {"exposure_rgb": {"view0": [1, 0, 1]}}}"#, "view0"),
        (r#"{"lights": {"exposure_rgb": {"view0": [1, 1]}}}"#, "view0"),
        (r#"{"lights": {"exposure_rgb": [1, 1, 1]}}"#, "exposure_rgb"),
        (r#"{"lights": "#, "result.json"),
    ] {
        std::fs::write(&fit.result, text).unwrap();
        expect_error(&scene(), &fit, &opts, needle);
    }
    std::fs::remove_file(&fit.result).unwrap();
    std::fs::remove_file(&fit.lights).unwrap();
    expect_error(&scene(), &fit, &opts, "missing");
}

#[test]
fn bad_scenes_are_clear_errors() {
    let tmp = temp_dir("bad-scene");
    let dir = tmp.path();
    let fit_dir = dir.join("fit");
    std::fs::create_dir_all(&fit_dir).unwrap();
    let fit = write_fit(&fit_dir, &scene());
    let opts = quick(&[Method::PixelMedian], &[ViewKind::Input], &[Geometry::Model], 1);

    // No truth/.
    let bare = dir.join("bare");
    copy_tree(&scene(), &bare, &["truth"]);
    expect_error(&bare, &fit, &opts, "no truth/");

    // A novel view whose label image has another size than its image.
    let odd = dir.join("odd");
    copy_tree(&scene(), &odd, &[]);
    psc_render::image_io::write_gray16(&odd.join("truth/novel/novel0_parts.png"), 160, 120, &vec![1u16; 160 * 120])
        .unwrap();
    expect_error(&odd, &fit, &opts, "160x120");

    // The true geometry asked for but absent.
    let no_mesh = dir.join("no_mesh");
    copy_tree(&scene(), &no_mesh, &["scene_true.obj"]);
    let truth_opts = quick(&[Method::PixelMedian], &[ViewKind::Input], &[Geometry::Truth], 1);
    expect_error(&no_mesh, &fit, &truth_opts, "scene_true.obj");
}
