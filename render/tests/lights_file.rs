//! The lights file: round trips, hostile input with messages that name the file, the field and
//! what was expected, and truth read only when asked for by name.

mod common;

use std::path::Path;

use common::*;
use psc_render::lights::{LightEntry, Rgb};
use psc_render::{LightRadiances, LightsFile, LightsSource, Scene};

fn parse(text: &str) -> Result<LightsFile, String> {
    LightsFile::parse(Path::new("dir/lights.json"), text).map_err(|e| e.to_string())
}

fn parse_err(text: &str) -> String {
    match parse(text) {
        Ok(f) => panic!("{text} should be refused, got {f:?}"),
        Err(e) => {
            eprintln!("{e}");
            assert!(e.starts_with("dir/lights.json:"), "the message names the file: {e}");
            e
        }
    }
}

#[test]
fn round_trips() {
    let file = LightsFile {
        lights: vec![
            LightEntry { name: "a".into(), radiance_rgb: Rgb([1.5, 0.0, 3.25e7]) },
            LightEntry { name: "b c".into(), radiance_rgb: Rgb([f32::MAX, 1e-30, 0.1]) },
        ],
        environment_scale: Some(Rgb([0.5; 3])),
    };
    assert_eq!(parse(&file.to_json()).unwrap(), file);
    let no_env = LightsFile { environment_scale: None, ..file.clone() };
    assert_eq!(parse(&no_env.to_json()).unwrap(), no_env);
    // A grey scalar (and the `radiance` spelling) reads as a triple and writes as one.
    let grey = parse(r#"{"lights": [{"name": "a", "radiance": 2}], "environment_scale": 0.25}"#).unwrap();
    assert_eq!(grey.lights[0].radiance_rgb, Rgb([2.0; 3]));
    assert_eq!(grey.environment_scale, Some(Rgb([0.25; 3])));
    assert_eq!(parse(&grey.to_json()).unwrap(), grey);
}

#[test]
fn written_radiances_read_back_for_the_scene() {
    let tmp = temp_dir("lights-rt");
    let dir = tmp.path();
    write_scene(dir);
    let scene = Scene::load(dir).unwrap();
    let mut r = LightRadiances::unit(&scene);
    r.lights = vec![[12.5, 7.25, 0.1]];
    r.environment = [0.3, 0.2, 0.1];
    let names: Vec<String> = scene.lights.iter().map(|l| l.name.clone()).collect();
    let path = dir.join("out_lights.json");
    LightsFile::from_radiances(&r, &names).write(&path).unwrap();
    let mut w = Vec::new();
    let back = LightRadiances::from_file(&path, &scene, &mut w).unwrap();
    assert_eq!((back.lights, back.environment), (r.lights, r.environment));
    assert!(w.is_empty(), "{w:?}");
}

#[test]
fn negative_and_overflowing_values_are_refused() {
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": [1, -2, 3]}]}"#);
    assert!(e.contains("lights[0].radiance_rgb") && e.contains("-2") && e.contains("non-negative"), "{e}");
    let e = parse_err(r#"{"lights": [], "environment_scale": -0.5}"#);
    assert!(e.contains("environment_scale") && e.contains("-0.5"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": [1e39, 1, 1]}]}"#);
    assert!(e.contains("1e39") && e.contains("f32"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": 1e400}]}"#);
    assert!(e.contains("lights[0].radiance_rgb") || e.contains("out of range"), "{e}");
}

#[test]
fn wrong_shapes_name_the_field_and_what_was_expected() {
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": "bright"}]}"#);
    assert!(e.contains("field `lights[0].radiance_rgb`") && e.contains("\"bright\"") && e.contains("[r, g, b]"), "{e}");
    assert!(!e.contains("untagged"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": [[1, 2, 3]]}]}"#);
    assert!(e.contains("lights[0].radiance_rgb") && e.contains("sequence") && e.contains("number"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": [1, 2]}]}"#);
    assert!(e.contains("lights[0].radiance_rgb") && e.contains("three numbers"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": [1, 2, 3, 4]}]}"#);
    assert!(e.contains("three numbers"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a"}]}"#);
    assert!(e.contains("radiance_rgb") && e.contains("missing"), "{e}");
    let e = parse_err(r#"{"lights": {"name": "a"}}"#);
    assert!(e.contains("lights") && e.contains("sequence"), "{e}");
}

#[test]
fn unknown_fields_and_repeated_lights_are_refused() {
    let e = parse_err(r#"{"lights": [], "enviroment_scale": 2}"#);
    assert!(e.contains("enviroment_scale") && e.contains("unknown field"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": 1, "colour": 2}]}"#);
    assert!(e.contains("lights[0]") && e.contains("colour"), "{e}");
    let e = parse_err(r#"{"lights": [{"name": "a", "radiance_rgb": 1}, {"name": "a", "radiance_rgb": 2}]}"#);
    assert!(e.contains("'a'") && e.contains("twice"), "{e}");
}

#[test]
fn a_folder_or_a_missing_file_says_which() {
    let tmp = temp_dir("lights-dir");
    let dir = tmp.path();
    let e = LightsFile::read(dir).unwrap_err().to_string();
    assert!(e.contains("is a directory") && e.contains("lights file"), "{e}");
    let e = LightsFile::read(&dir.join("nope.json")).unwrap_err().to_string();
    assert!(e.contains("not found"), "{e}");
}

#[test]
fn truth_is_read_only_when_asked_for() {
    let tmp = temp_dir("lights-truth");
    let dir = tmp.path();
    write_scene(dir);
    std::fs::create_dir_all(dir.join("truth")).unwrap();
    std::fs::write(
        dir.join("truth/truth.json"),
        r#"{"lights": [{"name": "lamp", "mesh": "x", "radiance_rgb": [7, 8, 9], "relit_radiance_rgb": [1, 1, 1]}]}"#,
    )
    .unwrap();
    let scene = Scene::load(dir).unwrap();
    let mut w = Vec::new();
    let default = LightRadiances::resolve(&scene, &LightsSource::Default, &mut w).unwrap();
    assert_eq!(default.lights, vec![[1.0; 3]]);
    assert!(w.iter().any(|m| m.contains("unit radiance")), "the default is announced: {w:?}");
    let truth = LightRadiances::resolve(&scene, &LightsSource::Truth, &mut w).unwrap();
    assert_eq!(truth.lights, vec![[7.0, 8.0, 9.0]]);
    assert_eq!(LightsSource::from_arg(Some(Path::new("truth"))), LightsSource::Truth);
    assert_eq!(LightsSource::from_arg(None), LightsSource::Default);
    assert_eq!(LightsSource::from_arg(Some(Path::new("./truth"))), LightsSource::File("./truth".into()));
}
