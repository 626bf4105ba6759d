//! Throughput benchmark (no criterion): primary rays/s, path rays/s and the time of a render.
//!
//! `cargo run --release -p psc-render --example bench -- ../shared/scenes/dev_1 [spp] [WxH] [threads]`
//! Uses the dev scene's truth geometry, truth materials and truth light radiances when present
//! (as `psc render --geometry truth --materials truth`). Prints wall and process CPU seconds:
//! on a shared machine CPU seconds are the comparable figure.

use std::path::PathBuf;

use psc_render::integrator::rescale;
use psc_render::{truth, LightRadiances, RenderOptions, Renderer, Scene};

/// User + system CPU seconds of this process (Linux), 0 elsewhere.
fn cpu_seconds() -> f64 {
    let Ok(stat) = std::fs::read_to_string("/proc/self/stat") else { return 0.0 };
    let after = stat.rsplit_once(')').map(|x| x.1).unwrap_or("");
    let f: Vec<&str> = after.split_whitespace().collect();
    let ticks = |i: usize| f.get(i).and_then(|v| v.parse::<f64>().ok()).unwrap_or(0.0);
    (ticks(11) + ticks(12)) / 100.0 // utime, stime (fields 14, 15), USER_HZ = 100
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = PathBuf::from(args.get(1).map(String::as_str).unwrap_or("../shared/scenes/dev_1"));
    let spp: u32 = args.get(2).and_then(|s| s.parse().ok()).unwrap_or(64);
    let (w, h) = args
        .get(3)
        .and_then(|s| s.split_once('x'))
        .and_then(|(a, b)| Some((a.parse().ok()?, b.parse().ok()?)))
        .unwrap_or((320usize, 240usize));
    let threads: Option<usize> = args.get(4).and_then(|s| s.parse().ok());
    let c0 = cpu_seconds();
    let t0 = std::time::Instant::now();
    let scene = Scene::load_with_mesh(&dir, truth::truth_mesh(&dir).as_deref()).expect("scene");
    let mut warnings = Vec::new();
    let materials =
        truth::truth_materials(&scene, &mut warnings).unwrap_or_else(|_| scene.mtl_materials(&mut warnings));
    let radiances =
        LightRadiances::resolve(&scene, &psc_render::LightsSource::Truth, &mut warnings).expect("radiances");
    let r = Renderer::new(&scene, materials, &radiances).expect("renderer");
    let load = (t0.elapsed().as_secs_f64(), cpu_seconds() - c0);
    let cam = rescale(&scene.views[0].camera, w, h).expect("camera");

    let c1 = cpu_seconds();
    let (primary, p_wall) = r.primary_ray_benchmark(&cam, 16, threads).expect("bench");
    let p_cpu = cpu_seconds() - c1;
    let opts = RenderOptions { width: w, height: h, spp, seed: 1, threads, ..Default::default() };
    let c2 = cpu_seconds();
    let out = r.render(&cam, &opts).expect("render");
    let r_cpu = cpu_seconds() - c2;
    let n_threads = threads.unwrap_or_else(rayon::current_num_threads);
    let samples = (w * h) as f64 * spp as f64;
    println!(
        "scene {} ({} triangles), {w}x{h}, {spp} spp, max_depth 6, {n_threads} threads",
        dir.display(),
        scene.mesh.triangles.len()
    );
    println!("load + BVH:   {:.3} s wall, {:.3} s CPU", load.0, load.1);
    println!(
        "primary rays: {:.2} Mrays/s wall, {:.2} Mrays per CPU s ({primary} rays)",
        primary as f64 / p_wall / 1e6,
        primary as f64 / p_cpu.max(1e-9) / 1e6
    );
    println!(
        "full paths:   {:.2} Mrays/s wall, {:.2} Mrays per CPU s ({:.2} rays/sample incl. shadow rays)",
        out.rays as f64 / out.seconds / 1e6,
        out.rays as f64 / r_cpu.max(1e-9) / 1e6,
        out.rays as f64 / samples
    );
    println!(
        "render:       {:.3} s wall, {:.3} s CPU, {:.3} Msamples per CPU s",
        out.seconds,
        r_cpu,
        samples / r_cpu.max(1e-9) / 1e6
    );
}
