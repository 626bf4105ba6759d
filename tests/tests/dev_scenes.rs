//! The dev scenes through `psc_runtime::view`: the validation choices that read ground truth
//! work on every dev scene, and with the default choices a scene renders the same with its
//! `truth/` folder as without it (nothing read it). Needs `../shared/scenes`: says so loudly
//! when absent, and fails then under `CI`.

use psc_base::progress::NoProgress;
use psc_render::LightsSource;
use psc_render::{RenderOptions, Renderer};
use psc_runtime::view::{open_view, GeometryChoice, MaterialsChoice, OpenedView, ViewRequest};
use psc_tests::dev_scenes::{all_dev_scenes, dev_scene};
use psc_tests::folders::copy_tree;

fn render_small(v: &OpenedView) -> Vec<[f32; 3]> {
    let renderer = Renderer::new(&v.scene, v.materials.clone(), &v.radiances).unwrap();
    let opts = RenderOptions { width: v.width, height: v.height, spp: 2, ..Default::default() };
    renderer.render(&v.camera, &opts).unwrap().image
}

#[test]
fn truth_choices_open_every_dev_scene() {
    let Some(scenes) = all_dev_scenes("truth_choices_open_every_dev_scene") else { return };
    for dir in scenes {
        let truth = ViewRequest {
            scene: dir.clone(),
            geometry: GeometryChoice::Truth,
            materials: MaterialsChoice::Truth,
            lights: LightsSource::Truth,
            size: Some((16, 12)),
            ..Default::default()
        };
        let v = open_view(&truth, None, &NoProgress).unwrap_or_else(|e| panic!("{}: {e}", dir.display()));
        assert!(v.radiances.source.contains("truth.json"), "{}", v.radiances.source);
        assert!(v.radiances.lights.iter().any(|r| *r != [1.0; 3]), "{}: unit radiances from truth?", dir.display());
        let img = render_small(&v);
        assert!(img.iter().any(|p| p.iter().any(|&c| c > 0.0)), "{}: a black image", dir.display());
    }
}

#[test]
fn default_choices_render_the_same_without_truth() {
    let Some(dir) = dev_scene("dev_1", "default_choices_render_the_same_without_truth") else { return };
    let tmp = tempfile::Builder::new().prefix("psc-dev-scene-no-truth-").tempdir().unwrap();
    let copy = tmp.path();
    copy_tree(&dir, copy, &["truth"]);
    assert!(!copy.join("truth").exists());
    let with =
        open_view(&ViewRequest { scene: dir, size: Some((24, 18)), ..Default::default() }, None, &NoProgress).unwrap();
    let without = open_view(
        &ViewRequest { scene: copy.to_path_buf(), size: Some((24, 18)), ..Default::default() },
        None,
        &NoProgress,
    )
    .unwrap();
    assert_eq!(with.radiances.lights, without.radiances.lights);
    assert_eq!(render_small(&with), render_small(&without));
}

/// A missing scene is `None` on a developer's machine and a failure under CI.
#[test]
fn a_missing_scene_is_reported_and_fails_under_ci() {
    let result = std::panic::catch_unwind(|| dev_scene("no_such_scene", "this self-test of the skip path"));
    if std::env::var_os("CI").is_some() {
        let err = result.expect_err("CI is set: a missing scene must fail the test");
        let msg = err.downcast_ref::<String>().cloned().unwrap_or_default();
        assert!(msg.contains("no_such_scene") && msg.contains("CI is set"), "{msg}");
    } else {
        assert_eq!(result.ok(), Some(None));
    }
}
