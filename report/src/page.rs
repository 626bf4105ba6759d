//! The page: a table of contents, then the views, the parts, the lights, the evaluation and the
//! run, from a [`FitFolder`]. Pieces the folder lacks are said to be "not available".

use std::borrow::Cow;
use std::collections::BTreeMap;
use std::fmt::Write;

use serde_json::Value;

use crate::fit_folder::{FitFolder, Part};
use crate::html::{anchor, esc, figure, hex_of_linear, img, missing, num, swatch, table, value};
use crate::pictures::{difference, label_bounds, part_crop, Rgb8, DIFFERENCE_GAIN};
use crate::svg::loss_curve;

/// Longest side of the photos and renders as embedded.
const VIEW_SIDE: usize = 640;
/// Longest side of the part crops as embedded (a wall in a large photo is most of it).
const CROP_SIDE: usize = 480;
/// Longest side of the baked-map swatches.
const SWATCH_SIDE: usize = 128;

const STYLE: &str = "body{font:14px/1.45 system-ui,sans-serif;margin:0 auto;max-width:1200px;padding:0 16px;color:#222}\
h1{font-size:22px}h2{border-bottom:2px solid #ddd;margin-top:36px}h3{margin:22px 0 6px}h4{margin:8px 0 4px}\
nav{background:#f6f6f6;padding:8px 16px;columns:3}nav ul{margin:0;padding-left:18px}\
figure{display:inline-block;margin:4px 8px 8px 0;vertical-align:top}figcaption{font-size:12px;color:#555;max-width:320px}\
img.view{width:320px;height:auto}img.crop{height:140px;width:auto;max-width:380px;object-fit:contain;image-rendering:pixelated}\
img.map{width:128px;height:128px;image-rendering:pixelated}img.broken{outline:3px solid red}\
table{border-collapse:collapse;margin:6px 0}td,th{border:1px solid #ddd;padding:2px 6px;text-align:left;font-size:13px}\
th{background:#f0f0f0}.sw{display:inline-block;width:12px;height:12px;border:1px solid #888;margin-right:4px;vertical-align:middle}\
.na{color:#a0522d;font-style:italic}.part{border-top:1px solid #eee}.cols{display:flex;flex-wrap:wrap;gap:18px}\
code{background:#f3f3f3;padding:0 3px}";

/// Marks every image with its decoded width and counts the broken ones and any resource the page
/// loaded from elsewhere (the CSP forbids them; this makes a failure visible, and testable).
const CHECK_SCRIPT: &str = "addEventListener('load',function(){var n=0,bad=0;\
document.querySelectorAll('img').forEach(function(i){i.setAttribute('data-natural-width',i.naturalWidth);\
if(!i.complete||i.naturalWidth===0){bad++;i.classList.add('broken');}n++;});\
var b=document.body;b.setAttribute('data-images',n);b.setAttribute('data-broken-images',bad);\
b.setAttribute('data-external-resources',performance.getEntriesByType('resource').length);});";

/// The whole HTML text of the report.
pub fn render(fit: &FitFolder) -> String {
    let title = format!("photoscene fit: {}", fit.shown_as.file_name().and_then(|n| n.to_str()).unwrap_or("output"));
    let images = ViewImages::read(fit);
    let mut body = String::new();
    let _ = write!(body, "<h1>{}</h1>", esc(&title));
    body.push_str(&summary(fit));
    body.push_str(&contents(fit));
    body.push_str(&views(fit, &images));
    body.push_str("<h2 id=\"parts\">Parts</h2>");
    for part in &fit.parts {
        body.push_str(&part_section(fit, part, &images));
    }
    body.push_str(&crate::lights::lights(fit));
    body.push_str(&evaluation(fit));
    body.push_str(&run(fit));
    format!(
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
<meta http-equiv=\"Content-Security-Policy\" content=\"default-src 'none'; img-src data:; style-src 'unsafe-inline'; script-src 'unsafe-inline'\">\
<meta name=\"viewport\" content=\"width=device-width\"><title>{}</title><style>{STYLE}</style></head>\n<body>{body}\
<script>{CHECK_SCRIPT}</script></body></html>\n",
        esc(&title)
    )
}

/// Every view's images, each read from disk once for the whole page.
struct ViewImages {
    /// The photo (sRGB as stored), or why it is not available.
    photos: BTreeMap<String, Result<Rgb8, String>>,
    /// Per view, in the page's order ([`view_names`]), the fit's re-render as written (at the
    /// working raster where the fit used one), or why it is not available.
    renders: Vec<(String, Result<Rgb8, String>)>,
    /// The re-render on its photo's raster (for crops beside the photo's): as written, or, for
    /// a view fitted at a working raster, each pixel over its block.
    renders_on_photo: BTreeMap<String, Rgb8>,
}

impl ViewImages {
    fn read(fit: &FitFolder) -> ViewImages {
        let photos = match &fit.scene {
            Ok(scene) => scene.views.iter().map(|v| (v.name.clone(), Rgb8::read(&v.image))).collect(),
            Err(_) => BTreeMap::new(),
        };
        let renders: Vec<(String, Result<Rgb8, String>)> = view_names(fit)
            .into_iter()
            .map(|name| {
                let render = match fit.render_of(&name) {
                    Some(path) => Rgb8::read(&path),
                    None => Err("the fit wrote no renders/ for this view (--render-spp 0?)".into()),
                };
                (name, render)
            })
            .collect();
        let mut renders_on_photo = BTreeMap::new();
        if let Ok(scene) = &fit.scene {
            for view in &scene.views {
                let Some((_, Ok(r))) = renders.iter().find(|(name, _)| name == &view.name) else { continue };
                let r = match fit.working_raster(&view.name) {
                    Some((origin, factor, w, h)) if (w, h) == (r.width, r.height) => {
                        r.blocks_at(origin, factor, view.width, view.height)
                    }
                    _ => r.clone(),
                };
                renders_on_photo.insert(view.name.clone(), r);
            }
        }
        ViewImages { photos, renders, renders_on_photo }
    }
}

/// The names of the views: the scene's, else those the fit rendered.
fn view_names(fit: &FitFolder) -> Vec<String> {
    if let Ok(scene) = &fit.scene {
        return scene.views.iter().map(|v| v.name.clone()).collect();
    }
    let mut names: Vec<String> = fit
        .result
        .get("renders")
        .and_then(Value::as_array)
        .into_iter()
        .flatten()
        .filter_map(Value::as_str)
        .filter_map(|r| r.strip_prefix("renders/")?.strip_suffix(".png"))
        .filter(|n| !n.ends_with("_beside_photo"))
        .map(str::to_string)
        .collect();
    names.dedup();
    names
}

fn summary(fit: &FitFolder) -> String {
    let get = |k: &str| fit.result.get(k).and_then(Value::as_str).unwrap_or("—").to_string();
    let scene = fit.scene_dir.as_ref().map(|p| p.display().to_string()).unwrap_or_else(|| "—".into());
    let mut s = format!(
        "<p>Fit output <code>{}</code> of the scene <code>{}</code>, made by photoscene {}.</p>",
        esc(&fit.shown_as.display().to_string()),
        esc(&scene),
        esc(&get("version"))
    );
    if let Err(why) = &fit.scene {
        s.push_str(&missing("Photos and part labels", why));
    }
    s
}

fn contents(fit: &FitFolder) -> String {
    let mut s = String::from("<nav><b>Contents</b><ul><li><a href=\"#views\">Views</a><ul>");
    for v in view_names(fit) {
        let _ = write!(s, "<li><a href=\"#{}\">{}</a></li>", anchor("view", &v), esc(&v));
    }
    s.push_str("</ul></li><li><a href=\"#parts\">Parts</a><ul>");
    for p in &fit.parts {
        let _ = write!(s, "<li><a href=\"#{}\">{}</a></li>", anchor("part", &p.name), esc(&p.name));
    }
    s.push_str(
        "</ul></li><li><a href=\"#lights\">Lights</a></li><li><a href=\"#evaluation\">Evaluation</a></li>\
         <li><a href=\"#run\">Run</a></li></ul></nav>",
    );
    s
}

fn views(fit: &FitFolder, images: &ViewImages) -> String {
    let mut s = String::from("<h2 id=\"views\">Views</h2>");
    let _ = write!(
        s,
        "<p>Each input view: the photo, the fit's re-render by the path tracer, and |photo − render| per sRGB \
         channel ×{DIFFERENCE_GAIN} (black: equal).</p>"
    );
    if images.renders.is_empty() {
        s.push_str(&missing("Views", "the scene is not available and the fit rendered none"));
    }
    for (name, render) in &images.renders {
        let _ = write!(s, "<h3 id=\"{}\">{}</h3><div>", anchor("view", name), esc(name));
        let photo = images.photos.get(name);
        match photo {
            Some(Ok(p)) => s.push_str(&figure(&img(&p.fit_within(VIEW_SIDE).data_uri(), "photo", "view"), "photo")),
            Some(Err(e)) => s.push_str(&missing("Photo", e)),
            None => s.push_str(&missing("Photo", "the scene is not available")),
        }
        match render {
            Ok(r) => s.push_str(&figure(&img(&r.fit_within(VIEW_SIDE).data_uri(), "re-render", "view"), "re-render")),
            Err(e) => s.push_str(&missing("Re-render", e)),
        }
        match (photo, render) {
            (Some(Ok(p)), Ok(r)) => match difference(&photo_at_render_raster(fit, name, p, r), r) {
                Some((d, mean)) => s.push_str(&figure(
                    &img(&d.fit_within(VIEW_SIDE).data_uri(), "difference", "view"),
                    &format!("|photo − render| ×{DIFFERENCE_GAIN}; mean {} of full scale", num(mean)),
                )),
                None => s.push_str(&missing(
                    "Difference",
                    &format!("the photo is {}×{}, the render {}×{}", p.width, p.height, r.width, r.height),
                )),
            },
            _ => s.push_str(&missing("Difference", "it needs both the photo and the render")),
        }
        s.push_str("</div>");
    }
    s
}

/// The photo at the raster its re-render was made at: itself, or, for a view `psc fit` fitted at
/// a working raster, its block average there.
fn photo_at_render_raster<'a>(fit: &FitFolder, view: &str, photo: &'a Rgb8, render: &Rgb8) -> Cow<'a, Rgb8> {
    match fit.working_raster(view) {
        Some((origin, factor, w, h))
            if (w, h) == (render.width, render.height)
                && origin[0] + w * factor <= photo.width
                && origin[1] + h * factor <= photo.height =>
        {
            Cow::Owned(photo.block_average(origin, factor, w, h))
        }
        _ => Cow::Borrowed(photo),
    }
}

/// The crop of the part in its view, from the photo and (when there) the render.
fn crops(fit: &FitFolder, part: &Part, images: &ViewImages) -> String {
    let Some(view_name) = part.view() else {
        return missing("Crop", "the part was not fitted in any view");
    };
    let Ok(scene) = &fit.scene else {
        return missing("Crop", "the scene is not available");
    };
    let Some(view) = scene.view(view_name) else {
        return missing("Crop", &format!("the scene has no view '{view_name}'"));
    };
    let Some(labels) = &view.labels else {
        return missing("Crop", &format!("view '{view_name}' has no label image"));
    };
    let values: Vec<u16> = view.part_labels.iter().filter(|(_, n)| **n == part.name).map(|(v, _)| *v).collect();
    let Some(bounds) = label_bounds(labels, &values) else {
        return missing("Crop", &format!("no pixel of view '{view_name}' is labelled '{}'", part.name));
    };
    let mut s = String::new();
    match images.photos.get(view_name) {
        Some(Ok(p)) if (p.width, p.height) == (labels.width, labels.height) => {
            let c = part_crop(p, labels, &values, bounds).fit_within(CROP_SIDE);
            s.push_str(&figure(&img(&c.data_uri(), "photo crop", "crop"), &format!("photo, {}", esc(view_name))));
        }
        Some(Ok(_)) => s.push_str(&missing("Crop", "the label image and the photo differ in size")),
        Some(Err(e)) => s.push_str(&missing("Crop", e)),
        None => s.push_str(&missing("Crop", "no photo")),
    }
    if let Some(r) = images.renders_on_photo.get(view_name) {
        if (r.width, r.height) == (labels.width, labels.height) {
            let c = part_crop(r, labels, &values, bounds).fit_within(CROP_SIDE);
            s.push_str(&figure(&img(&c.data_uri(), "render crop", "crop"), "re-render"));
        }
    }
    s
}

fn part_section(fit: &FitFolder, part: &Part, images: &ViewImages) -> String {
    let mut s = format!("<section class=\"part\" id=\"{}\"><h3>{}</h3>", anchor("part", &part.name), esc(&part.name));
    let _ = write!(
        s,
        "<p>Graph <b>{}</b>; status <i>{}</i>; view {}.</p>",
        esc(part.graph().unwrap_or("—")),
        esc(part.status()),
        esc(part.view().unwrap_or("none"))
    );
    s.push_str("<div class=\"cols\"><div>");
    s.push_str(&crops(fit, part, images));
    s.push_str("</div><div>");
    s.push_str(&swatches(part));
    s.push_str("</div></div><div class=\"cols\"><div><h4>Graph selection</h4>");
    match &part.detail {
        Ok(d) => s.push_str(&selection(part, d)),
        Err(e) => s.push_str(&missing("Selection", e)),
    }
    s.push_str("</div><div><h4>Loss</h4>");
    match &part.detail {
        Ok(d) => s.push_str(&fit_figures(d)),
        Err(e) => s.push_str(&missing("Loss", e)),
    }
    s.push_str("</div><div><h4>Fitted parameters</h4>");
    match &part.material {
        Ok(m) => s.push_str(&parameters(m)),
        Err(e) => s.push_str(&missing("Parameters", e)),
    }
    s.push_str("</div></div></section>");
    s
}

fn swatches(part: &Part) -> String {
    let mut s = String::new();
    for map in ["albedo", "normal", "roughness"] {
        let path = part.maps_dir.join(format!("material_{map}.png"));
        if !path.is_file() {
            s.push_str(&missing(&format!("Baked {map}"), "not baked (--texture-size 0?)"));
            continue;
        }
        match Rgb8::read(&path) {
            Ok(m) => s.push_str(&figure(
                &img(&m.fit_within(SWATCH_SIDE).data_uri(), &format!("baked {map}"), "map"),
                &format!("{map} ({}²)", m.width),
            )),
            Err(e) => s.push_str(&missing(&format!("Baked {map}"), &e)),
        }
    }
    s
}

fn selection(part: &Part, detail: &Value) -> String {
    let Some(top) = detail.get("top").and_then(Value::as_array).filter(|t| !t.is_empty()) else {
        return "<p>No selection: the graph was forced or the part was not observed.</p>".into();
    };
    let chosen = part.graph().unwrap_or("");
    let rows: Vec<Vec<String>> = top
        .iter()
        .enumerate()
        .map(|(i, t)| {
            let g = t.get("graph").and_then(Value::as_str).unwrap_or("?");
            let mark = if g == chosen { " ✔" } else { "" };
            vec![
                format!("{}", i + 1),
                format!("{}{mark}", esc(g)),
                t.get("votes").map(value).unwrap_or_default(),
                t.get("best_loss").map(value).unwrap_or_default(),
                t.get("start_loss").map(value).unwrap_or_default(),
            ]
        })
        .collect();
    let mut s = table(&["#", "graph", "votes", "best exemplar loss", "loss after a start of the fit"], &rows);
    let check = detail.get("flat_check").filter(|c| !c.is_null());
    let loss = |key: &str| check.and_then(|c| c.get(key)).and_then(Value::as_f64);
    let winner = check.and_then(|c| c.get("contest_winner")).and_then(Value::as_str);
    match (winner, loss("contest_loss"), loss("flat_loss")) {
        (Some(winner), Some(contest), Some(flat)) if flat < contest => {
            let _ = write!(
                s,
                "<p>Chosen: <b>{}</b>: a flat colour fitted to the same pixels ended below the contest's winner, \
                 <b>{}</b> (loss {} against {}).</p>",
                esc(chosen),
                esc(winner),
                num(flat),
                num(contest)
            );
        }
        (Some(_), Some(contest), Some(flat)) => {
            let _ = write!(
                s,
                "<p>A flat colour fitted to the same pixels ended at loss {}, above the winner's {}.</p>",
                num(flat),
                num(contest)
            );
        }
        _ if !top.iter().any(|t| t.get("graph").and_then(Value::as_str) == Some(chosen)) => {
            let _ = write!(s, "<p>Chosen: <b>{}</b> (not among the alternatives above).</p>", esc(chosen));
        }
        _ => {}
    }
    s
}

fn fit_figures(detail: &Value) -> String {
    let mut s = String::new();
    let curve: Vec<f64> = detail
        .get("loss_curve")
        .and_then(Value::as_array)
        .map(|a| a.iter().map(|v| v.as_f64().unwrap_or(f64::NAN)).collect())
        .unwrap_or_default();
    match loss_curve(&curve) {
        Some(svg) => s.push_str(&svg),
        None => s.push_str("<p>No loss curve (the part was not optimised).</p>"),
    }
    let mut rows = Vec::new();
    if let Some(loss) = detail.get("loss").and_then(Value::as_object) {
        for (k, v) in loss {
            rows.push(vec![format!("loss: {}", esc(k)), value(v)]);
        }
    }
    for key in ["iterations", "uv_candidates", "roughness"] {
        if let Some(v) = detail.get(key) {
            rows.push(vec![esc(key), value(v)]);
        }
    }
    if let Some(pixels) = detail.get("pixels").and_then(Value::as_object) {
        for (k, v) in pixels.iter().filter(|(_, v)| v.is_number()) {
            rows.push(vec![format!("pixels: {}", esc(k)), value(v)]);
        }
    }
    if let Some(iou) = detail.pointer("/alignment/iou") {
        rows.push(vec!["alignment IoU".into(), value(iou)]);
    }
    if let Some(t) = detail.get("timings_s").and_then(Value::as_object) {
        for (k, v) in t {
            rows.push(vec![format!("time: {} (s)", esc(k)), value(v)]);
        }
    }
    s.push_str(&table(&["", "value"], &rows));
    s
}

/// A linear colour `[r, g, b]` as numbers.
pub(crate) fn as_rgb(v: &Value) -> Option<[f64; 3]> {
    let a = v.as_array().filter(|a| a.len() == 3)?;
    Some([a[0].as_f64()?, a[1].as_f64()?, a[2].as_f64()?])
}

fn parameters(material: &Value) -> String {
    let mut rows = Vec::new();
    if let Some(params) = material.get("params").and_then(Value::as_object) {
        for (k, v) in params {
            let shown = match as_rgb(v) {
                Some(rgb) => format!("{}{} (linear)", swatch(&hex_of_linear(rgb)), value(v)),
                None => value(v),
            };
            rows.push(vec![format!("<code>{}</code>", esc(k)), shown]);
        }
    }
    for key in ["albedo_scale", "roughness_scale", "uv_scale", "uv_offset", "uv_rotation_deg"] {
        if let Some(v) = material.get(key) {
            rows.push(vec![format!("<i>{}</i>", esc(key)), value(v)]);
        }
    }
    if rows.is_empty() {
        return "<p>None.</p>".into();
    }
    table(&["parameter", "value"], &rows)
}

fn evaluation(fit: &FitFolder) -> String {
    let mut s = String::from("<h2 id=\"evaluation\">Evaluation</h2>");
    let eval = match &fit.eval {
        Ok(e) => e,
        Err(e) => return s + &missing("Evaluation (run `psc eval` on a scene with truth/)", e),
    };
    let metrics = ["rmse", "ssim", "mean_colour", "colour_w1", "contrast_w1"];
    let cell = |r: &Value, k: &str| r.get(k).map(value).unwrap_or_default();
    if let Some(rows) = eval.get("rows").and_then(Value::as_array) {
        let mut header = vec!["geometry", "views", "method", "images", "parts"];
        header.extend(metrics);
        let body: Vec<Vec<String>> = rows
            .iter()
            .map(|r| {
                let mut row: Vec<String> =
                    ["geometry", "views", "method", "images", "parts"].iter().map(|k| cell(r, k)).collect();
                row.extend(metrics.iter().map(|k| cell(r, k)));
                row
            })
            .collect();
        s.push_str("<p>Errors against the truth renders (lower is better; SSIM higher).</p>");
        s.push_str(&table(&header, &body));
    }
    if let Some(ratios) = eval.get("ratios").and_then(Value::as_array) {
        let keys = ["rmse", "one_minus_ssim", "mean_colour", "colour_w1", "contrast_w1"];
        let body: Vec<Vec<String>> = ratios
            .iter()
            .map(|r| {
                let mut row = vec![
                    cell(r, "geometry"),
                    cell(r, "views"),
                    format!("{} / {}", cell(r, "numerator"), cell(r, "denominator")),
                ];
                row.extend(keys.iter().map(|k| cell(r, k)));
                row
            })
            .collect();
        let mut header = vec!["geometry", "views", "ratio"];
        header.extend(keys);
        s.push_str("<p>Ratios of errors (below 1: the numerator is better).</p>");
        s.push_str(&table(&header, &body));
    }
    if let Some(floors) = eval.get("unseen_floors").and_then(Value::as_array).filter(|f| !f.is_empty()) {
        let keys = ["geometry", "views", "rmse", "mean_colour", "colour_w1", "contrast_w1"];
        let body: Vec<Vec<String>> = floors.iter().map(|f| keys.iter().map(|k| cell(f, k)).collect()).collect();
        s.push_str(
            "<p>Floor of the parts no input view shows: the fitted / pixel median ratio with every photographed part scored 0 (no fit of those parts goes below it).</p>",
        );
        s.push_str(&table(&keys, &body));
    }
    s
}

fn run(fit: &FitFolder) -> String {
    let mut s = String::from("<h2 id=\"run\">Run</h2>");
    let field = |k: &str| fit.result.get(k).and_then(Value::as_str).unwrap_or("—");
    let _ = write!(
        s,
        "<p>Command: <code>{}</code><br>photoscene {} · format {}</p>",
        esc(field("command")),
        esc(field("version")),
        esc(field("format"))
    );
    if let Some(t) = fit.result.get("timings_s").and_then(Value::as_object) {
        let mut rows: Vec<Vec<String>> = t.iter().map(|(k, v)| vec![esc(k), value(v)]).collect();
        let total: f64 = t.values().filter_map(Value::as_f64).sum();
        rows.push(vec!["<b>total</b>".into(), format!("<b>{}</b>", num(total))]);
        s.push_str(&table(&["stage", "seconds"], &rows));
    }
    s
}
