//! Random IR programs, for benchmarks and tests that need IR without a `.psg` source.
//!
//! [`material_like`] is a seeded, reproducible workload shaped like a lowered material graph
//! (the synthetic program of `psc bench`); [`non_leaf_op`] numbers every non-leaf op kind so
//! that property tests can draw programs from plain integers (and shrink them).

use psc_base::SplitMix64;

use super::{Builder, NodeId, Op, Output, Program};

/// How many non-leaf op kinds [`non_leaf_op`] numbers.
pub const NON_LEAF_KINDS: usize = 21;

/// Non-leaf op kind `kind` (`< NON_LEAF_KINDS`, in the order [`Op`] declares them: `neg`,
/// `abs`, `floor`, `sqrt`, `sin`, `cos`, `exp`, `log`, `add`, `sub`, `mul`, `div`, `min`, `max`,
/// `pow`, `atan2`, `hash`, `lt`, `le`, `eq`, `select`) on the operands it takes of `a`, `b`,
/// `c`; `None` past the last kind.
pub fn non_leaf_op(kind: usize, a: NodeId, b: NodeId, c: NodeId) -> Option<Op> {
    Some(match kind {
        0 => Op::Neg(a),
        1 => Op::Abs(a),
        2 => Op::Floor(a),
        3 => Op::Sqrt(a),
        4 => Op::Sin(a),
        5 => Op::Cos(a),
        6 => Op::Exp(a),
        7 => Op::Log(a),
        8 => Op::Add(a, b),
        9 => Op::Sub(a, b),
        10 => Op::Mul(a, b),
        11 => Op::Div(a, b),
        12 => Op::Min(a, b),
        13 => Op::Max(a, b),
        14 => Op::Pow(a, b),
        15 => Op::Atan2(a, b),
        16 => Op::Hash(a, b),
        17 => Op::Lt(a, b),
        18 => Op::Le(a, b),
        19 => Op::Eq(a, b),
        20 => Op::Select(a, b, c),
        _ => return None,
    })
}

/// A seeded random material-like program of about `ops` IR ops: mostly arithmetic, with
/// the mix of transcendentals, comparisons, selects and hashes procedural graphs use; every
/// argument is shaped so values stay finite (exp of negatives, log of 1 + x², …).
pub fn material_like(ops: usize, seed: u64) -> Program {
    // Dead code is removed at the end; generate until what survives has `ops` ops.
    let mut raw = ops;
    loop {
        let prog = material_like_attempt(raw, seed);
        if prog.op_count() >= ops || raw > ops * 4 {
            return prog;
        }
        raw += raw / 8 + 1;
    }
}

fn material_like_attempt(raw: usize, seed: u64) -> Program {
    let mut r = SplitMix64::new(seed ^ 0x5053_4342_454E_4348);
    let mut b = Builder::new();
    let mut pool: Vec<NodeId> = vec![b.u(), b.v()];
    for p in 0..8 {
        pool.push(b.param(p));
    }
    for _ in 0..4 {
        let c = b.constant((r.next_f32() * 8.0 - 4.0).round() / 2.0 + 0.25);
        pool.push(c);
    }
    let leaves = b.len();
    // Prefer recent nodes so the program has depth, like chained graph nodes.
    let pick = |r: &mut SplitMix64, pool: &[NodeId]| pool[pool.len() - 1 - r.below(pool.len().min(24))];
    let mut guard = 0;
    while b.len() - leaves < raw && guard < raw * 20 {
        guard += 1;
        let (x, y, z) = (pick(&mut r, &pool), pick(&mut r, &pool), pick(&mut r, &pool));
        let one = b.constant(1.0);
        let node = match r.below(100) {
            0..=19 => b.add(x, y),
            20..=31 => b.sub(x, y),
            32..=51 => b.mul(x, y),
            52..=57 => b.sin(x),
            58..=61 => b.cos(x),
            62..=64 => {
                let a = b.abs(x);
                let n = b.neg(a);
                b.exp(n)
            }
            65..=67 => {
                let s = b.mul(x, x);
                let t = b.add(one, s);
                b.log(t)
            }
            68..=69 => {
                let a = b.abs(x);
                let t = b.add(one, a);
                let e = b.sin(y);
                b.pow(t, e)
            }
            70..=71 => b.atan2(x, y),
            72..=74 => b.fract(x),
            75..=76 => {
                let s = b.scale(16.0, x);
                b.hash(s, y)
            }
            77..=80 => b.min(x, y),
            81..=84 => b.max(x, y),
            85..=88 => {
                let c = b.lt(x, y);
                b.select(c, y, z)
            }
            89..=92 => {
                let a = b.abs(x);
                b.sqrt(a)
            }
            93..=95 => {
                let d = b.mul(y, y);
                let d = b.add(one, d);
                b.div(x, d)
            }
            _ => b.scale(0.5, x),
        };
        // Renormalise now and then, as graphs do with mix/clamp, so magnitudes stay sane:
        // a soft clamp x / (1 + |x|) or a periodic remap.
        let node = match r.below(6) {
            0 | 1 => {
                let a = b.abs(node);
                let d = b.add(one, a);
                b.div(node, d)
            }
            2 => b.sin(node),
            _ => node,
        };
        pool.push(node);
    }
    let names = ["albedo.r", "albedo.g", "albedo.b", "roughness", "height"];
    let outputs = names
        .iter()
        .enumerate()
        .map(|(k, name)| Output { name: (*name).into(), node: pool[pool.len() - 1 - 3 * k] })
        .collect();
    let mut prog = b.finish(outputs);
    prog.eliminate_dead_code();
    prog
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_kind_is_numbered_once_in_declaration_order() {
        let (a, b, c) = (NodeId(0), NodeId(1), NodeId(2));
        let names: Vec<&str> = (0..NON_LEAF_KINDS).map(|k| non_leaf_op(k, a, b, c).unwrap().mnemonic()).collect();
        let mut unique = names.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), NON_LEAF_KINDS, "{names:?}");
        assert!((0..NON_LEAF_KINDS).all(|k| !non_leaf_op(k, a, b, c).unwrap().is_leaf()));
        assert_eq!(non_leaf_op(NON_LEAF_KINDS, a, b, c), None);
        assert_eq!(names[0], "neg");
        assert_eq!(names[NON_LEAF_KINDS - 1], "select");
    }

    #[test]
    fn the_material_like_workload_is_deterministic_valid_and_large_enough() {
        let a = material_like(300, 7);
        assert_eq!(a, material_like(300, 7));
        assert_ne!(a, material_like(300, 8));
        for seed in 1..6 {
            let p = material_like(300, seed);
            assert!(p.op_count() >= 300, "{} ops", p.op_count());
            p.validate().unwrap();
            // NaN/inf (and their slow paths) would make a benchmark unrepresentative: finite
            // everywhere on a 32×32 grid, at parameters like psc bench's.
            let params: Vec<f32> = (0..p.num_params).map(|i| 0.3 + 0.37 * ((i * 7) % 11) as f32 / 11.0).collect();
            let grid: Vec<f32> = (0..32).map(|k| (k as f32 + 0.5) / 32.0).collect();
            let u: Vec<f32> = grid.iter().flat_map(|_| grid.iter().copied()).collect();
            let v: Vec<f32> = grid.iter().flat_map(|&y| std::iter::repeat_n(y, 32)).collect();
            let out = crate::interp::eval(&p, &params, &crate::interp::Batch { u: &u, v: &v, seeds: &[] });
            assert!(out.iter().flatten().all(|x| x.is_finite()), "seed {seed}: the workload should stay finite");
        }
    }
}
