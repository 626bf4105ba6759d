//! Throughput of the feature loss: `describe` and `loss_and_grad` in pixels per second on
//! synthetic crops of several sizes and shapes, single-threaded, and the two-thread rate of
//! many candidates at once (as UV search and selection call it). Single-thread figures are
//! on-CPU time of the calling thread (`/proc/thread-self/schedstat` on Linux, wall time
//! elsewhere), so that a shared, busy machine disturbs them less; ratios within one run are
//! the figures to quote.
//!
//! `cargo bench -p psc-fit --bench features`

use std::time::Instant;

use psc_fit::features::{FeatureConfig, FeatureLoss, Region, Scratch};
use rayon::prelude::*;

fn pattern(w: usize, h: usize, seed: u64) -> Vec<[f32; 3]> {
    let s = seed as f32;
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32, (i / w) as f32);
            let a = (0.31 * x + 0.17 * y + s).sin() * 0.2 + (0.05 * x - 0.11 * y + 2.0 * s).sin() * 0.1;
            [0.5 + a, 0.45 + 0.8 * a, 0.4 + 0.5 * a]
        })
        .collect()
}

fn disc(w: usize, h: usize) -> Vec<f32> {
    let (cx, cy, r) = (w as f32 / 2.0, h as f32 / 2.0, w.min(h) as f32 / 2.0);
    (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f32 + 0.5 - cx, (i / w) as f32 + 0.5 - cy);
            if x * x + y * y < r * r {
                1.0
            } else {
                0.0
            }
        })
        .collect()
}

/// Seconds this thread has spent on a CPU, if the platform says.
fn thread_cpu_seconds() -> Option<f64> {
    let text = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    let ns: f64 = text.split_whitespace().next()?.parse().ok()?;
    Some(ns * 1e-9)
}

/// Seconds per call (thread CPU time where available): the median of `reps` batches, each
/// long enough (about 50 ms) for the scheduler's accounting to be exact.
fn time(reps: usize, mut f: impl FnMut()) -> f64 {
    let t = Instant::now();
    f();
    let per_batch = ((0.05 / t.elapsed().as_secs_f64().max(1e-6)) as usize).clamp(1, 10_000);
    let mut samples: Vec<f64> = (0..reps)
        .map(|_| {
            let (t, c) = (Instant::now(), thread_cpu_seconds());
            for _ in 0..per_batch {
                f();
            }
            let secs = match (c, thread_cpu_seconds()) {
                (Some(a), Some(b)) if b > a => b - a,
                _ => t.elapsed().as_secs_f64(),
            };
            secs / per_batch as f64
        })
        .collect();
    samples.sort_by(f64::total_cmp);
    samples[reps / 2]
}

fn main() {
    println!(
        "{:<28} {:>9} {:>7} {:>13} {:>13} {:>6} {:>10}",
        "crop", "pixels", "levels", "describe Mpx/s", "loss+grad Mpx/s", "ratio", "new() ms"
    );
    let shapes: Vec<(String, FeatureConfig, Region)> = vec![
        ("64x64 rect".into(), FeatureConfig::default(), Region { width: 64, height: 64, weight: vec![1.0; 64 * 64] }),
        (
            "128x128 rect".into(),
            FeatureConfig::default(),
            Region { width: 128, height: 128, weight: vec![1.0; 128 * 128] },
        ),
        (
            "320x240 rect".into(),
            FeatureConfig::default(),
            Region { width: 320, height: 240, weight: vec![1.0; 320 * 240] },
        ),
        ("240x240 disc".into(), FeatureConfig::default(), Region { width: 240, height: 240, weight: disc(240, 240) }),
        (
            "320x240 rect, achromatic".into(),
            FeatureConfig { colour: false, ..FeatureConfig::default() },
            Region { width: 320, height: 240, weight: vec![1.0; 320 * 240] },
        ),
        (
            "320x240 rect, cap 128²".into(),
            FeatureConfig { max_pixels: Some(128 * 128), ..FeatureConfig::default() },
            Region { width: 320, height: 240, weight: vec![1.0; 320 * 240] },
        ),
    ];
    for (name, config, region) in &shapes {
        let n = region.width * region.height;
        let t = Instant::now();
        let loss = FeatureLoss::new(config, region).unwrap();
        let new_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut s = Scratch::default();
        let target = loss.describe(&pattern(region.width, region.height, 1), &mut s).unwrap();
        let image = pattern(region.width, region.height, 2);
        let mut grad = vec![[0.0; 3]; n];
        let reps = 7;
        let td = time(reps, || {
            std::hint::black_box(loss.describe(&image, &mut s).unwrap());
        });
        let tg = time(reps, || {
            std::hint::black_box(loss.loss_and_grad(&image, &target, &mut s, &mut grad).unwrap());
        });
        println!(
            "{:<28} {:>9} {:>7} {:>13.2} {:>13.2} {:>6.2} {:>10.2}",
            name,
            n,
            format!("{:?}", loss.active_levels()),
            n as f64 / td / 1e6,
            n as f64 / tg / 1e6,
            tg / td,
            new_ms
        );
    }

    // Many candidates on one region from every rayon thread, as UV search and selection do.
    let region = Region { width: 128, height: 128, weight: disc(128, 128) };
    let loss = FeatureLoss::new(&FeatureConfig::default(), &region).unwrap();
    let target = loss.describe(&pattern(128, 128, 1), &mut Scratch::default()).unwrap();
    let images: Vec<Vec<[f32; 3]>> = (0..64).map(|k| pattern(128, 128, k + 3)).collect();
    let wall = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        t.elapsed().as_secs_f64()
    };
    let single = wall(&mut || {
        let mut s = Scratch::default();
        for img in &images {
            std::hint::black_box(loss.loss(img, &target, &mut s).unwrap());
        }
    });
    let parallel = wall(&mut || {
        images.par_iter().for_each_init(Scratch::default, |s, img| {
            std::hint::black_box(loss.loss(img, &target, s).unwrap());
        });
    });
    let px = (64 * 128 * 128) as f64;
    println!(
        "64 candidates of a 128x128 disc, wall time: 1 thread {:.2} Mpx/s, {} threads {:.2} Mpx/s ({:.2}x)",
        px / single / 1e6,
        rayon::current_num_threads(),
        px / parallel / 1e6,
        single / parallel
    );
}
