//! Assignment files: what is written reads back equal (and binds to the same parameter
//! vectors), the bundled example binds to its scene, and every kind of bad file is refused with
//! the file, the part and the field named.

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

use psc_base::SplitMix64;
use psc_render::material::MaterialBinding;
use psc_runtime::assign::{apply_assignment, Assignment, PartMaterial, UvTransform};
use psc_runtime::library::{default_library_root, Library};
use psc_runtime::params::ParamSpace;

fn library() -> &'static Library {
    static LIB: OnceLock<Library> = OnceLock::new();
    LIB.get_or_init(|| Library::load(&default_library_root()).unwrap_or_else(|e| panic!("{e}")))
}

fn scratch(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-assign-test-{name}-")).tempdir().unwrap()
}

fn example_room() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../examples/room")
}

#[test]
fn written_assignments_read_back_equal_with_the_same_parameters() {
    let lib = library();
    let mut rng = SplitMix64::new(11);
    let mut a = Assignment::default();
    for (k, m) in lib.materials.iter().enumerate() {
        let space = ParamSpace::new(&m.graph.info);
        let values = space.random(&mut rng);
        let mut part = PartMaterial::new(m.name()).with_param_values(&space, &values).unwrap();
        part.uv = UvTransform {
            scale: [0.5 + rng.next_f32(), 2.0 + rng.next_f32()],
            offset: [rng.next_f32(), -rng.next_f32()],
            rotation_deg: 360.0 * rng.next_f32(),
        };
        part.albedo_scale = [rng.next_f32(), 1.0, 1.5];
        part.roughness_scale = 0.25 + k as f32 / 7.0;
        a.parts.insert(format!("part{k}"), part);
    }
    let tmp = scratch("roundtrip");
    let dir = tmp.path();
    let path = dir.join("materials.json");
    std::fs::write(&path, a.to_json_string()).unwrap();
    let back = Assignment::read(&path).unwrap();
    assert_eq!(back, a);
    for (name, part) in &a.parts {
        let (m, values) = part.resolve(lib).unwrap();
        let (_, again) = back.parts[name].resolve(lib).unwrap();
        assert_eq!(values, again, "{name}");
        // And the vector is the one that was written.
        let space = ParamSpace::new(&m.graph.info);
        assert_eq!(PartMaterial::new(m.name()).with_param_values(&space, &values).unwrap().params, part.params);
    }
}

#[test]
fn the_bundled_example_binds_to_its_scene() {
    let room = example_room();
    let scene = psc_render::Scene::load(&room).unwrap();
    let mut bindings: Vec<MaterialBinding> = scene.mtl_materials(&mut Vec::new());
    apply_assignment(&room.join("materials.json"), library(), &scene.mesh.part_names, &mut bindings).unwrap();
    let a = Assignment::read(&room.join("materials.json")).unwrap();
    let floor = scene.mesh.part_names.iter().position(|p| p == "floor").unwrap();
    assert_eq!(a.parts["floor"].uv.scale, [2.0, 2.0], "a scalar uv_scale applies to both axes");
    assert_eq!(bindings[floor].uv_transform, [[2.0, 0.0, 0.0], [0.0, 2.0, 0.0]]);
    // The walls shade with painted_wall at its defaults.
    let walls = scene.mesh.part_names.iter().position(|p| p == "walls").unwrap();
    let m = library().get("painted_wall").unwrap();
    let want = m.kernel.eval(&m.graph.info.default_params(), &[0.3], &[0.7]).unwrap();
    let got = bindings[walls].material.eval([0.3, 0.7]);
    assert_eq!(got.albedo, [want[0][0], want[1][0], want[2][0]]);
}

#[test]
fn bad_files_name_the_file_part_and_field() {
    let tmp = scratch("bad");
    let dir = tmp.path();
    let part_names: Vec<String> = ["floor", "walls"].iter().map(|s| s.to_string()).collect();
    let cases: &[(&str, &str)] = &[
        ("{", "materials.json:1:1: EOF while parsing an object"),
        (r#"{"parts": {"floor": {"graph": "plaster"}, "floor": {"graph": "walnut"}}}"#, "\"floor\" appears twice"),
        (r#"[]"#, "expected an object {\"parts\": {...}}, found an array of 0 elements"),
        (r#"{"parts": {}, "lights": []}"#, "unknown field `lights` (expected one of: parts)"),
        (r#"{}"#, "the field `parts` is required"),
        (r#"{"parts": {"floor": {}}}"#, "part `floor`: the field `graph` is required"),
        (
            r#"{"parts": {"floor": {"graph": ["plaster"]}}}"#,
            "part `floor`: `graph`: expected the name of a library graph",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "scale": 2}}}"#,
            "part `floor`: unknown field `scale` (expected one of: graph, params",
        ),
        (r#"{"parts": {"floor": {"graph": "plaster", "uv_scale": 0}}}"#, "part `floor`: `uv_scale`: the scale 0e0"),
        // A subnormal, a scale beyond any use, either axis: refused with the value and the range.
        (
            r#"{"parts": {"floor": {"graph": "plaster", "uv_scale": 1e-45}}}"#,
            "part `floor`: `uv_scale`: the scale 1e-45 is outside the usable range: a uv scale's magnitude must be \
             between 1e-4 and 1e4",
        ),
        (r#"{"parts": {"floor": {"graph": "plaster", "uv_scale": [1, 2e4]}}}"#, "`uv_scale`: the scale 2e4 is outside"),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "uv_scale": [-5e-5, 1]}}}"#,
            "`uv_scale`: the scale -5e-5 is outside",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "uv_scale": "big"}}}"#,
            "`uv_scale`: expected a non-zero number or [su, sv], found a string \"big\"",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "uv_offset": [1, 2, 3]}}}"#,
            "`uv_offset`: expected [ou, ov], found an array of 3 elements",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "uv_rotation_deg": 1e39}}}"#,
            "`uv_rotation_deg`: 1e39 is beyond the largest 32-bit float",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "albedo_scale": [1, -1, 1]}}}"#,
            "`albedo_scale`: [1.0, -1.0, 1.0] has a negative channel",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "roughness_scale": -0.5}}}"#,
            "`roughness_scale`: -0.5 is negative",
        ),
        (
            r#"{"parts": {"floor": {"graph": "plaster", "params": [1]}}}"#,
            "`params`: expected an object of parameter name",
        ),
        // Checked against the library and the scene when bound:
        (
            r#"{"parts": {"flor": {"graph": "plaster"}}}"#,
            "part `flor`: the scene has no such part (parts: floor, walls)",
        ),
        (r#"{"parts": {"floor": {"graph": "plastr"}}}"#, "part `floor`: `graph`: no graph `plastr` in the library"),
        (
            r#"{"parts": {"floor": {"graph": "oak_planks", "params": {"rows": 99}}}}"#,
            "part `floor`: `params`: `rows` = 99 is outside its range [2, 16]",
        ),
        (
            r#"{"parts": {"floor": {"graph": "oak_planks", "params": {"row": 9}}}}"#,
            "`params`: graph `oak_planks` has no parameter `row`",
        ),
    ];
    for (text, want) in cases {
        let path = dir.join("materials.json");
        std::fs::write(&path, text).unwrap();
        let mut bindings = vec![MaterialBinding::constant([0.5; 3], 0.5); 2];
        let err = apply_assignment(&path, library(), &part_names, &mut bindings).expect_err(text).to_string();
        assert!(err.starts_with(&path.display().to_string()), "{text}: {err}");
        assert!(err.contains(want), "{text}:\n  {err}\nlacks\n  {want}");
        assert!(
            bindings.iter().all(|b| b.uv_transform == UvTransform::IDENTITY.matrix()),
            "{text}: a refused assignment changed a binding"
        );
    }
    let err = Assignment::read(dir).unwrap_err().to_string();
    assert!(err.contains("expected a JSON file, found a directory"), "{err}");
}
