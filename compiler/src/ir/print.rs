//! The textual IR dump used by `psc compile --emit ir` and the golden tests.
//!
//! One node per line, `%id = mnemonic operands`, then one line per output. Stable across runs:
//! it depends only on the program.

use std::fmt::{self, Write as _};

use super::{Op, Program};

impl fmt::Display for Program {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        writeln!(
            f,
            "; {} nodes, {} ops, {} params, {} seeds",
            self.nodes.len(),
            self.op_count(),
            self.num_params,
            self.num_seeds
        )?;
        for (i, op) in self.nodes.iter().enumerate() {
            let mut line = format!("%{i} = {}", op.mnemonic());
            match *op {
                Op::Const(bits) => {
                    let _ = write!(line, " {:?}", f32::from_bits(bits));
                }
                Op::Param(p) | Op::Seed(p) => {
                    let _ = write!(line, " {p}");
                }
                _ => {
                    for (k, operand) in op.operands().enumerate() {
                        let _ = write!(line, "{}{operand}", if k == 0 { " " } else { ", " });
                    }
                }
            }
            writeln!(f, "{line}")?;
        }
        for out in &self.outputs {
            writeln!(f, "out {} = {}", out.name, out.node)?;
        }
        Ok(())
    }
}
