//! Throughput of the shading layer, the fit's inner loop: samples per second of a render
//! (graph forward kernel + shading + sRGB) and of a render followed by its backward pass
//! (fused adjoint kernel + shading adjoint), on a 64×64 crop with 2×2 to 4×4 samples per pixel,
//! for a few library graphs; and the cost of one irradiance evaluation by normal tilt. Times
//! are process CPU seconds (so a busy machine disturbs them less); quote the ratios.
//!
//! `cargo bench -p psc-fit --bench layer`

use std::time::Instant;

use glam::Vec3;
use psc_base::SplitMix64;
use psc_fit::layer::{FitPixel, MaterialState, PartView, Sampling, Workspace};
use psc_fit::shading::{LightSample, BINS};
use psc_fit::uvmap::UvTransform;
use psc_runtime::library::{default_library_root, Library};

/// CPU seconds used by this process so far (user + system), from /proc; wall time elsewhere.
fn cpu_seconds(start: Instant) -> f64 {
    let ticks = std::fs::read_to_string("/proc/self/stat").ok().and_then(|s| {
        let rest = &s[s.rfind(')')? + 2..];
        let f: Vec<&str> = rest.split_whitespace().collect();
        Some(f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?)
    });
    match ticks {
        Some(t) => t / 100.0,
        None => start.elapsed().as_secs_f64(),
    }
}

fn measure(mut f: impl FnMut()) -> f64 {
    let origin = Instant::now();
    f();
    let (c0, mut reps) = (cpu_seconds(origin), 0);
    while cpu_seconds(origin) - c0 < 1.0 || reps < 3 {
        f();
        reps += 1;
    }
    (cpu_seconds(origin) - c0) / reps as f64
}

fn view(rng: &mut SplitMix64) -> PartView {
    let (w, h) = (64usize, 64usize);
    let mut bins = [[0.0f32; 3]; BINS];
    for b in bins.iter_mut() {
        *b = [0, 1, 2].map(|_| 0.2 + rng.next_f32());
    }
    let light = LightSample::new(&bins, Vec3::new(0.2, 0.1, 0.9).normalize());
    let step = 1.0 / 60.0;
    let pixels = (0..w * h)
        .map(|i| FitPixel {
            crop_index: i as u32,
            uv: [(i % w) as f32 * step, (i / w) as f32 * step],
            duv_dx: [step, 0.0],
            duv_dy: [0.0, -step],
            bitangent_sign: 1.0,
            wo_local: Vec3::new(0.2, 0.1, 0.9).normalize(),
            light: light.clone(),
        })
        .collect();
    PartView {
        width: w,
        height: h,
        origin: [0, 0],
        factor: 1,
        pixels,
        weight: vec![1.0; w * h],
        target: vec![[0.5; 3]; w * h],
        target_linear: vec![[0.2; 3]; w * h],
        exposure: [1.0; 3],
        noise: [0.0; 4],
        noise_scale: 1.0,
        faces: Vec::new(),
    }
}

fn main() {
    let library = Library::load(&default_library_root()).expect("library");
    let mut rng = SplitMix64::new(1);
    let view = view(&mut rng);
    let sampling = Sampling::default();
    println!("shading layer, 64x64 crop ({} pixels), process CPU time", view.pixels.len());
    println!("{:<20} {:>8} {:>14} {:>18} {:>8}", "graph", "samples", "render Ms/s", "render+back Ms/s", "ratio");
    for name in ["homogeneous", "plaster", "oak_planks", "granite", "striped_wallpaper", "boucle"] {
        let Some(material) = library.get(name) else { continue };
        material.gradient_kernel().expect("adjoint");
        let state = MaterialState {
            params: material.graph.info.default_params(),
            uv: UvTransform { rotation: 0.4, log_scale: 1.0, offset: [0.1, 0.2] },
            albedo_scale: [1.0; 3],
            roughness: 0.4,
        };
        let samples = view.sample_count(&state, sampling);
        let mut ws = Workspace::default();
        let d_image = vec![[0.01f32; 3]; view.width * view.height];
        let forward = measure(|| view.render(material, &state, sampling, &mut ws).unwrap());
        let both = measure(|| {
            view.render(material, &state, sampling, &mut ws).unwrap();
            view.backward(material, &state, &mut ws, &d_image).unwrap();
        });
        println!(
            "{name:<20} {samples:>8} {:>14.2} {:>18.2} {:>7.2}x",
            samples as f64 / forward / 1e6,
            samples as f64 / both / 1e6,
            both / forward
        );
    }
    println!("irradiance of one sample (bins below a tilted normal's horizon are walked per row)");
    let mut bins = [[0.0f32; 3]; BINS];
    for b in bins.iter_mut() {
        *b = [0, 1, 2].map(|_| rng.next_f32());
    }
    let light = LightSample::new(&bins, Vec3::Z);
    for tilt in [0.0f32, 0.1, 0.3, 0.6] {
        let normals: Vec<Vec3> = (0..100_000)
            .map(|_| {
                let p = rng.next_f32() * std::f32::consts::TAU;
                Vec3::new(tilt.sin() * p.cos(), tilt.sin() * p.sin(), tilt.cos())
            })
            .collect();
        let mut sink = 0.0f32;
        let t = measure(|| {
            for n in &normals {
                sink += light.irradiance(*n)[0];
            }
        });
        println!("  tilt {:>4.0}°: {:>6.1} ns ({sink:.0})", tilt.to_degrees(), t / normals.len() as f64 * 1e9);
    }
}
