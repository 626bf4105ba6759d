//! The report of a hand-made fit folder over the bundled example room (its photo and labels):
//! every part gets a section, every image is a `data:` URI that decodes, pieces the folder lacks
//! are said to be "not available", the page names the folder it is shown as, and a folder that
//! is not a fit output is refused.

use std::path::{Path, PathBuf};

use psc_report::{write_report, write_report_with, ReportError, ReportOptions};
use serde_json::json;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap().to_path_buf()
}

fn temp(name: &str) -> tempfile::TempDir {
    tempfile::Builder::new().prefix(&format!("psc-report-{name}-")).tempdir().unwrap()
}

fn write(path: &Path, v: &serde_json::Value) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    std::fs::write(path, serde_json::to_string_pretty(v).unwrap()).unwrap();
}

fn png(path: &Path, w: u32, h: u32, f: impl Fn(u32, u32) -> [u8; 3]) {
    std::fs::create_dir_all(path.parent().unwrap()).unwrap();
    image::RgbImage::from_fn(w, h, |x, y| image::Rgb(f(x, y))).save(path).unwrap();
}

/// A fit folder naming the example room; `floor` has everything, `walls` has no part file and
/// no maps, `ghost` is not in the scene.
fn fit_folder(dir: &Path) {
    let scene = repo().join("examples/room");
    write(
        &dir.join("result.json"),
        &json!({
            "format": "photoscene-fit/1", "version": "0.1.0", "command": "psc fit examples/room <&>",
            "scene": scene.display().to_string(),
            "lights": {"source": "solved", "slots": ["ceiling0"], "radiance_rgb": [[5, 5, 5]],
                       "exposure_rgb": {"view0": [1.25, 1.0, 0.8], "view1": [0.8, 1.0, 1.25]},
                       "solve_rounds": [{"change": 0.5, "solve": {"radiance": [[4, 4, 4]], "share": [0.75], "pixels": 900,
                                                                   "relative_rms": [0.1, 0.1, 0.1], "outliers": 0.05}}]},
            "parts": [
                {"name": "floor", "status": "fitted", "graph": "oak_planks", "loss": 0.01, "view": "view0"},
                {"name": "walls", "status": "fitted", "graph": "painted_wall", "loss": 0.02, "view": "view0"},
                {"name": "ghost", "status": "unobserved", "graph": "homogeneous", "loss": 0.0, "view": null}
            ],
            "renders": ["renders/view0.png", "renders/view0_beside_photo.png"],
            "timings_s": {"fit parts": 1.5}
        }),
    );
    write(
        &dir.join("parts/floor.json"),
        &json!({"name": "floor", "status": "fitted", "graph": "oak_planks",
                "top": [{"graph": "walnut", "votes": 3.0, "best_loss": 0.1}, {"graph": "oak_planks", "votes": 2.0, "best_loss": 0.05}],
                "flat_check": {"contest_winner": "oak_planks", "contest_loss": 0.01, "flat_loss": 0.03},
                "loss": {"total": 0.01}, "loss_curve": [0.5, 0.2, 0.1, 0.01], "iterations": 3,
                "pixels": {"fitted": 100, "usable": 120}}),
    );
    write(
        &dir.join("materials.json"),
        &json!({"parts": {
            "floor": {"graph": "oak_planks", "params": {"rows": 8, "light": [0.6, 0.4, 0.2]}, "albedo_scale": [1, 1, 1]},
            "walls": {"graph": "painted_wall"},
            "ghost": {"graph": "homogeneous"}}}),
    );
    write(&dir.join("lights.json"), &json!({"lights": [{"name": "ceiling0", "radiance_rgb": [5, 5, 5]}]}));
    for map in ["albedo", "normal", "roughness"] {
        png(&dir.join(format!("parts/floor/material_{map}.png")), 300, 300, |x, y| [x as u8, y as u8, 90]);
    }
    let photo = image::open(scene.join("views/view0.png")).unwrap().to_rgb8();
    png(&dir.join("renders/view0.png"), photo.width(), photo.height(), |x, y| {
        let p = photo.get_pixel(x, y);
        [p[0].saturating_add(20), p[1], p[2]]
    });
}

/// Every `src="…"` of the page.
fn sources(html: &str) -> Vec<&str> {
    html.split("src=\"").skip(1).map(|s| &s[..s.find('"').unwrap()]).collect()
}

#[test]
fn every_part_has_a_section_and_every_image_is_inline() {
    let tmp = temp("synthetic");
    let dir = tmp.path();
    fit_folder(dir);
    let path = write_report(dir).unwrap();
    assert_eq!(path, dir.join("report.html"));
    let html = std::fs::read_to_string(&path).unwrap();
    for part in ["floor", "walls", "ghost"] {
        assert!(html.contains(&format!("<section class=\"part\" id=\"part-{part}\">")), "{part}");
        assert!(html.contains(&format!("href=\"#part-{part}\"")), "{part} in the contents");
    }
    let srcs = sources(&html);
    // photo, render, difference; floor's two crops and three maps; walls' two crops.
    assert_eq!(srcs.len(), 3 + 5 + 2, "{srcs:?}");
    for s in &srcs {
        let b64 = s.strip_prefix("data:image/png;base64,").expect("a PNG data URI");
        let bytes = decode_base64(b64);
        let img = image::load_from_memory(&bytes).expect("decodes");
        assert!(img.width() > 0 && img.height() > 0);
    }
    // Maps are thumbnails, not the 300² originals.
    assert!(html.contains("albedo (300²)"));
    // The difference of a render up to 20 levels brighter in red, averaged over the channels.
    let photo = image::open(repo().join("examples/room/views/view0.png")).unwrap().to_rgb8();
    let raised: u64 = photo.pixels().map(|p| (p[0].saturating_add(20) - p[0]) as u64).sum();
    let mean = raised as f64 / (3.0 * 255.0 * (photo.width() * photo.height()) as f64);
    assert!((0.01..0.1).contains(&mean), "{mean}");
    let said = format!("mean {mean:.5} of full scale");
    assert!(html.contains(&said), "{said} not in {}", &html[html.find("mean ").unwrap()..][..60]);
    // What is missing is said, and text from files is escaped.
    assert!(html.contains("Selection: not available"));
    assert!(html.contains("Baked albedo: not available"));
    assert!(html.contains("Crop: not available (the part was not fitted in any view)"));
    assert!(html.contains("Evaluation (run `psc eval` on a scene with truth/): not available"));
    assert!(html.contains("psc fit examples/room &lt;&amp;&gt;"));
    // The chosen graph is marked among the alternatives, shares and fitted colours shown.
    assert!(html.contains("oak_planks ✔"));
    assert!(html.contains("A flat colour fitted to the same pixels ended at loss 0.03000, above the winner's 0.01000."));
    assert!(html.contains("<th>share</th>") && html.contains("<td>0.7500</td>"), "the last solve's share");
    assert!(html.contains("<td>900</td>"), "the solve rounds' table");
    assert!(html.contains("<td>view1</td><td>[0.8000, 1.000, 1.250]</td>"), "the per-view exposures");
    assert!(html.contains("<code>light</code>"));
    // Nothing but data: URIs and anchors is referenced, and a CSP forbids anything else.
    assert!(html.contains("default-src 'none'; img-src data:"));
    for attr in ["href=\"", "url("] {
        for rest in html.split(attr).skip(1) {
            assert!(rest.starts_with('#') || rest.starts_with("data:"), "{attr}{}", &rest[..40.min(rest.len())]);
        }
    }
    assert!(!html.contains("http://") && !html.contains("https://"));
}

#[test]
fn a_missing_scene_leaves_the_photos_out_and_says_why() {
    let tmp = temp("noscene");
    let dir = tmp.path();
    fit_folder(dir);
    let elsewhere = dir.join("no-such-scene");
    let html = std::fs::read_to_string(
        write_report_with(dir, &ReportOptions { scene: Some(elsewhere.clone()), ..Default::default() }).unwrap(),
    )
    .unwrap();
    assert!(html.contains("Photos and part labels: not available"));
    assert!(html.contains("Photo: not available"));
    // The render is still there; no crop can be made.
    assert_eq!(sources(&html).len(), 1 + 3);
}

/// A flat colour that ended below the contest's winner replaced it: the page says so, and by
/// how much, rather than showing a choice from outside the table.
#[test]
fn a_flat_colour_kept_over_the_contests_winner_is_explained() {
    let tmp = temp("flatkept");
    let dir = tmp.path();
    fit_folder(dir);
    let floor = dir.join("parts/floor.json");
    let mut detail: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&floor).unwrap()).unwrap();
    detail["graph"] = json!("homogeneous");
    detail["flat_check"] = json!({"contest_winner": "oak_planks", "contest_loss": 0.02, "flat_loss": 0.015});
    write(&floor, &detail);
    let mut result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("result.json")).unwrap()).unwrap();
    result["parts"][0]["graph"] = json!("homogeneous");
    write(&dir.join("result.json"), &result);
    let html = std::fs::read_to_string(write_report(dir).unwrap()).unwrap();
    let said = "Chosen: <b>homogeneous</b>: a flat colour fitted to the same pixels ended below the contest's \
                winner, <b>oak_planks</b> (loss 0.01500 against 0.02000).";
    assert!(html.contains(said), "{}", &html[html.find("Graph selection").unwrap()..][..1200]);
    assert!(!html.contains("not among the alternatives"));
}

#[test]
fn the_evaluation_shows_its_rows_ratios_and_the_floor_of_unseen_parts() {
    let tmp = temp("eval");
    let dir = tmp.path();
    fit_folder(dir);
    let row = |method: &str, contrast: f64| {
        json!({"geometry": "truth", "views": "novel", "method": method, "images": 2, "parts": 5,
               "rmse": 0.05, "ssim": 0.6, "mean_colour": 0.02, "colour_w1": 0.02, "contrast_w1": contrast})
    };
    let eval = json!({
        "format": "photoscene-eval/1",
        "rows": [row("fitted", 0.0076), row("pixel median", 0.01)],
        "ratios": [{"geometry": "truth", "views": "novel", "numerator": "fitted", "denominator": "pixel median",
                    "rmse": 1.0, "one_minus_ssim": 1.0, "mean_colour": 1.0, "colour_w1": 1.0, "contrast_w1": 0.76}],
        "unseen_floors": [{"geometry": "truth", "views": "novel", "rmse": 0.36, "mean_colour": 0.32,
                           "colour_w1": 0.29, "contrast_w1": 0.65}],
    });
    write(&dir.join("eval/eval.json"), &eval);
    let html = std::fs::read_to_string(write_report(dir).unwrap()).unwrap();
    let at = html.find("<h2 id=\"evaluation\">").expect("an evaluation section");
    let section = &html[at..];
    assert!(section.contains("<td>fitted / pixel median</td>") && section.contains("<td>0.7600</td>"), "{section}");
    let floor = section.find("Floor of the parts no input view shows").expect("the floor is explained");
    assert!(section[floor..].contains("<td>0.6500</td>"), "{}", &section[floor..]);
    // Without floors in the JSON (no unseen part), the page says nothing about them.
    let mut plain = eval;
    plain["unseen_floors"] = json!([]);
    write(&dir.join("eval/eval.json"), &plain);
    let html = std::fs::read_to_string(write_report(dir).unwrap()).unwrap();
    assert!(!html.contains("Floor of the parts no input view shows"));
}

/// `psc fit` writes the report into its staging folder before renaming it into place: the page
/// must name the folder the user will find, and say which files are missing by their path
/// within it, so that nothing on it names the staging folder.
#[test]
fn the_page_names_the_folder_it_is_shown_as() {
    let tmp = temp("staged");
    let dir = tmp.path().join(".staging-of-fitted");
    fit_folder(&dir);
    let shown_as = tmp.path().join("fitted");
    let options = ReportOptions { shown_as: Some(shown_as.clone()), ..Default::default() };
    let html = std::fs::read_to_string(write_report_with(&dir, &options).unwrap()).unwrap();
    assert!(html.contains("<title>photoscene fit: fitted</title>"), "{}", &html[..400]);
    assert!(html.contains(&shown_as.display().to_string()));
    assert!(!html.contains(".staging-of-fitted"), "the staging folder is named");
    assert!(html.contains("eval/eval.json does not exist"), "a missing file is named within the folder");
    // Without the option the page names the folder it was read from.
    let html = std::fs::read_to_string(write_report(&dir).unwrap()).unwrap();
    assert!(html.contains("<title>photoscene fit: .staging-of-fitted</title>"));
}

#[test]
fn a_folder_that_is_not_a_fit_output_is_refused() {
    let tmp = temp("notfit");
    let dir = tmp.path();
    match write_report(dir) {
        Err(ReportError::NotAFitOutput { reason, .. }) => assert!(reason.contains("result.json"), "{reason}"),
        other => panic!("{other:?}"),
    }
    write(&dir.join("result.json"), &json!({"format": "photoscene-eval/1"}));
    let e = write_report(dir).unwrap_err().to_string();
    assert!(e.contains("not a `psc fit` output folder") && e.contains("photoscene-eval/1"), "{e}");
    std::fs::write(dir.join("result.json"), "{ not json").unwrap();
    assert!(matches!(write_report(dir), Err(ReportError::Input { .. })));
    assert!(!dir.join("report.html").exists());
}

/// A base64 decoder written separately from the encoder, so a wrong encoder cannot pass.
fn decode_base64(text: &str) -> Vec<u8> {
    let value = |c: u8| match c {
        b'A'..=b'Z' => c - b'A',
        b'a'..=b'z' => c - b'a' + 26,
        b'0'..=b'9' => c - b'0' + 52,
        b'+' => 62,
        b'/' => 63,
        _ => panic!("not base64: {c}"),
    };
    let bytes: Vec<u8> = text.bytes().filter(|&c| c != b'=').collect();
    let mut out = Vec::new();
    for chunk in bytes.chunks(4) {
        let mut n = 0u32;
        for (i, &c) in chunk.iter().enumerate() {
            n |= (value(c) as u32) << (18 - 6 * i);
        }
        out.extend_from_slice(&n.to_be_bytes()[1..chunk.len()]);
    }
    out
}

/// JSON files of the folder that an editor saved with a byte-order mark are read as without
/// one: the page is the same.
#[test]
fn files_saved_with_a_byte_order_mark_read_the_same() {
    let tmp = temp("bom");
    let (plain, marked) = (tmp.path().join("fitted"), tmp.path().join("marked"));
    fit_folder(&plain);
    fit_folder(&marked);
    for file in ["result.json", "parts/floor.json", "materials.json", "lights.json"] {
        let text = std::fs::read(marked.join(file)).unwrap();
        std::fs::write(marked.join(file), [b"\xEF\xBB\xBF".as_slice(), &text].concat()).unwrap();
    }
    let page = |dir: &Path| {
        let options = ReportOptions { shown_as: Some(tmp.path().join("shown")), ..Default::default() };
        std::fs::read_to_string(write_report_with(dir, &options).unwrap()).unwrap()
    };
    assert_eq!(page(&marked), page(&plain));
}
