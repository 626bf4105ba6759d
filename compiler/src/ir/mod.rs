//! The scalar expression IR every graph lowers to.
//!
//! A [`Program`] is an arena of [`Op`]s addressed by [`NodeId`] handles plus a list of named
//! scalar outputs. Every value is an `f32`; booleans are `0.0` / `1.0`, integers are
//! integer-valued floats.
//!
//! Invariants, established by [`Builder`] and [`Program::eliminate_dead_code`], and checked,
//! one rule at a time, by [`Program::validate`] (see [`validate`] for the exact rules):
//! - **well-formed**: every operand of node `i` has an id `< i` (topological order); every
//!   `Param`/`Seed` slot and output node is in range. This much is all evaluation needs:
//!   [`Program::check_well_formed`], which the JIT requires;
//! - **hash-consed**: no two nodes are the same op on the same operands;
//! - **folded and simplified**: every node is what the [`Builder`] makes of it: no non-leaf node
//!   has only constant operands, no algebraic identity applies, commutative operands are in
//!   canonical order, constants are canonical (no `-0.0`, one NaN);
//! - **no dead code**: every node reaches an output (true after `eliminate_dead_code`).
//!
//! The exact meaning of every op lives in [`semantics`]; the interpreter and the JIT both
//! follow it (the JIT within the stated error of its polynomial transcendentals).

pub mod builder;
pub mod print;
pub mod random;
pub mod semantics;
pub mod validate;

pub use builder::Builder;
pub use validate::InvalidProgram;

use std::fmt;

/// A typed handle to a node of one [`Program`] (or of the [`Builder`] making it).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct NodeId(pub u32);

impl NodeId {
    pub fn index(self) -> usize {
        self.0 as usize
    }
}

impl fmt::Display for NodeId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "%{}", self.0)
    }
}

/// One scalar operation. Leaves first, then by arity.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Op {
    /// A constant, stored as `f32` bits so that `Op` can be hashed.
    Const(u32),
    /// The texel's u coordinate.
    U,
    /// The texel's v coordinate.
    V,
    /// Graph parameter slot `i` (continuous, colour channel, or discrete int as a float).
    Param(u32),
    /// Adjoint programs only: the incoming gradient of forward output `i` at this texel.
    Seed(u32),

    Neg(NodeId),
    Abs(NodeId),
    Floor(NodeId),
    /// `sqrt(max(x, 0))`.
    Sqrt(NodeId),
    Sin(NodeId),
    Cos(NodeId),
    /// `exp(x)`.
    Exp(NodeId),
    /// Natural log, `ln(max(x, f32::MIN_POSITIVE))`.
    Log(NodeId),

    Add(NodeId, NodeId),
    Sub(NodeId, NodeId),
    Mul(NodeId, NodeId),
    /// IEEE division.
    Div(NodeId, NodeId),
    /// `if a < b { a } else { b }`.
    Min(NodeId, NodeId),
    /// `if a > b { a } else { b }`.
    Max(NodeId, NodeId),
    /// `if a > 0 { a^b } else { 0 }`.
    Pow(NodeId, NodeId),
    /// `atan2(y, x)` in `(-pi, pi]`, with `atan2(0, 0) = 0`.
    Atan2(NodeId, NodeId),
    /// Integer hash of `(trunc(a), trunc(b))` to `[0, 1)` in steps of `2^-24`; see
    /// [`semantics::hash`]. Piecewise constant: its derivative is zero.
    Hash(NodeId, NodeId),
    /// `1.0` if `a < b`, else `0.0` (NaN compares false).
    Lt(NodeId, NodeId),
    /// `1.0` if `a <= b`, else `0.0`.
    Le(NodeId, NodeId),
    /// `1.0` if `a == b`, else `0.0`.
    Eq(NodeId, NodeId),

    /// `if c != 0 { a } else { b }`.
    Select(NodeId, NodeId, NodeId),
}

impl Op {
    pub fn constant(x: f32) -> Op {
        // One NaN and one zero, so that hash-consing sees equal values as equal.
        let x = if x.is_nan() {
            f32::NAN
        } else if x == 0.0 {
            0.0
        } else {
            x
        };
        Op::Const(x.to_bits())
    }

    pub fn as_const(&self) -> Option<f32> {
        match *self {
            Op::Const(bits) => Some(f32::from_bits(bits)),
            _ => None,
        }
    }

    pub fn is_leaf(&self) -> bool {
        matches!(self, Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_))
    }

    /// The operands, in order.
    pub fn operands(&self) -> OperandIter {
        let (ids, len): ([NodeId; 3], usize) = match *self {
            Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_) => ([NodeId(0); 3], 0),
            Op::Neg(a)
            | Op::Abs(a)
            | Op::Floor(a)
            | Op::Sqrt(a)
            | Op::Sin(a)
            | Op::Cos(a)
            | Op::Exp(a)
            | Op::Log(a) => ([a, NodeId(0), NodeId(0)], 1),
            Op::Add(a, b)
            | Op::Sub(a, b)
            | Op::Mul(a, b)
            | Op::Div(a, b)
            | Op::Min(a, b)
            | Op::Max(a, b)
            | Op::Pow(a, b)
            | Op::Atan2(a, b)
            | Op::Hash(a, b)
            | Op::Lt(a, b)
            | Op::Le(a, b)
            | Op::Eq(a, b) => ([a, b, NodeId(0)], 2),
            Op::Select(c, a, b) => ([c, a, b], 3),
        };
        OperandIter { ids, len, pos: 0 }
    }

    /// The same op with every operand passed through `f`.
    pub fn map_operands(&self, mut f: impl FnMut(NodeId) -> NodeId) -> Op {
        match *self {
            Op::Const(_) | Op::U | Op::V | Op::Param(_) | Op::Seed(_) => *self,
            Op::Neg(a) => Op::Neg(f(a)),
            Op::Abs(a) => Op::Abs(f(a)),
            Op::Floor(a) => Op::Floor(f(a)),
            Op::Sqrt(a) => Op::Sqrt(f(a)),
            Op::Sin(a) => Op::Sin(f(a)),
            Op::Cos(a) => Op::Cos(f(a)),
            Op::Exp(a) => Op::Exp(f(a)),
            Op::Log(a) => Op::Log(f(a)),
            Op::Add(a, b) => Op::Add(f(a), f(b)),
            Op::Sub(a, b) => Op::Sub(f(a), f(b)),
            Op::Mul(a, b) => Op::Mul(f(a), f(b)),
            Op::Div(a, b) => Op::Div(f(a), f(b)),
            Op::Min(a, b) => Op::Min(f(a), f(b)),
            Op::Max(a, b) => Op::Max(f(a), f(b)),
            Op::Pow(a, b) => Op::Pow(f(a), f(b)),
            Op::Atan2(a, b) => Op::Atan2(f(a), f(b)),
            Op::Hash(a, b) => Op::Hash(f(a), f(b)),
            Op::Lt(a, b) => Op::Lt(f(a), f(b)),
            Op::Le(a, b) => Op::Le(f(a), f(b)),
            Op::Eq(a, b) => Op::Eq(f(a), f(b)),
            Op::Select(c, a, b) => Op::Select(f(c), f(a), f(b)),
        }
    }

    /// Lower-case mnemonic used in IR dumps.
    pub fn mnemonic(&self) -> &'static str {
        match self {
            Op::Const(_) => "const",
            Op::U => "u",
            Op::V => "v",
            Op::Param(_) => "param",
            Op::Seed(_) => "seed",
            Op::Neg(_) => "neg",
            Op::Abs(_) => "abs",
            Op::Floor(_) => "floor",
            Op::Sqrt(_) => "sqrt",
            Op::Sin(_) => "sin",
            Op::Cos(_) => "cos",
            Op::Exp(_) => "exp",
            Op::Log(_) => "log",
            Op::Add(..) => "add",
            Op::Sub(..) => "sub",
            Op::Mul(..) => "mul",
            Op::Div(..) => "div",
            Op::Min(..) => "min",
            Op::Max(..) => "max",
            Op::Pow(..) => "pow",
            Op::Atan2(..) => "atan2",
            Op::Hash(..) => "hash",
            Op::Lt(..) => "lt",
            Op::Le(..) => "le",
            Op::Eq(..) => "eq",
            Op::Select(..) => "select",
        }
    }
}

pub struct OperandIter {
    ids: [NodeId; 3],
    len: usize,
    pos: usize,
}

impl Iterator for OperandIter {
    type Item = NodeId;
    fn next(&mut self) -> Option<NodeId> {
        if self.pos < self.len {
            self.pos += 1;
            Some(self.ids[self.pos - 1])
        } else {
            None
        }
    }
}

/// A named scalar result of a program (`albedo.r`, `d_param3`, …).
#[derive(Clone, Debug, PartialEq)]
pub struct Output {
    pub name: String,
    pub node: NodeId,
}

/// A finished, immutable IR program.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    pub nodes: Vec<Op>,
    pub outputs: Vec<Output>,
    /// Number of parameter slots the program reads (`Param(i)` has `i < num_params`).
    pub num_params: usize,
    /// Number of seed inputs (`Seed(i)` has `i < num_seeds`); zero for forward programs.
    pub num_seeds: usize,
}

impl Program {
    pub fn op(&self, id: NodeId) -> Op {
        self.nodes[id.index()]
    }

    /// Non-leaf nodes: the arithmetic a kernel actually performs per texel.
    pub fn op_count(&self) -> usize {
        self.nodes.iter().filter(|op| !op.is_leaf()).count()
    }

    pub fn output(&self, name: &str) -> Option<NodeId> {
        self.outputs.iter().find(|o| o.name == name).map(|o| o.node)
    }

    /// Removes nodes no output reaches and renumbers the rest, keeping their order.
    pub fn eliminate_dead_code(&mut self) {
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
        let mut remap = vec![NodeId(u32::MAX); self.nodes.len()];
        let mut kept = Vec::with_capacity(self.nodes.len());
        for (i, op) in self.nodes.iter().enumerate() {
            if live[i] {
                remap[i] = NodeId(kept.len() as u32);
                kept.push(op.map_operands(|a| remap[a.index()]));
            }
        }
        self.nodes = kept;
        for out in &mut self.outputs {
            out.node = remap[out.node.index()];
        }
    }

    /// How many times each node is used as an operand or output (for register allocation and
    /// for deciding which nodes a kernel must keep alive).
    pub fn use_counts(&self) -> Vec<u32> {
        let mut uses = vec![0u32; self.nodes.len()];
        for op in &self.nodes {
            for operand in op.operands() {
                uses[operand.index()] += 1;
            }
        }
        for out in &self.outputs {
            uses[out.node.index()] += 1;
        }
        uses
    }
}
