//! Dropping a kernel frees its executable pages (cranelift's JITModule leaks them otherwise).
//!
//! Calibrated so it can fail: first measure what one *leaked* kernel costs in RSS, require
//! that 600 such leaks would exceed twice the 2 MiB bound, then compile-and-drop 600 kernels and
//! require RSS to stay within the bound.

mod common;

use common::rss_bytes;
use psc_compiler::ir::{Builder, Output, Program};

/// A program with enough inline transcendentals that its code spans several pages.
fn program() -> Program {
    let mut b = Builder::new();
    let mut x = b.u();
    let v = b.v();
    for i in 0..16 {
        let p = b.param(i % 3);
        let t = b.mul(x, p);
        let s = b.sin(t);
        let e = b.exp(s);
        let l = b.log(e);
        let a = b.atan2(l, v);
        x = b.add(a, x);
    }
    b.finish(vec![Output { name: "x".into(), node: x }])
}

const CYCLES: u64 = 600;

#[test]
fn compiling_and_dropping_600_kernels_does_not_grow_rss() {
    let prog = program();
    let t = std::time::Instant::now();
    // Warm up allocators and cranelift's lazily built tables.
    for _ in 0..20 {
        drop(psc_jit::compile(&prog).unwrap());
    }
    // Generous: a correct drop grows RSS by a few KiB at most over the whole loop.
    let bound: u64 = 2 << 20;

    let before_leak = rss_bytes();
    let leaked: Vec<_> = (0..50).map(|_| psc_jit::compile(&prog).unwrap()).collect();
    let per_kernel = (rss_bytes().saturating_sub(before_leak)) / 50;
    println!("compile time {:?} per kernel", t.elapsed() / 70);
    println!("one live kernel holds ~{} KiB of RSS", per_kernel / 1024);
    assert!(per_kernel * CYCLES > 2 * bound, "the test could not detect a leak: {per_kernel} B per kernel");
    drop(leaked);

    let before = rss_bytes();
    for _ in 0..CYCLES {
        let k = psc_jit::compile(&prog).unwrap();
        drop(k);
    }
    let grown = rss_bytes().saturating_sub(before);
    println!("RSS grew by {} KiB over {CYCLES} compile/drop cycles", grown / 1024);
    assert!(grown < bound, "RSS grew by {} MiB", grown >> 20);
}
