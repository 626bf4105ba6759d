//! `--set` edits of an assignment (`psc_runtime::edit`) against a one-graph library: each kind of
//! target lands where the renderer reads it, and every bad edit is refused with a message that
//! says what exists, leaving the assignment unchanged.

use psc_runtime::assign::{Assignment, PartMaterial};
use psc_runtime::edit::{apply_edits, Edit};
use psc_runtime::library::Library;
use serde_json::json;

const GRAPH: &str = "
/// A test graph with one parameter of each kind.
graph tinted {
    category plaster
    param tint = srgb(0.5, 0.5, 0.5)
    param freq = 4.0 in [1, 32]
    param rows = 3 in [1, 8] int
    output albedo = tint
    output roughness = 0.5
    output height = 0.0
}
";

fn library() -> Library {
    // The library is loaded whole, so its folder can go as soon as it is read.
    let dir = tempfile::Builder::new().prefix("psc-edit-lib-").tempdir().unwrap();
    std::fs::write(dir.path().join("tinted.psg"), GRAPH).unwrap();
    Library::load(dir.path()).unwrap()
}

fn assignment() -> Assignment {
    let mut a = Assignment::default();
    a.parts.insert("floor".into(), PartMaterial::new("tinted"));
    a.parts.insert("walls.north".into(), PartMaterial::new("tinted"));
    a
}

fn edit(text: &str) -> Edit {
    Edit::parse(text).unwrap()
}

#[test]
fn every_target_lands_in_the_assignment() {
    let lib = library();
    let edits = [
        "floor.tint=0.9,0.1,0.2",
        "floor.freq=30",
        "floor.rows=5",
        "floor.albedo_scale=0.8,0.8,0.9",
        "floor.roughness_scale=0.5",
        "floor.uv.rotation=45",
        "floor.uv.offset=0.25,0.5",
        "walls.north.uv.log_scale=2",
        "walls.north.albedo_scale=0.5",
    ]
    .map(edit);
    let out = apply_edits(&assignment(), &edits, &lib).unwrap();
    let f = &out.parts["floor"];
    assert_eq!(f.params["tint"], json!([0.9, 0.1, 0.2]));
    assert_eq!(f.params["freq"], json!(30.0));
    assert_eq!(f.params["rows"], json!(5));
    assert_eq!(f.albedo_scale, [0.8, 0.8, 0.9]);
    assert_eq!(f.roughness_scale, 0.5);
    assert_eq!(f.uv.rotation_deg, 45.0);
    assert_eq!(f.uv.offset, [0.25, 0.5]);
    // A part whose name has a dot; log-scale k is the fit's 1.5^k.
    let w = &out.parts["walls.north"];
    assert_eq!(w.uv.scale, [2.25, 2.25]);
    assert_eq!(w.albedo_scale, [0.5; 3]);
    // The edited assignment binds: the values are valid for the graph.
    let (_, params) = f.resolve(&lib).unwrap();
    assert_eq!(params, vec![0.9, 0.1, 0.2, 30.0, 5.0]);
}

#[test]
fn bad_edits_say_what_exists_and_change_nothing() {
    let lib = library();
    let cases = [
        ("flor.tint=1,0,0", "no part is named `flor` (parts: floor, walls.north)"),
        ("floor.tnt=1,0,0", "has no parameter `tnt`; it has: tint (colour"),
        ("floor.tnt=1", "freq (number in [1, 32]), rows (integer in [1, 8])"),
        ("floor.freq=40", "`freq` = 40 is outside its range [1, 32]"),
        ("floor.rows=2.5", "`rows` is an integer parameter"),
        ("floor.tint=1,0", "takes 3 value(s), got 2"),
        ("floor.tint=1.5,0,0", "outside its range [0, 1]"),
        ("floor.albedo_scale=1,-1,1", "negative channel"),
        ("floor.roughness_scale=-2", "is negative"),
        ("floor.uv.scale=0", "the scale 0e0 is outside the usable range (a scale of 0 maps the part to one texel)"),
        (
            "floor.uv.scale=1e-45",
            "the scale 1e-45 is outside the usable range: a uv scale's magnitude must be between 1e-4 and 1e4",
        ),
        ("floor.uv.log_scale=100", "is outside the usable range"),
        ("floor.uv.offset=1", "takes 2 value(s), got 1"),
    ];
    let before = assignment();
    for (text, expected) in cases {
        let mut a = before.clone();
        let e = edit(text).apply(&mut a, &lib).unwrap_err().to_string();
        assert!(e.contains(expected), "{text}: {e}");
        assert_eq!(a, before, "{text} changed the assignment");
    }
    // A later bad edit leaves the earlier good ones unapplied too.
    assert!(apply_edits(&before, &[edit("floor.freq=8"), edit("floor.freq=99")], &lib).is_err());
}

#[test]
fn malformed_edits_are_refused_when_parsed() {
    for (text, expected) in [
        ("floor", "no `=`"),
        ("floor=1", "part.param"),
        (".tint=1", "part.param"),
        ("floor.freq=abc", "`abc` is not a number"),
        ("floor.freq=1e99", "not a finite 32-bit number"),
        ("floor.freq=", "`` is not a number"),
    ] {
        let e = Edit::parse(text).unwrap_err().to_string();
        assert!(e.contains(expected), "{text}: {e}");
    }
    assert_eq!(
        Edit::parse(" floor.tint = 1, 0.5 ,0 ").unwrap(),
        Edit { key: "floor.tint".into(), values: vec![1.0, 0.5, 0.0] }
    );
}
