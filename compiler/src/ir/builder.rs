//! Building IR: every insertion is hash-consed, constant-folded and simplified, so that the
//! invariants of [`super::Program`] hold by construction.

use std::collections::HashMap;

use super::{semantics, NodeId, Op, Output, Program};

#[derive(Clone, Debug, Default)]
pub struct Builder {
    nodes: Vec<Op>,
    dedup: HashMap<Op, NodeId>,
    num_params: usize,
    num_seeds: usize,
    /// Nodes requested before simplification, for the "IR size before optimisation" figure.
    requested: usize,
}

impl Builder {
    pub fn new() -> Self {
        Self::default()
    }

    /// A builder that continues an existing program (its nodes keep their ids).
    pub fn from_program(program: &Program) -> Self {
        let mut b = Builder { num_params: program.num_params, num_seeds: program.num_seeds, ..Default::default() };
        for op in &program.nodes {
            let id = NodeId(b.nodes.len() as u32);
            b.nodes.push(*op);
            b.dedup.insert(*op, id);
        }
        b
    }

    pub fn op(&self, id: NodeId) -> Op {
        self.nodes[id.index()]
    }

    pub fn len(&self) -> usize {
        self.nodes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.nodes.is_empty()
    }

    /// How many node insertions were asked for, including those folded or deduplicated away.
    pub fn requested(&self) -> usize {
        self.requested
    }

    pub fn const_of(&self, id: NodeId) -> Option<f32> {
        self.nodes[id.index()].as_const()
    }

    pub fn finish(self, outputs: Vec<Output>) -> Program {
        Program { nodes: self.nodes, outputs, num_params: self.num_params, num_seeds: self.num_seeds }
    }

    fn intern(&mut self, op: Op) -> NodeId {
        if let Some(&id) = self.dedup.get(&op) {
            return id;
        }
        let id = NodeId(self.nodes.len() as u32);
        self.nodes.push(op);
        self.dedup.insert(op, id);
        id
    }

    pub fn constant(&mut self, x: f32) -> NodeId {
        self.intern(Op::constant(x))
    }
    pub fn u(&mut self) -> NodeId {
        self.intern(Op::U)
    }
    pub fn v(&mut self) -> NodeId {
        self.intern(Op::V)
    }
    pub fn param(&mut self, slot: u32) -> NodeId {
        self.num_params = self.num_params.max(slot as usize + 1);
        self.intern(Op::Param(slot))
    }
    pub fn seed(&mut self, slot: u32) -> NodeId {
        self.num_seeds = self.num_seeds.max(slot as usize + 1);
        self.intern(Op::Seed(slot))
    }
    /// Declares that the program reads at least `n` parameter slots, used or not.
    pub fn reserve_params(&mut self, n: usize) {
        self.num_params = self.num_params.max(n);
    }
    pub fn reserve_seeds(&mut self, n: usize) {
        self.num_seeds = self.num_seeds.max(n);
    }

    /// Inserts any op, simplifying it first. All the named helpers below go through here.
    pub fn push(&mut self, op: Op) -> NodeId {
        self.requested += 1;
        if op.is_leaf() {
            return self.intern(op);
        }
        // Constant folding: every operand constant.
        let mut vals = [0.0f32; 3];
        let mut all_const = true;
        for (k, operand) in op.operands().enumerate() {
            match self.const_of(operand) {
                Some(x) => vals[k] = x,
                None => all_const = false,
            }
        }
        if all_const {
            let x = semantics::eval(&op, vals[0], vals[1], vals[2]).expect("non-leaf op folds");
            return self.constant(x);
        }
        match self.simplify(op) {
            Simplified::Node(id) => id,
            Simplified::Op(op) => self.intern(op),
        }
    }

    /// Algebraic identities and canonical operand order. Identities that would change a NaN
    /// or infinity into a finite number (`x * 0 → 0`) are applied deliberately: kernels treat
    /// non-finite intermediates as errors that the runtime reports, not as values to preserve.
    fn simplify(&mut self, op: Op) -> Simplified {
        use Simplified::{Node, Op as Keep};
        let k = |b: &Builder, id: NodeId| b.const_of(id);
        match op {
            Op::Neg(a) => match self.op(a) {
                Op::Neg(x) => Node(x),
                Op::Sub(x, y) => Node(self.push(Op::Sub(y, x))),
                _ => Keep(op),
            },
            Op::Abs(a) => match self.op(a) {
                Op::Abs(_) | Op::Sqrt(_) | Op::Exp(_) | Op::Hash(..) | Op::Lt(..) | Op::Le(..) | Op::Eq(..) => Node(a),
                Op::Neg(x) => Node(self.push(Op::Abs(x))),
                _ => Keep(op),
            },
            Op::Floor(a) => match self.op(a) {
                Op::Floor(_) | Op::Lt(..) | Op::Le(..) | Op::Eq(..) => Node(a),
                _ => Keep(op),
            },
            Op::Add(a, b) => {
                if k(self, a) == Some(0.0) {
                    return Node(b);
                }
                if k(self, b) == Some(0.0) {
                    return Node(a);
                }
                if let Op::Neg(nb) = self.op(b) {
                    return Node(self.push(Op::Sub(a, nb)));
                }
                if let Op::Neg(na) = self.op(a) {
                    return Node(self.push(Op::Sub(b, na)));
                }
                if a == b {
                    let two = self.constant(2.0);
                    return Node(self.push(Op::Mul(two, a)));
                }
                Keep(Op::Add(a.min(b), a.max(b)))
            }
            Op::Sub(a, b) => {
                if a == b {
                    return Node(self.constant(0.0));
                }
                if k(self, b) == Some(0.0) {
                    return Node(a);
                }
                if k(self, a) == Some(0.0) {
                    return Node(self.push(Op::Neg(b)));
                }
                if let Op::Neg(nb) = self.op(b) {
                    return Node(self.push(Op::Add(a, nb)));
                }
                Keep(op)
            }
            Op::Mul(a, b) => {
                for (x, y) in [(a, b), (b, a)] {
                    match k(self, x) {
                        Some(0.0) => return Node(self.constant(0.0)),
                        Some(1.0) => return Node(y),
                        Some(-1.0) => return Node(self.push(Op::Neg(y))),
                        _ => {}
                    }
                }
                // Constants gather to the left: c1 * (c2 * x) → (c1 c2) * x.
                if let (Some(c1), Op::Mul(p, q)) = (k(self, a), self.op(b)) {
                    if let Some(c2) = k(self, p) {
                        let c = self.constant(c1 * c2);
                        return Node(self.push(Op::Mul(c, q)));
                    }
                }
                if let (Some(c1), Op::Mul(p, q)) = (k(self, b), self.op(a)) {
                    if let Some(c2) = k(self, p) {
                        let c = self.constant(c1 * c2);
                        return Node(self.push(Op::Mul(c, q)));
                    }
                }
                let (lo, hi) = (a.min(b), a.max(b));
                // Keep a constant operand first so the rule above can see it.
                if k(self, hi).is_some() {
                    return Keep(Op::Mul(hi, lo));
                }
                Keep(Op::Mul(lo, hi))
            }
            Op::Div(a, b) => {
                if k(self, a) == Some(0.0) {
                    return Node(self.constant(0.0));
                }
                match k(self, b) {
                    Some(1.0) => Node(a),
                    // Division by a constant is multiplication by its reciprocal when that is
                    // exact (a power of two), so results match the unfolded program bit for bit.
                    Some(c) if c != 0.0 && c.is_finite() && (1.0 / c).is_finite() && is_pow2(c) => {
                        let r = self.constant(1.0 / c);
                        Node(self.push(Op::Mul(r, a)))
                    }
                    _ if a == b => Node(self.constant(1.0)),
                    _ => Keep(op),
                }
            }
            Op::Min(a, b) | Op::Max(a, b) if a == b => Node(a),
            Op::Min(a, b) => Keep(Op::Min(a.min(b), a.max(b))),
            Op::Max(a, b) => Keep(Op::Max(a.min(b), a.max(b))),
            Op::Pow(a, b) => match k(self, b) {
                Some(1.0) => {
                    // pow(a, 1) = a for a > 0, else 0.
                    let zero = self.constant(0.0);
                    Node(self.push(Op::Max(a, zero)))
                }
                _ => Keep(op),
            },
            Op::Select(c, a, b) => {
                if a == b {
                    return Node(a);
                }
                if let Some(cv) = k(self, c) {
                    return Node(if cv != 0.0 { a } else { b });
                }
                Keep(op)
            }
            Op::Lt(a, b) | Op::Le(a, b) | Op::Eq(a, b) if a == b => {
                // x < x is false, x <= x and x == x are true (NaN aside).
                Node(self.constant(if matches!(op, Op::Lt(..)) { 0.0 } else { 1.0 }))
            }
            Op::Eq(a, b) => Keep(Op::Eq(a.min(b), a.max(b))),
            _ => Keep(op),
        }
    }

    // Named constructors, so lowering and differentiation read like math.
    pub fn neg(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Neg(a))
    }
    pub fn abs(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Abs(a))
    }
    pub fn floor(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Floor(a))
    }
    pub fn sqrt(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Sqrt(a))
    }
    pub fn sin(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Sin(a))
    }
    pub fn cos(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Cos(a))
    }
    pub fn exp(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Exp(a))
    }
    pub fn log(&mut self, a: NodeId) -> NodeId {
        self.push(Op::Log(a))
    }
    pub fn add(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Add(a, b))
    }
    pub fn sub(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Sub(a, b))
    }
    pub fn mul(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Mul(a, b))
    }
    pub fn div(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Div(a, b))
    }
    pub fn min(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Min(a, b))
    }
    pub fn max(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Max(a, b))
    }
    pub fn pow(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Pow(a, b))
    }
    pub fn atan2(&mut self, y: NodeId, x: NodeId) -> NodeId {
        self.push(Op::Atan2(y, x))
    }
    pub fn hash(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Hash(a, b))
    }
    pub fn lt(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Lt(a, b))
    }
    pub fn le(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Le(a, b))
    }
    pub fn eq(&mut self, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Eq(a, b))
    }
    pub fn select(&mut self, c: NodeId, a: NodeId, b: NodeId) -> NodeId {
        self.push(Op::Select(c, a, b))
    }
    /// `x - floor(x)`: its derivative is 1 by construction.
    pub fn fract(&mut self, a: NodeId) -> NodeId {
        let f = self.floor(a);
        self.sub(a, f)
    }
    pub fn scale(&mut self, c: f32, a: NodeId) -> NodeId {
        let k = self.constant(c);
        self.mul(k, a)
    }
}

enum Simplified {
    Node(NodeId),
    Op(Op),
}

fn is_pow2(c: f32) -> bool {
    let m = c.abs();
    m.is_normal() && (m.to_bits() & 0x007F_FFFF) == 0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hash_consing_shares_equal_nodes() {
        let mut b = Builder::new();
        let u = b.u();
        let v = b.v();
        let x = b.add(u, v);
        let y = b.add(v, u);
        assert_eq!(x, y, "commutative operands are canonicalised");
        let s1 = b.sin(x);
        let s2 = b.sin(y);
        assert_eq!(s1, s2);
    }

    #[test]
    fn constants_fold_and_identities_apply() {
        let mut b = Builder::new();
        let u = b.u();
        let two = b.constant(2.0);
        let three = b.constant(3.0);
        let six = b.mul(two, three);
        assert_eq!(b.const_of(six), Some(6.0));
        let zero = b.constant(0.0);
        let one = b.constant(1.0);
        assert_eq!(b.add(u, zero), u);
        assert_eq!(b.mul(one, u), u);
        let times_zero = b.mul(u, zero);
        assert_eq!(b.const_of(times_zero), Some(0.0));
        let u_minus_u = b.sub(u, u);
        assert_eq!(b.const_of(u_minus_u), Some(0.0));
        let nn = {
            let n = b.neg(u);
            b.neg(n)
        };
        assert_eq!(nn, u);
        // 2 * (3 * u) → 6 * u
        let t = b.mul(three, u);
        let s = b.mul(two, t);
        match b.op(s) {
            Op::Mul(c, x) => {
                assert_eq!(b.const_of(c), Some(6.0));
                assert_eq!(x, u);
            }
            other => panic!("expected a gathered constant, got {other:?}"),
        }
    }

    #[test]
    fn built_programs_validate() {
        let mut b = Builder::new();
        let u = b.u();
        let p = b.param(2);
        let m = b.mul(u, p);
        let s = b.sin(m);
        let prog = b.finish(vec![Output { name: "x".into(), node: s }]);
        assert_eq!(prog.num_params, 3);
        prog.validate().unwrap();
    }

    #[test]
    fn dead_code_is_removed_and_order_kept() {
        let mut b = Builder::new();
        let u = b.u();
        let v = b.v();
        let _dead = b.sin(v);
        let e = b.exp(u);
        let mut prog = b.finish(vec![Output { name: "e".into(), node: e }]);
        prog.eliminate_dead_code();
        prog.validate().unwrap();
        assert_eq!(prog.nodes.len(), 2);
        assert_eq!(prog.op_count(), 1);
    }
}
