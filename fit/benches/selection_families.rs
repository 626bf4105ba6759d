//! Graph selection on the dev scenes' true textures, one at a time, away from any room: each
//! texture in `../shared/scenes/dev_*/truth/textures` that a generator made (planks, stripes,
//! plaster; the photo textures too, unjudged) is laid on a flat, evenly lit 96×96 crop at two
//! pixel densities and a random rotation, with the dev photos' pixel noise, and the whole
//! selection runs on it as `psc fit` runs it on a part: both votes over the full library, then
//! the contest of a start each. It prints the winner's category beside the family `psc eval`
//! expects of the texture's kind, and the selection's throughput.
//!
//! The dev scenes judge the graph family on six parts; this judges the selection alone on every
//! generated texture they hold, without the misalignment, clipping and small parts of a room,
//! so that a change to selection can be measured on more than six cases.
//!
//! `cargo bench -p psc-fit --bench selection_families` (about ten minutes on two cores: some
//! 20 s of selection per crop). Reads `truth/`, as tests and `psc eval` may; `psc fit` never
//! does.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use psc_base::SplitMix64;
use psc_fit::eval::expected_categories;
use psc_fit::features::{estimate_noise_sigma, FeatureConfig, Scratch};
use psc_fit::layer::{FitPixel, MaterialState, PartView, Sampling, Workspace};
use psc_fit::loss::{LossWeights, PartLoss};
use psc_fit::optim::Free;
use psc_fit::part::flat_state;
use psc_fit::part_fit::{fit_contest, FitSettings, Problem};
use psc_fit::select::{select, SelectSettings};
use psc_fit::shading::{LightSample, BINS};
use psc_render::image_io::{linear_to_srgb, read_rgb, RgbImage};
use psc_runtime::library::{default_library_root, Library};

/// Crop side in pixels.
const SIZE: usize = 96;
/// Crop pixels per texture tile: a coarse and a fine view of the same texture.
const DENSITIES: [f32; 2] = [160.0, 64.0];
/// The photos' pixel noise (sRGB), about the dev photos' (256-spp path tracing).
const NOISE: f32 = 0.01;
/// Texture kinds a generator made, by file-name prefix.
const KINDS: [&str; 4] = ["planks", "stripes", "plaster", "photo"];

fn main() {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/scenes");
    let textures = generated_textures(&scenes);
    if textures.is_empty() {
        eprintln!("SKIPPED: no dev-scene textures under {}", scenes.display());
        return;
    }
    let library = Library::load(&default_library_root()).expect("the graph library compiles");
    let settings = SelectSettings::default();
    let contest =
        FitSettings { starts: 1, max_iterations: FitSettings::default().start_iterations, ..FitSettings::default() };
    let (mut judged, mut matched, mut exemplars, mut seconds) = (0, 0, 0usize, 0.0f64);
    println!(
        "{:<28} {:>7} {:>8}  {:<44} {:<22} family",
        "texture", "kind", "px/tile", "pattern vote's top three", "chosen (category)"
    );
    for (case, (path, kind)) in textures.iter().enumerate() {
        let image = read_rgb(path, true).expect("a readable texture");
        for (d, &density) in DENSITIES.iter().enumerate() {
            let seed = (case * DENSITIES.len() + d) as u64;
            let view = textured_view(&library, &image, density, seed);
            let mut scratch = Scratch::default();
            let loss = PartLoss::new(&view, LossWeights::default(), &FeatureConfig::default(), &mut scratch).unwrap();
            let started = Instant::now();
            let selection =
                select(&library, &view, &loss, settings, FitSettings::default().search_sampling, seed, None)
                    .expect("selection runs");
            seconds += started.elapsed().as_secs_f64();
            exemplars += library.materials.len() * settings.exemplars * settings.scales;
            let (contenders, starts) = selection.entrants(&library, settings.contenders, 1);
            let problems: Vec<(Problem, Vec<MaterialState>)> = contenders
                .iter()
                .zip(starts)
                .map(|(&g, s)| (Problem::on_one_view(&library.materials[g], &view, &loss), s))
                .collect();
            let winner = contenders[fit_contest(&problems, &contest, Free::ALL).unwrap().winner];
            let graph = &library.materials[winner];
            let category = graph.graph.info.category.as_str();
            let verdict = match expected_categories(kind) {
                Some(expected) => {
                    judged += 1;
                    let ok = expected.contains(&category);
                    matched += usize::from(ok);
                    if ok {
                        "yes"
                    } else {
                        "no"
                    }
                }
                None => "-",
            };
            let top: Vec<&str> = selection.pattern.ranking.iter().take(3).map(|r| r.graph.as_str()).collect();
            let name = path.strip_prefix(&scenes).unwrap_or(path).display().to_string().replace("/truth/textures", "");
            println!(
                "{name:<28} {kind:>7} {density:>8.0}  {:<44} {:<22} {verdict}",
                top.join(", "),
                format!("{} ({category})", graph.name())
            );
        }
    }
    println!("family matches the kind's: {matched} of {judged} judged crops");
    println!(
        "selection: {:.0} exemplar scorings per second ({} graphs × {} exemplars × {} scales per crop, {:.1} s per crop)",
        exemplars as f64 / seconds,
        library.materials.len(),
        settings.exemplars,
        settings.scales,
        seconds / (textures.len() * DENSITIES.len()) as f64
    );
}

/// Every generated texture of every dev scene, once (the scenes share some), with its kind.
fn generated_textures(scenes: &Path) -> Vec<(PathBuf, &'static str)> {
    let mut seen = BTreeSet::new();
    let mut out = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(scenes)
        .map(|r| r.filter_map(|e| e.ok()).map(|e| e.path().join("truth/textures")).collect())
        .unwrap_or_default();
    dirs.sort();
    for dir in dirs {
        let mut files: Vec<PathBuf> =
            std::fs::read_dir(&dir).map(|r| r.filter_map(|e| e.ok()).map(|e| e.path()).collect()).unwrap_or_default();
        files.sort();
        for file in files {
            let name = file.file_name().and_then(|n| n.to_str()).unwrap_or_default().to_string();
            let Some(kind) = KINDS.iter().find(|k| name.starts_with(&format!("{k}_"))) else { continue };
            let bytes = std::fs::read(&file).unwrap_or_default();
            if seen.insert(bytes) {
                out.push((file, *kind));
            }
        }
    }
    out
}

/// A crop of the texture as albedo on a flat surface under an even light, `density` crop
/// pixels per texture tile at a random rotation and offset, each pixel the box average of its
/// footprint, with the photos' noise; its noise estimate as `targets` makes it.
fn textured_view(library: &Library, image: &RgbImage, density: f32, seed: u64) -> PartView {
    let mut rng = SplitMix64::new(seed.wrapping_mul(0x9e37_79b9) ^ 0x005e_1ec7);
    let (angle, offset) = (rng.next_f32() * std::f32::consts::TAU, [rng.next_f32(), rng.next_f32()]);
    let (c, s) = (angle.cos() / density, angle.sin() / density);
    let uv_at = |x: f32, y: f32| [offset[0] + c * x - s * y, offset[1] + s * x + c * y];
    let light = LightSample::new(&[[0.4; 3]; BINS], Vec3::Z);
    let pixels: Vec<FitPixel> = (0..SIZE * SIZE)
        .map(|i| FitPixel {
            crop_index: i as u32,
            uv: uv_at((i % SIZE) as f32 + 0.5, (i / SIZE) as f32 + 0.5),
            duv_dx: [c, s],
            duv_dy: [-s, c],
            bitangent_sign: 1.0,
            wo_local: Vec3::Z,
            light: light.clone(),
        })
        .collect();
    let mut view = PartView {
        width: SIZE,
        height: SIZE,
        origin: [0, 0],
        factor: 1,
        pixels,
        weight: vec![1.0; SIZE * SIZE],
        target: vec![[0.0; 3]; SIZE * SIZE],
        target_linear: vec![[0.0; 3]; SIZE * SIZE],
        exposure: [1.0; 3],
        noise: [0.0; 4],
        noise_scale: 1.0,
        faces: Vec::new(),
    };
    // The light a white diffuse surface reflects here, which the texture's albedo scales.
    let white = library.get("homogeneous").expect("the library has the homogeneous material");
    let state = flat_state(white, [1.0; 3], 1.0);
    let mut ws = Workspace::default();
    view.render(white, &state, Sampling { density: 0.0, max_per_axis: 1 }, &mut ws).unwrap();
    let texels_per_pixel = image.width as f32 / density;
    let n = (texels_per_pixel.ceil() as usize).clamp(1, 8);
    for i in 0..SIZE * SIZE {
        let (x, y) = ((i % SIZE) as f32, (i / SIZE) as f32);
        let mut albedo = [0.0f32; 3];
        for j in 0..n * n {
            let uv = uv_at(x + ((j % n) as f32 + 0.5) / n as f32, y + ((j / n) as f32 + 0.5) / n as f32);
            let t = bilinear(image, uv);
            (0..3).for_each(|k| albedo[k] += t[k] / (n * n) as f32);
        }
        let linear: [f32; 3] = std::array::from_fn(|k| albedo[k] * ws.linear[i][k]);
        let noisy = linear.map(|v| (linear_to_srgb(v) + NOISE * gaussian(&mut rng)).clamp(0.0, 1.0));
        view.target[i] = noisy;
        view.target_linear[i] = noisy.map(psc_render::image_io::srgb_to_linear);
    }
    view.noise = std::array::from_fn(|k| {
        let plane: Vec<f32> =
            view.target.iter().map(|&p| if k < 3 { p[k] } else { psc_fit::contrast::luma(p) }).collect();
        estimate_noise_sigma(&plane, &view.weight, SIZE, SIZE)
    });
    view
}

/// The texture at uv (repeating; v up, row 0 at the top), bilinear.
fn bilinear(image: &RgbImage, uv: [f32; 2]) -> [f32; 3] {
    let (w, h) = (image.width as f32, image.height as f32);
    let x = uv[0].rem_euclid(1.0) * w - 0.5;
    let y = (1.0 - uv[1].rem_euclid(1.0)) * h - 0.5;
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let at = |xi: f32, yi: f32| {
        let (xi, yi) = (xi.rem_euclid(w) as usize, yi.rem_euclid(h) as usize);
        image.data[yi * image.width + xi]
    };
    let (a, b, c, d) = (at(x0, y0), at(x0 + 1.0, y0), at(x0, y0 + 1.0), at(x0 + 1.0, y0 + 1.0));
    std::array::from_fn(|k| (a[k] * (1.0 - fx) + b[k] * fx) * (1.0 - fy) + (c[k] * (1.0 - fx) + d[k] * fx) * fy)
}

/// A standard normal draw (Box–Muller).
fn gaussian(rng: &mut SplitMix64) -> f32 {
    let (u, v) = (rng.next_f32().max(1e-7), rng.next_f32());
    (-2.0 * u.ln()).sqrt() * (std::f32::consts::TAU * v).cos()
}
