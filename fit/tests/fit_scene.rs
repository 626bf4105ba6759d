//! A whole fit of a dev scene, end to end, at reduced settings: the result does not depend on
//! the thread count, never reads `truth/` (a copy of the scene without it gives the same
//! bytes), and the output folder is complete.

use std::path::{Path, PathBuf};

use psc_fit::align::align_view;
use psc_fit::layer::Sampling;
use psc_fit::observe::ViewObservation;
use psc_fit::output::{self, OutputOptions};
use psc_fit::pipeline::{continue_fit, fit_scene, Continue, FitOptions, PartStatus, Silent};
use psc_fit::refit;
use psc_render::scene::Scene;
use psc_render::{LightRadiances, Renderer};
use psc_runtime::library::{default_library_root, Library};

#[allow(dead_code)] // the file serves several test crates
#[path = "../../tests/src/dev_scenes.rs"]
mod dev_scenes;
#[path = "../../tests/src/folders.rs"]
mod folders;
#[path = "../../tests/src/not_run.rs"]
mod not_run;
use folders::copy_tree;

fn small_options() -> FitOptions {
    let mut o = FitOptions { seed: 7, ..Default::default() };
    o.select.exemplars = 2;
    o.select.scales = 2;
    o.fit.max_iterations = 24;
    o.fit.starts = 2;
    o.fit.start_iterations = 4;
    o.fit.search_every = 12;
    o.fit.sampling = Sampling { density: 160.0, max_per_axis: 2 };
    o.grid.stride = 8;
    o.grid.samples_per_bin = 1;
    o.fit_pixels = 1024;
    o.search_pixels = 256;
    o.refit_iterations = 8;
    o.refit_rounds = 1;
    o
}

fn fit_into(scene_dir: &Path, out: &Path, threads: usize, library: &Library) {
    let scene = Scene::load(scene_dir).unwrap();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    pool.install(|| {
        let result = fit_scene(&scene, library, None, &small_options(), &Silent).unwrap();
        let opts = OutputOptions { texture_size: 32, render_spp: 2, force: true, seed: 7, command: "test".into() };
        output::write(out, &scene, library, &result, &opts).unwrap();
    });
}

/// Every file under `dir`, relative path → bytes, with the JSON fields that legitimately differ
/// between runs (timings, the scene's path) removed.
fn contents(dir: &Path) -> Vec<(PathBuf, Vec<u8>)> {
    fn walk(root: &Path, dir: &Path, out: &mut Vec<(PathBuf, Vec<u8>)>) {
        let mut entries: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
        entries.sort();
        for p in entries {
            if p.is_dir() {
                walk(root, &p, out);
                continue;
            }
            let mut bytes = std::fs::read(&p).unwrap();
            if p.extension().is_some_and(|e| e == "json") {
                let mut v: serde_json::Value = serde_json::from_slice(&bytes).unwrap();
                strip(&mut v);
                bytes = serde_json::to_vec(&v).unwrap();
            }
            out.push((p.strip_prefix(root).unwrap().to_path_buf(), bytes));
        }
    }
    fn strip(v: &mut serde_json::Value) {
        match v {
            serde_json::Value::Object(m) => {
                m.remove("timings_s");
                m.remove("timings"); // a part's timings inside result.json's fit_state
                m.remove("scene");
                m.values_mut().for_each(strip);
            }
            serde_json::Value::Array(a) => a.iter_mut().for_each(strip),
            _ => {}
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out
}

#[test]
fn fit_is_deterministic_across_thread_counts_and_never_reads_truth() {
    let Some(scene) = dev_scenes::dev_scene("dev_1", "fit_is_deterministic_across_thread_counts_and_never_reads_truth")
    else {
        return;
    };
    assert!(scene.join("truth").is_dir(), "the original keeps its truth/ for the comparison to mean something");
    let library = Library::load(&default_library_root()).unwrap();
    let scratch = tempfile::Builder::new().prefix("psc-fit-determinism-").tempdir().unwrap();
    let tmp = scratch.path();
    let copy = tmp.join("dev_1_without_truth");
    copy_tree(&scene, &copy, &["truth"]);
    fit_into(&scene, &tmp.join("with_truth_1_thread"), 1, &library);
    fit_into(&copy, &tmp.join("without_truth_2_threads"), 2, &library);
    let a = contents(&tmp.join("with_truth_1_thread"));
    let b = contents(&tmp.join("without_truth_2_threads"));
    let names: Vec<_> = a.iter().map(|x| x.0.clone()).collect();
    assert_eq!(names, b.iter().map(|x| x.0.clone()).collect::<Vec<_>>());
    for name in ["materials.json", "lights.json", "result.json", "renders/view0.png"] {
        assert!(names.iter().any(|n| n == Path::new(name)), "no {name} in the output");
    }
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "{} differs between the two fits", name.display());
    }
    eprintln!("{} files identical", a.len());
}

#[test]
fn an_existing_output_folder_is_kept_unless_forced_and_refit_only_starts_from_it() {
    let Some(scene_dir) =
        dev_scenes::dev_scene("dev_4", "an_existing_output_folder_is_kept_unless_forced_and_refit_only_starts_from_it")
    else {
        return;
    };
    let library = Library::load(&default_library_root()).unwrap();
    let scene = Scene::load(&scene_dir).unwrap();
    let scratch = tempfile::Builder::new().prefix("psc-fit-existing-").tempdir().unwrap();
    let tmp = scratch.path();
    std::fs::create_dir_all(tmp.join("out")).unwrap();
    std::fs::write(tmp.join("out/mine.txt"), "keep me").unwrap();
    let mut options = small_options();
    options.refit_rounds = 0;
    options.select.exemplars = 1;
    options.fit.max_iterations = 4;
    let result = fit_scene(&scene, &library, None, &options, &Silent).unwrap();
    let opts = OutputOptions { texture_size: 0, render_spp: 0, force: false, seed: 7, command: "test".into() };
    let err = output::write(&tmp.join("out"), &scene, &library, &result, &opts).unwrap_err().to_string();
    assert!(err.contains("exists") && err.contains("--force"), "{err}");
    assert_eq!(std::fs::read_to_string(tmp.join("out/mine.txt")).unwrap(), "keep me");
    let opts = OutputOptions { force: true, ..opts };
    output::write(&tmp.join("out"), &scene, &library, &result, &opts).unwrap();
    assert!(!tmp.join("out/mine.txt").exists() && tmp.join("out/materials.json").is_file());
    // No temporaries left beside it.
    let leftovers: Vec<_> = std::fs::read_dir(tmp).unwrap().map(|e| e.unwrap().file_name()).collect();
    assert_eq!(leftovers, vec![std::ffi::OsString::from("out")]);

    // `--refit-only` starts from exactly what was fitted, and keeps graphs, parameters and UV.
    let previous = output::read_previous(&tmp.join("out")).unwrap();
    assert_eq!(
        serde_json::to_string(&previous.parts).unwrap(),
        serde_json::to_string(&result.parts).unwrap(),
        "result.json's fit_state does not round-trip"
    );
    assert_eq!(previous.radiance, result.radiance);
    assert_eq!(previous.exposure, result.exposure, "the views' exposures round-trip");
    assert_eq!(result.exposure, vec![[1.0f32; 3]], "a single view's exposure is 1");
    let mut refit_options = options.clone();
    refit_options.refit_rounds = 1;
    let refit = continue_fit(&scene, &library, None, &previous, Continue::RefitOnly, &refit_options, &Silent).unwrap();
    assert!(!refit.light_rounds.is_empty(), "the refit solves the lights");
    for (a, b) in refit.parts.iter().zip(&result.parts) {
        assert_eq!((&a.graph, &a.state.params, a.state.uv), (&b.graph, &b.state.params, b.state.uv), "{}", a.name);
    }
    let mut wrong = previous.clone();
    wrong.parts.pop();
    let err = continue_fit(&scene, &library, None, &wrong, Continue::RefitOnly, &refit_options, &Silent)
        .unwrap_err()
        .to_string();
    assert!(err.contains("other parts"), "{err}");
    let mut wrong = previous.clone();
    wrong.exposure = vec![[1.0; 3], [0.9; 3]];
    let err = continue_fit(&scene, &library, None, &wrong, Continue::RefitOnly, &refit_options, &Silent)
        .unwrap_err()
        .to_string();
    assert!(err.contains("view exposures"), "{err}");
    wrong.exposure = vec![[1.0, f32::NAN, 1.0]];
    let err = continue_fit(&scene, &library, None, &wrong, Continue::RefitOnly, &refit_options, &Silent)
        .unwrap_err()
        .to_string();
    assert!(err.contains("view exposures"), "{err}");
}

/// A scene that names no lights is fitted under the area lights the loader places on the
/// ceiling every 3 m (as PhotoScene), and the global solve gives each of them its own radiance.
#[test]
fn a_scene_without_lights_is_fitted_under_generated_ceiling_lights() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room");
    let scratch = tempfile::Builder::new().prefix("psc-fit-no-lights-").tempdir().unwrap();
    let tmp = scratch.path();
    copy_tree(&example, tmp, &["truth"]);
    let manifest = tmp.join("scene.json");
    let mut m: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&manifest).unwrap()).unwrap();
    assert!(m.as_object_mut().unwrap().remove("lights").is_some(), "the example names its lights");
    std::fs::write(&manifest, serde_json::to_string_pretty(&m).unwrap()).unwrap();
    let scene = Scene::load(tmp).unwrap();
    assert!(scene.lights_generated);
    let (lo, hi) = scene.mesh.bounds();
    let per_axis = |a: usize| (((hi[a] - lo[a]) / 3.0).round() as usize).max(1);
    assert_eq!(scene.lights.len(), per_axis(0) * per_axis(2), "one light per 3 m × 3 m cell of the ceiling");
    assert!(scene.lights.len() >= 2, "the example room is big enough for a grid, so the solve has lights to separate");

    let library = Library::load(&default_library_root()).unwrap();
    let result = fit_scene(&scene, &library, None, &small_options(), &Silent).unwrap();
    assert_eq!(result.slot_names.len(), scene.lights.len());
    assert!(result.slot_names.iter().all(|n| n.starts_with("auto")), "{:?}", result.slot_names);
    assert!(!result.light_rounds.is_empty(), "the lights are solved");
    let solved = &result.light_rounds[0].solve;
    for (name, r) in result.slot_names.iter().zip(&solved.radiance) {
        assert!(r.iter().all(|x| x.is_finite() && *x >= 0.0), "{name}: {r:?}");
    }
    assert!(
        solved.radiance.iter().filter(|r| r.iter().sum::<f32>() > 0.0).count() >= 2,
        "the photo is lit by more than one of the generated lights: {:?}",
        solved.radiance
    );
}

/// `--resume` continues a fit: every fitted part keeps its graph (unless `--graph` now forces
/// another) and its optimisation goes on from the fitted state, so the parts' losses fall.
#[test]
fn resume_continues_every_part_from_its_fitted_state() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room");
    let library = Library::load(&default_library_root()).unwrap();
    let scene = Scene::load(&example).unwrap();
    let scratch = tempfile::Builder::new().prefix("psc-fit-resume-").tempdir().unwrap();
    // A child of the scratch folder: like a first fit's, the output folder does not exist yet.
    let out = scratch.path().join("out");
    // No light rounds, in either: the losses are then of the part fits under the same lights.
    let options = FitOptions { refit_rounds: 0, ..small_options() };
    let first = fit_scene(&scene, &library, None, &options, &Silent).unwrap();
    let opts = OutputOptions { texture_size: 0, render_spp: 0, force: true, seed: 7, command: "test".into() };
    output::write(&out, &scene, &library, &first, &opts).unwrap();
    let previous = output::read_previous(&out).unwrap();
    // A result.json an editor saved with a byte-order mark reads the same.
    let bom = scratch.path().join("bom");
    std::fs::create_dir(&bom).unwrap();
    let text = std::fs::read(out.join("result.json")).unwrap();
    std::fs::write(bom.join("result.json"), [b"\xEF\xBB\xBF".as_slice(), &text].concat()).unwrap();
    let with_bom = output::read_previous(&bom).unwrap();
    assert_eq!(serde_json::to_value(&with_bom).unwrap(), serde_json::to_value(&previous).unwrap());

    let fitted = |r: &psc_fit::pipeline::FitResult| -> Vec<(String, String, f32)> {
        r.parts
            .iter()
            .filter(|p| p.status == PartStatus::Fitted)
            .map(|p| (p.name.clone(), p.graph.clone(), p.loss.total))
            .collect()
    };
    let mut resume_options = options.clone();
    resume_options.fit.max_iterations = 48;
    let resumed = continue_fit(&scene, &library, None, &previous, Continue::Resume, &resume_options, &Silent).unwrap();
    let (before, after) = (fitted(&first), fitted(&resumed));
    assert!(before.len() >= 3, "the example has textured parts: {before:?}");
    // Every selected part records its flat-colour check, and its material is the check's
    // lower-loss side.
    for p in first.parts.iter().filter(|p| p.status == PartStatus::Fitted) {
        let check = p.flat_check.as_ref().unwrap_or_else(|| panic!("{}: no flat-colour check", p.name));
        let kept = if check.flat_kept() { "homogeneous" } else { check.contest_winner.as_str() };
        assert_eq!(p.graph, kept, "{}: {check:?}", p.name);
        assert_eq!(p.loss.total, check.contest_loss.min(check.flat_loss), "{}: {check:?}", p.name);
    }
    assert_eq!(
        before.iter().map(|p| (&p.0, &p.1)).collect::<Vec<_>>(),
        after.iter().map(|p| (&p.0, &p.1)).collect::<Vec<_>>(),
        "every fitted part keeps its graph"
    );
    for (a, b) in first.parts.iter().zip(&resumed.parts).filter(|(a, _)| a.status == PartStatus::Fitted) {
        assert!(b.history.starts_with(&a.history), "{}: the history goes on from the previous one", a.name);
        assert!(b.iterations > a.iterations, "{}", a.name);
        assert_eq!(
            b.top.iter().map(|t| &t.graph).collect::<Vec<_>>(),
            a.top.iter().map(|t| &t.graph).collect::<Vec<_>>()
        );
        assert_eq!(b.flat_check, a.flat_check, "{}: the check is read back from result.json", a.name);
    }
    let total = |v: &[(String, String, f32)]| v.iter().map(|p| p.2).sum::<f32>();
    println!("summed loss of the fitted parts: {:.4} → {:.4} after resuming", total(&before), total(&after));
    assert!(total(&after) < total(&before), "{before:?} → {after:?}");

    // A part forced to another graph is fitted anew with it.
    let (name, graph, _) = &before[0];
    let other = if graph == "plaster" { "oak_planks" } else { "plaster" };
    resume_options.forced.insert(name.clone(), other.to_string());
    let forced = continue_fit(&scene, &library, None, &previous, Continue::Resume, &resume_options, &Silent).unwrap();
    let part = forced.parts.iter().find(|p| &p.name == name).unwrap();
    assert_eq!((&part.graph, &part.status), (&other.to_string(), &PartStatus::Forced));
}

/// The fit ends on a light solve applied without a re-fit, so that the path tracer sees the
/// parts as the photos do: a fresh solve under the fitted materials finds the parts' albedo
/// factors nearer 1 than the final calibration found them (the whole-part mean match of the
/// last round, made in the shading layer, had left them off). Both solves carry the Monte Carlo
/// noise of their 16-spp renders, which bounds how near 1 the fresh one can come (at these test
/// settings about half of the calibration's mean |ln factor|); without the calibration the two
/// would be alike.
#[test]
fn the_fit_ends_with_part_colours_the_path_tracer_agrees_with() {
    let example = Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room");
    let scene = Scene::load(&example).unwrap();
    let library = Library::load(&default_library_root()).unwrap();
    let result = fit_scene(&scene, &library, None, &small_options(), &Silent).unwrap();
    // The last solve was applied without a re-fit: the final calibration, or a round whose
    // lights had converged.
    let calibration = &result.light_rounds.last().expect("the lights are solved").solve;

    let mut renderer =
        Renderer::new(&scene, scene.mtl_materials(&mut Vec::new()), &LightRadiances::unit(&scene)).unwrap();
    renderer.set_materials(result.bindings(&library).unwrap()).unwrap();
    let views: Vec<ViewObservation> = scene
        .views
        .iter()
        .map(|v| ViewObservation::new(v, &scene.mesh.part_names, renderer.geometry(), 0).unwrap())
        .collect();
    let aligned: Vec<_> =
        views.iter().enumerate().map(|(i, o)| align_view(o, i, scene.mesh.part_names.len())).collect();
    let check = refit::solve_lights(&renderer, &views, &aligned, 99).unwrap();
    let observed: Vec<usize> =
        (0..result.parts.len()).filter(|&i| result.parts[i].status != PartStatus::Unobserved).collect();
    // Mean over observed parts of the largest |ln factor| over the channels.
    let off = |factors: &[[f32; 3]]| {
        observed.iter().map(|&i| factors[i].iter().map(|f| f.ln().abs()).fold(0.0f32, f32::max)).sum::<f32>()
            / observed.len() as f32
    };
    let (before, after) = (off(&calibration.part_scales), off(&check.part_scales));
    println!(
        "mean |ln factor| over {} parts: {before:.4} found by the calibration, {after:.4} after it",
        observed.len()
    );
    assert!(before > 0.0 && after < 0.75 * before, "the calibration left the parts off: {before} → {after}");
}
