//! A real fit output, made once by `psc fit` on the bundled example room (every observed part
//! forced to the homogeneous graph, few iterations, small maps: seconds, not minutes), then:
//! `psc report` writes a page a headless Chromium opens with every image decoded and nothing
//! loaded from outside; `psc render <fit>` renders it from a camera; `--set` of a colour changes
//! that part's pixels in the expected direction and leaves the others; bad edits fail cleanly.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use std::sync::OnceLock;

#[path = "../../tests/src/not_run.rs"]
mod not_run;

fn repo() -> PathBuf {
    let here = Path::new(env!("CARGO_MANIFEST_DIR"));
    here.parent().unwrap_or(here).to_path_buf()
}

fn scratch() -> PathBuf {
    std::env::temp_dir().join(format!("psc-fitted-room-{}", std::process::id()))
}

fn psc(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_psc")).args(args).output().expect("psc runs")
}

fn text(o: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&o.stdout), String::from_utf8_lossy(&o.stderr))
}

/// The parts of the example room its label image shows, each forced to `homogeneous`.
const OBSERVED: [&str; 7] =
    ["floor", "ceiling", "walls", "rug", "crate_crate", "barrel_barrelRing", "barrel_barrelS_D"];

/// Scratch folders of earlier runs whose process has ended (the shared fit output outlives the
/// tests that use it, so each run clears its predecessors'; Linux only, where `/proc` tells).
fn remove_stale_scratch() {
    let Ok(entries) = std::fs::read_dir(std::env::temp_dir()) else { return };
    for e in entries.flatten() {
        let name = e.file_name().to_string_lossy().to_string();
        let Some(pid) = name.strip_prefix("psc-fitted-room-").and_then(|p| p.parse::<u32>().ok()) else { continue };
        if pid != std::process::id() && Path::new("/proc/self").exists() && !Path::new(&format!("/proc/{pid}")).exists()
        {
            let _ = std::fs::remove_dir_all(e.path());
        }
    }
}

/// The fit output, made on first use.
fn fitted() -> &'static Path {
    static FIT: OnceLock<PathBuf> = OnceLock::new();
    FIT.get_or_init(|| {
        remove_stale_scratch();
        let out = scratch().join("fit");
        let _ = std::fs::remove_dir_all(&out);
        let scene = repo().join("examples/room");
        let mut args: Vec<String> =
            ["fit", scene.to_str().unwrap(), "--out", out.to_str().unwrap()].iter().map(|s| s.to_string()).collect();
        for p in OBSERVED {
            args.extend(["--graph".into(), format!("{p}=homogeneous")]);
        }
        args.extend(
            ["--iterations", "20", "--texture-size", "32", "--render-spp", "4", "--refit-rounds", "0", "--quiet"]
                .map(String::from),
        );
        let o = Command::new(env!("CARGO_BIN_EXE_psc")).args(&args).output().expect("psc runs");
        assert!(o.status.success(), "psc fit failed: {}", text(&o));
        out
    })
}

#[test]
fn report_of_a_real_fit_is_self_contained() {
    let fit = fitted();
    // The page `psc fit` wrote (in its staging folder, renamed into place afterwards) names the
    // output folder, never the staging one.
    let written_by_fit = std::fs::read_to_string(fit.join("report.html")).unwrap();
    let out_name = fit.file_name().unwrap().to_str().unwrap();
    assert!(written_by_fit.contains(&format!("<title>photoscene fit: {out_name}</title>")));
    assert!(!written_by_fit.contains(".psc-tmp"), "the report names the staging folder");
    let o = psc(&["report", fit.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let html = std::fs::read_to_string(fit.join("report.html")).unwrap();
    let result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fit.join("result.json")).unwrap()).unwrap();
    for part in result["parts"].as_array().unwrap() {
        let name = part["name"].as_str().unwrap();
        assert!(html.contains(&format!("id=\"part-{name}\"")), "no section for {name}");
    }
    // Every image a PNG data URI; photo, render and difference of the one view at least.
    let srcs: Vec<&str> = html.split("src=\"").skip(1).map(|s| &s[..s.find('"').unwrap()]).collect();
    assert!(srcs.len() >= 3 + OBSERVED.len(), "{} images", srcs.len());
    assert!(srcs.iter().all(|s| s.starts_with("data:image/png;base64,")));
    for rest in html.split("href=\"").skip(1) {
        assert!(rest.starts_with('#'), "href=\"{}", &rest[..40.min(rest.len())]);
    }
    assert!(!html.contains("not available (the scene"), "the scene was found");
    in_chromium(&fit.join("report.html"), srcs.len());
}

/// Opens the page in headless Chromium and reads back what its inline script recorded: every
/// image's decoded width, broken images, resources loaded from outside.
fn in_chromium(page: &Path, images: usize) {
    let Some(browser) = ["chromium", "chromium-browser", "google-chrome"]
        .into_iter()
        .find(|b| Command::new(b).arg("--version").output().is_ok_and(|o| o.status.success()))
    else {
        let message = "the headless-browser check of report.html (no chromium installed; `apt-get install chromium`)";
        not_run::say_skipped(message);
        if std::env::var_os("CI").is_some() && std::env::var_os("PSC_CHROMIUM_INSTALL_FAILED").is_none() {
            panic!("{message}, and CI is set while .ci/run reported no failed install");
        }
        return;
    };
    let profile = scratch().join("chromium-profile");
    let url = format!("file://{}", page.canonicalize().unwrap().display());
    let o = Command::new(browser)
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--disable-background-networking",
            "--disable-component-update",
            "--no-first-run",
            "--disable-sync",
            &format!("--user-data-dir={}", profile.display()),
            "--virtual-time-budget=5000",
            "--dump-dom",
            &url,
        ])
        .output()
        .expect("chromium runs");
    let dom = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success() && dom.contains("<body"), "chromium failed: {}", String::from_utf8_lossy(&o.stderr));
    let attr = |name: &str| -> Option<String> {
        let at = dom.find(&format!("{name}=\""))? + name.len() + 2;
        Some(dom[at..at + dom[at..].find('"')?].to_string())
    };
    assert_eq!(attr("data-images").as_deref(), Some(images.to_string().as_str()), "the check script did not run");
    assert_eq!(attr("data-broken-images").as_deref(), Some("0"));
    assert_eq!(attr("data-external-resources").as_deref(), Some("0"));
    let widths: Vec<&str> = dom.split("data-natural-width=\"").skip(1).map(|s| &s[..s.find('"').unwrap()]).collect();
    assert_eq!(widths.len(), images);
    assert!(widths.iter().all(|w| w.parse::<u32>().is_ok_and(|w| w > 0)), "{widths:?}");
}

#[test]
fn report_refuses_a_folder_that_is_not_a_fit_output() {
    let o = psc(&["report", repo().join("examples/room").to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("not a `psc fit` output folder"), "{}", text(&o));
}

/// Mean linear RGB per part id of an EXR render, with the G-buffer's part ids.
fn part_means(image: &Path, gbuffer: &Path) -> std::collections::BTreeMap<String, ([f64; 3], usize)> {
    let img = psc_render::image_io::read_rgb(image, false).unwrap();
    let (_, _, ids) = psc_render::image_io::read_labels(&gbuffer.join("part_id.png")).unwrap();
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(gbuffer.join("gbuffer.json")).unwrap()).unwrap();
    let mut out = std::collections::BTreeMap::new();
    for (px, id) in img.data.iter().zip(&ids) {
        let Some(name) = index["part_ids"][id.to_string()].as_str() else { continue };
        let e = out.entry(name.to_string()).or_insert(([0.0; 3], 0));
        for (sum, v) in e.0.iter_mut().zip(px) {
            *sum += *v as f64;
        }
        e.1 += 1;
    }
    for (sum, n) in out.values_mut() {
        *sum = sum.map(|s| s / *n as f64);
    }
    out
}

#[test]
fn render_a_fit_output_from_a_camera_and_edit_a_colour() {
    let fit = fitted();
    let dir = scratch().join("render");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let camera = dir.join("cam.json");
    std::fs::write(
        &camera,
        r#"{"position": [2.8, 1.4, 4.5], "look_at": [1.9, 0.6, 1.3], "up": [0, 1, 0], "fov_y_deg": 60, "width": 64, "height": 48}"#,
    )
    .unwrap();
    let fit_s = fit.to_str().unwrap();
    let cam_s = camera.to_str().unwrap();
    // Direct light only, so that another part's pixels cannot see the edited one.
    let common = ["--camera", cam_s, "--spp", "8", "--max-depth", "2", "--quiet"];
    let render = |out: &Path, extra: &[&str]| {
        let mut args = vec!["render", fit_s, "--out", out.to_str().unwrap()];
        args.extend_from_slice(&common);
        args.extend_from_slice(extra);
        let o = psc(&args);
        assert!(o.status.success(), "{:?}: {}", extra, text(&o));
    };
    let base = dir.join("base.exr");
    render(&base, &[]);
    let gbuffer = dir.join("gbuffer");
    render(&gbuffer, &["--gbuffer"]);
    // The fitted floor, made red.
    let edited = dir.join("edited.exr");
    render(&edited, &["--set", "floor.albedo_color=0.9,0.05,0.05", "--set", "floor.albedo_scale=1"]);
    let before = part_means(&base, &gbuffer);
    let after = part_means(&edited, &gbuffer);
    let (floor_before, floor_after) = (before["floor"].0, after["floor"].0);
    assert!(before["floor"].1 > 50, "the camera sees the floor: {before:?}");
    let fitted_colour: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fit.join("materials.json")).unwrap()).unwrap();
    let part = &fitted_colour["parts"]["floor"];
    let was: Vec<f64> = (0..3)
        .map(|c| part["params"]["albedo_color"][c].as_f64().unwrap() * part["albedo_scale"][c].as_f64().unwrap())
        .collect();
    // Each channel moves the way the albedo moved (red up to 0.9, green and blue down to 0.05).
    for (c, target) in [0.9, 0.05, 0.05].iter().enumerate() {
        let change = floor_after[c] - floor_before[c];
        assert!(
            (target - was[c]).signum() == change.signum() && change.abs() > 1e-4,
            "channel {c}: albedo {} → {target}, floor mean {} → {}",
            was[c],
            floor_before[c],
            floor_after[c]
        );
    }
    // Pixels away from the floor (no floor in their 3×3 neighbourhood, so no sample of theirs
    // hits it) do not change at all: with direct light only they never see it.
    let (a, b) = (
        psc_render::image_io::read_rgb(&base, false).unwrap(),
        psc_render::image_io::read_rgb(&edited, false).unwrap(),
    );
    let (w, h, ids) = psc_render::image_io::read_labels(&gbuffer.join("part_id.png")).unwrap();
    let index: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(gbuffer.join("gbuffer.json")).unwrap()).unwrap();
    let floor_id: u16 =
        index["part_ids"].as_object().unwrap().iter().find(|(_, n)| *n == "floor").unwrap().0.parse().unwrap();
    let (mut away, mut changed) = (0, 0);
    for y in 1..h - 1 {
        for x in 1..w - 1 {
            let near_floor = (y - 1..=y + 1).any(|yy| (x - 1..=x + 1).any(|xx| ids[yy * w + xx] == floor_id));
            if !near_floor {
                away += 1;
                let i = y * w + x;
                if (0..3).any(|c| (a.data[i][c] - b.data[i][c]).abs() > 1e-6 * (1.0 + a.data[i][c].abs())) {
                    changed += 1;
                }
            }
        }
    }
    assert!(away > 200, "{away} pixels away from the floor");
    assert_eq!(changed, 0, "{changed} of {away} pixels away from the floor changed");
    // --lights relights: double radiance, about double the image.
    let lights: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fit.join("lights.json")).unwrap()).unwrap();
    let mut brighter = lights.clone();
    for l in brighter["lights"].as_array_mut().unwrap() {
        let r: Vec<f64> = l["radiance_rgb"].as_array().unwrap().iter().map(|x| 2.0 * x.as_f64().unwrap()).collect();
        l["radiance_rgb"] = serde_json::json!(r);
    }
    let lights_file = dir.join("brighter.json");
    std::fs::write(&lights_file, brighter.to_string()).unwrap();
    let relit = dir.join("relit.exr");
    render(&relit, &["--lights", lights_file.to_str().unwrap()]);
    let (b, r) = (part_means(&base, &gbuffer), part_means(&relit, &gbuffer));
    let ratio = (r["walls"].0[1] + 1e-9) / (b["walls"].0[1] + 1e-9);
    assert!((ratio - 2.0).abs() < 0.05, "walls twice as bright under twice the radiance: {ratio}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn bad_edits_fail_cleanly_and_say_what_exists() {
    let fit = fitted();
    let out = scratch().join("never.png");
    let run = |set: &str| {
        let o = psc(&[
            "render",
            fit.to_str().unwrap(),
            "--spp",
            "1",
            "--size",
            "8x6",
            "--set",
            set,
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(o.status.code(), Some(1), "--set {set}: {}", text(&o));
        assert!(!out.exists(), "--set {set} wrote an image");
        text(&o)
    };
    let e = run("flor.albedo_color=1,0,0");
    assert!(e.contains("no part is named `flor`") && e.contains("floor") && e.contains("walls"), "{e}");
    let e = run("floor.colour=1,0,0");
    assert!(
        e.contains("no parameter `colour`") && e.contains("albedo_color") && e.contains("rough (number in [0.02, 1])"),
        "{e}"
    );
    assert!(e.contains("albedo_scale"), "the scale targets are listed: {e}");
    let e = run("floor.rough=2");
    assert!(e.contains("outside its range [0.02, 1]"), "{e}");
    let e = run("floor.albedo_color=1,0");
    assert!(e.contains("takes 3 value(s), got 2"), "{e}");
    let e = run("floor.rough=abc");
    assert!(e.contains("`abc` is not a number"), "{e}");
    let e = run("floor.albedo_scale=-1");
    assert!(e.contains("negative"), "{e}");
    let e = run("floor");
    assert!(e.contains("no `=`"), "{e}");
    // On a plain scene without --assign there is nothing to edit: a usage error.
    let o = psc(&[
        "render",
        repo().join("examples/room").to_str().unwrap(),
        "--set",
        "floor.rough=0.5",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
}

/// A copy of the fit output's files that rendering reads, with `result.json`'s view exposures
/// replaced by `exposure` (the example room has one view, whose solved exposure is exactly 1).
fn fit_with_exposure(dir: &Path, exposure: serde_json::Value) -> PathBuf {
    let copy = dir.join("fit");
    std::fs::create_dir_all(&copy).unwrap();
    for f in ["materials.json", "lights.json"] {
        std::fs::copy(fitted().join(f), copy.join(f)).unwrap();
    }
    let mut result: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(fitted().join("result.json")).unwrap()).unwrap();
    result["lights"]["exposure_rgb"] = exposure;
    std::fs::write(copy.join("result.json"), result.to_string()).unwrap();
    copy
}

#[test]
fn an_input_view_renders_at_the_fits_exposure_and_a_camera_file_does_not() {
    let dir = scratch().join("exposure");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let exposure = [1.6f32, 1.0, 0.5];
    let fit = fit_with_exposure(&dir, serde_json::json!({ "view0": exposure }));
    let render = |fit: &Path, out: &Path, camera: &[&str]| {
        let mut args = vec!["render", fit.to_str().unwrap(), "--out", out.to_str().unwrap()];
        args.extend_from_slice(camera);
        args.extend_from_slice(&["--size", "40x30", "--spp", "2", "--quiet"]);
        psc(&args)
    };
    let (unit, exposed) = (dir.join("unit.exr"), dir.join("exposed.exr"));
    let o = render(fitted(), &unit, &["--view", "view0"]);
    assert!(o.status.success(), "{}", text(&o));
    let o = render(&fit, &exposed, &["--view", "view0"]);
    assert!(o.status.success(), "{}", text(&o));
    let (a, b) = (
        psc_render::image_io::read_rgb(&unit, false).unwrap(),
        psc_render::image_io::read_rgb(&exposed, false).unwrap(),
    );
    let lit = a.data.iter().filter(|p| p[1] > 1e-3).count();
    assert!(lit > 100, "the view sees lit surfaces: {lit} pixels");
    for (p, q) in a.data.iter().zip(&b.data) {
        for c in 0..3 {
            let want = p[c] * exposure[c];
            assert!(
                (q[c] - want).abs() <= 1e-6 * (1.0 + want.abs()),
                "channel {c}: {} × {} ≠ {}",
                p[c],
                exposure[c],
                q[c]
            );
        }
    }
    // The same camera from a file is not the photo's: no exposure.
    let camera = dir.join("cam.json");
    let scene: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(repo().join("examples/room/scene.json")).unwrap()).unwrap();
    std::fs::write(&camera, scene["views"][0]["camera"].to_string()).unwrap();
    let from_file = dir.join("file.exr");
    let o = render(&fit, &from_file, &["--camera", camera.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let c = psc_render::image_io::read_rgb(&from_file, false).unwrap();
    assert_eq!(a.data, c.data, "a camera file renders at exposure 1");
    // An exposure that is not three positive numbers is refused before rendering.
    let bad = fit_with_exposure(&dir.join("bad"), serde_json::json!({ "view0": [1.0, -2.0, 1.0] }));
    let o = render(&bad, &dir.join("bad.exr"), &["--view", "view0"]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("exposure_rgb") && text(&o).contains("view0"), "{}", text(&o));
    assert!(!dir.join("bad.exr").exists());
    let _ = std::fs::remove_dir_all(&dir);
}
