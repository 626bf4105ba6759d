//! Checking the IR invariants of the module docs, rule by rule.
//!
//! [`Program::check_well_formed`] is what evaluating a program needs (the JIT requires it of
//! every program it compiles, canonical or not); [`Program::validate`] adds what the compiler
//! guarantees of every program it hands out (forward and adjoint): hash-consed, folded and
//! simplified exactly as the [`Builder`] would, and free of dead code. Each violation is its
//! own [`InvalidProgram`] variant, so tests can build a program that breaks one rule and see
//! that rule, and no other, reported.

use std::collections::HashMap;
use std::fmt;

use super::{Builder, NodeId, Op, Program};

/// The first rule a program breaks, and where.
#[derive(Clone, Debug, PartialEq)]
pub enum InvalidProgram {
    /// Well-formedness: `node` uses `operand`, which is not defined before it.
    NotTopological { node: NodeId, operand: NodeId },
    /// Well-formedness: `node` reads parameter or seed `slot` of a program that has `count`.
    SlotOutOfRange { node: NodeId, kind: &'static str, slot: u32, count: usize },
    /// Well-formedness: an output names a node past the end.
    OutputOutOfRange { output: String, node: NodeId },
    /// Hash-consing: `node` is the same op on the same operands as `first`.
    Duplicate { node: NodeId, first: NodeId },
    /// Folding: a constant the builder would have stored differently (`-0.0`, a NaN payload).
    NonCanonicalConstant { node: NodeId },
    /// Folding: a non-leaf node whose operands are all constants.
    Unfolded { node: NodeId },
    /// Simplification: the builder turns `node` into something else (an identity such as
    /// `x * 1` applies, or commutative operands are out of canonical order).
    NotSimplified { node: NodeId, op: Op },
    /// Dead code: `node` reaches no output.
    Dead { node: NodeId },
}

impl fmt::Display for InvalidProgram {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            InvalidProgram::NotTopological { node, operand } => {
                write!(f, "{node} uses {operand}, which is not defined before it")
            }
            InvalidProgram::SlotOutOfRange { node, kind, slot, count } => {
                write!(f, "{node} reads {kind} {slot} but the program has {count}")
            }
            InvalidProgram::OutputOutOfRange { output, node } => {
                write!(f, "output `{output}` is {node}, past the end of the program")
            }
            InvalidProgram::Duplicate { node, first } => {
                write!(f, "{node} duplicates {first} (the program is not hash-consed)")
            }
            InvalidProgram::NonCanonicalConstant { node } => {
                write!(f, "{node} is a constant in non-canonical form (-0 or a NaN payload)")
            }
            InvalidProgram::Unfolded { node } => write!(f, "{node} has only constant operands (not folded)"),
            InvalidProgram::NotSimplified { node, op } => {
                write!(f, "{node} ({}) is not in the builder's simplified form: {op:?}", op.mnemonic())
            }
            InvalidProgram::Dead { node } => write!(f, "{node} reaches no output (dead code)"),
        }
    }
}

impl std::error::Error for InvalidProgram {}

impl Program {
    /// Topological order and every slot and output in range: what evaluating the program (by
    /// the interpreter or the JIT) relies on.
    pub fn check_well_formed(&self) -> Result<(), InvalidProgram> {
        for (i, op) in self.nodes.iter().enumerate() {
            let node = NodeId(i as u32);
            if let Some(operand) = op.operands().find(|a| a.index() >= i) {
                return Err(InvalidProgram::NotTopological { node, operand });
            }
            let (kind, slot, count) = match *op {
                Op::Param(p) => ("param", p, self.num_params),
                Op::Seed(s) => ("seed", s, self.num_seeds),
                _ => continue,
            };
            if slot as usize >= count {
                return Err(InvalidProgram::SlotOutOfRange { node, kind, slot, count });
            }
        }
        if let Some(out) = self.outputs.iter().find(|o| o.node.index() >= self.nodes.len()) {
            return Err(InvalidProgram::OutputOutOfRange { output: out.name.clone(), node: out.node });
        }
        Ok(())
    }

    /// Every invariant of the module docs: well-formed, hash-consed, folded and simplified, no
    /// dead code. Every program the compiler returns (lowered forward programs, adjoints,
    /// derivative programs after dead-code elimination) passes.
    ///
    /// "Simplified" is checked by replaying the program through a fresh [`Builder`]: node `i`
    /// must come back as itself, at id `i`. So the rules checked are exactly the builder's, and
    /// a new simplification in the builder is checked here without further code.
    pub fn validate(&self) -> Result<(), InvalidProgram> {
        self.check_well_formed()?;
        let mut first_of: HashMap<Op, NodeId> = HashMap::with_capacity(self.nodes.len());
        let mut replay = Builder::new();
        for (i, &op) in self.nodes.iter().enumerate() {
            let node = NodeId(i as u32);
            if let Some(&first) = first_of.get(&op) {
                return Err(InvalidProgram::Duplicate { node, first });
            }
            first_of.insert(op, node);
            if let Some(x) = op.as_const() {
                if Op::constant(x) != op {
                    return Err(InvalidProgram::NonCanonicalConstant { node });
                }
            }
            if !op.is_leaf() && op.operands().all(|a| self.nodes[a.index()].as_const().is_some()) {
                return Err(InvalidProgram::Unfolded { node });
            }
            // The replay has exactly nodes 0..i, equal to this program's (checked so far).
            let got = replay.push(op);
            if got != node || replay.op(got) != op {
                return Err(InvalidProgram::NotSimplified { node, op });
            }
        }
        let mut live = vec![false; self.nodes.len()];
        for out in &self.outputs {
            live[out.node.index()] = true;
        }
        for i in (0..self.nodes.len()).rev() {
            if live[i] {
                for operand in self.nodes[i].operands() {
                    live[operand.index()] = true;
                }
            }
        }
        match live.iter().position(|&l| !l) {
            Some(i) => Err(InvalidProgram::Dead { node: NodeId(i as u32) }),
            None => Ok(()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ir::Output;

    fn program(nodes: Vec<Op>, outputs: &[u32]) -> Program {
        let outputs = outputs.iter().map(|&n| Output { name: format!("o{n}"), node: NodeId(n) }).collect();
        Program { nodes, outputs, num_params: 1, num_seeds: 0 }
    }

    fn c(x: f32) -> Op {
        Op::Const(x.to_bits())
    }

    const U: NodeId = NodeId(0);
    const V: NodeId = NodeId(1);

    /// One program per rule, each breaking that rule only: `validate` names that rule.
    #[test]
    fn each_rule_is_reported() {
        let fine = program(vec![Op::U, Op::V, Op::Add(U, V), Op::Sin(NodeId(2))], &[3]);
        fine.validate().unwrap();

        type IsExpected = fn(&InvalidProgram) -> bool;
        let cases: Vec<(Program, IsExpected)> = vec![
            (program(vec![Op::U, Op::Sin(NodeId(2)), Op::V], &[1, 2]), |e| {
                matches!(e, InvalidProgram::NotTopological { node: NodeId(1), operand: NodeId(2) })
            }),
            (program(vec![Op::U, Op::Param(3), Op::Mul(U, NodeId(1))], &[2]), |e| {
                matches!(e, InvalidProgram::SlotOutOfRange { kind: "param", slot: 3, count: 1, .. })
            }),
            (program(vec![Op::U, Op::Seed(0), Op::Mul(U, NodeId(1))], &[2]), |e| {
                matches!(e, InvalidProgram::SlotOutOfRange { kind: "seed", slot: 0, count: 0, .. })
            }),
            (program(vec![Op::U, Op::Sin(U)], &[7]), |e| matches!(e, InvalidProgram::OutputOutOfRange { .. })),
            (program(vec![Op::U, Op::Sin(U), Op::Sin(U), Op::Add(NodeId(1), NodeId(2))], &[3]), |e| {
                matches!(e, InvalidProgram::Duplicate { node: NodeId(2), first: NodeId(1) })
            }),
            (program(vec![Op::U, c(-0.0), Op::Max(U, NodeId(1))], &[2]), |e| {
                matches!(e, InvalidProgram::NonCanonicalConstant { node: NodeId(1) })
            }),
            (program(vec![c(2.0), Op::Sin(NodeId(0))], &[1]), |e| {
                matches!(e, InvalidProgram::Unfolded { node: NodeId(1) })
            }),
            // u * 1 is u.
            (program(vec![Op::U, c(1.0), Op::Mul(NodeId(1), U)], &[2]), |e| {
                matches!(e, InvalidProgram::NotSimplified { node: NodeId(2), .. })
            }),
            // add(v, u) is add(u, v) in canonical order (no add(u, v) exists to duplicate).
            (program(vec![Op::U, Op::V, Op::Add(V, U)], &[2]), |e| {
                matches!(e, InvalidProgram::NotSimplified { node: NodeId(2), .. })
            }),
            // neg(neg(u)) is u.
            (program(vec![Op::U, Op::Neg(U), Op::Neg(NodeId(1))], &[2]), |e| {
                matches!(e, InvalidProgram::NotSimplified { node: NodeId(2), .. })
            }),
            (program(vec![Op::U, Op::V, Op::Sin(V)], &[2]), |e| matches!(e, InvalidProgram::Dead { node: NodeId(0) })),
        ];
        for (p, is_expected) in cases {
            let err = p.validate().expect_err(&format!("{p}"));
            assert!(is_expected(&err), "wrong rule reported for\n{p}: {err}");
            assert!(!err.to_string().is_empty());
        }
    }

    /// Well-formedness is a subset: a canonical-form violation is still well-formed.
    #[test]
    fn well_formed_accepts_dead_and_unsimplified_code() {
        let p = program(vec![Op::U, Op::V, c(1.0), Op::Mul(NodeId(2), U), Op::Add(V, U)], &[3]);
        p.check_well_formed().unwrap();
        assert!(p.validate().is_err());
        let bad = program(vec![Op::Sin(NodeId(0))], &[0]);
        assert!(matches!(bad.check_well_formed(), Err(InvalidProgram::NotTopological { .. })));
    }

    /// What the builder makes, after dead-code elimination, validates.
    #[test]
    fn built_programs_validate() {
        let mut b = Builder::new();
        let (u, v, p) = (b.u(), b.v(), b.param(0));
        let one = b.constant(1.0);
        let x = b.mul(one, u);
        let y = b.add(v, x);
        let z = b.mul(y, p);
        let _dead = b.cos(v);
        let s = b.sin(z);
        let mut prog = b.finish(vec![Output { name: "s".into(), node: s }]);
        assert!(matches!(prog.validate(), Err(InvalidProgram::Dead { .. })));
        prog.eliminate_dead_code();
        prog.validate().unwrap();
    }
}
