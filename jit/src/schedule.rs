//! Instruction scheduling of the kernel's loop body, before cranelift lowers it.
//!
//! The IR arrives in the order the graph was built: mostly depth first, one subexpression
//! finished before the next begins. On an out-of-order core that order is latency-bound
//! (llvm-mca on library kernels: 55–90% of cycles waiting on register dependencies, 2–2.6x
//! the resource bound), because the reorder window cannot reach the independent work that
//! lies hundreds of instructions further on. Cranelift does not schedule at `opt_level =
//! "none"`, and its `"speed"` elaboration only sinks pure instructions to their uses.
//!
//! So the body block is list-scheduled here: among the instructions whose operands are
//! ready, the one with the longest latency-weighted path to the end of the block goes first
//! (interleaving independent chains), unless the number of live vector values has reached
//! [`MAX_LIVE`], in which case the instruction that frees the most registers goes first (ties
//! in the original order, which is the low-pressure one).
//! Single-use address arithmetic, constants and loads (every leaf is re-emitted at each use,
//! see `codegen`) are not scheduled on their own: they are placed right before their one
//! consumer, so they never hold a register across other work.
//!
//! Only the order changes. Dependencies are SSA uses plus the original order of stores, and
//! loads read memory no store of the kernel writes (inputs, parameter and constant tables,
//! never the output columns), so any topological order computes the same values bit for bit
//! (`tests/against_interp.rs` runs scheduled and unscheduled kernels against the mirror).
//!
//! Measured with `tools/jit_mca.sh` (llvm-mca, znver3) on the 30 library graphs: see
//! ARCHITECTURE.md. Interleaving two texel vectors per iteration (`Options::groups = 2`)
//! exposes more parallelism (20–45% fewer cycles) but costs 2.5–4x the compile time, so it is
//! not the default.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};

use cranelift_codegen::ir::{Block, Function, Inst, InstructionData, Opcode, Value, ValueDef};

/// Live vector values the scheduler aims to stay under (x86-64 has 16 xmm registers; the
/// rest is headroom for temporaries inside lowered sequences and for the glued loads).
pub(crate) const MAX_LIVE: usize = 12;

/// Rough result latencies (cycles) of the lowered instructions, for the critical path only.
fn latency(op: Opcode) -> u32 {
    match op {
        Opcode::Fdiv => 11,
        Opcode::Sqrt => 15,
        Opcode::Fma | Opcode::Fmul | Opcode::Fadd | Opcode::Fsub => 3,
        Opcode::Imul => 4,
        Opcode::X86Cvtt2dq | Opcode::FcvtToSintSat | Opcode::FcvtFromSint => 4,
        Opcode::Floor | Opcode::Nearest | Opcode::Ceil | Opcode::Trunc => 3,
        Opcode::Load => 4,
        Opcode::Fcmp | Opcode::Icmp => 2,
        _ => 1,
    }
}

/// Reorders the instructions of `block` (all but its terminator); see the module docs.
pub(crate) fn schedule_block(func: &mut Function, block: Block, max_live: usize) {
    let insts: Vec<Inst> = func.layout.block_insts(block).collect();
    let Some((&terminator, body)) = insts.split_last() else { return };
    let n = body.len();
    let position: HashMap<Inst, usize> = body.iter().enumerate().map(|(k, &inst)| (inst, k)).collect();
    let producer = |v: Value| match func.dfg.value_def(func.dfg.resolve_aliases(v)) {
        ValueDef::Result(inst, _) => position.get(&inst).copied(),
        _ => None,
    };

    // Direct operands (producer indices within the body) plus the store chain.
    let mut operands: Vec<Vec<usize>> = vec![Vec::new(); n];
    let mut use_count = vec![0usize; n];
    let mut last_store: Option<usize> = None;
    for (k, &inst) in body.iter().enumerate() {
        operands[k].extend(func.dfg.inst_values(inst).filter_map(producer));
        if func.dfg.insts[inst].opcode().can_store() {
            operands[k].extend(last_store);
            last_store = Some(k);
        }
        operands[k].sort_unstable();
        operands[k].dedup();
        for &p in &operands[k] {
            use_count[p] += 1;
        }
    }
    for p in func.dfg.inst_values(terminator).filter_map(producer) {
        use_count[p] += 2; // never glued
    }

    // Glued: single-use loads, constants and scalar (address) arithmetic.
    let glued: Vec<bool> = (0..n)
        .map(|k| {
            let data = &func.dfg.insts[body[k]];
            let results = func.dfg.inst_results(body[k]);
            let scalar = results.len() == 1 && !func.dfg.value_type(results[0]).is_vector();
            let cheap = matches!(data, InstructionData::Load { .. })
                || matches!(data.opcode(), Opcode::Iconst | Opcode::Vconst)
                || scalar;
            cheap && use_count[k] == 1 && !data.opcode().can_store()
        })
        .collect();
    let defines_vector: Vec<bool> = body
        .iter()
        .map(|&inst| func.dfg.inst_results(inst).iter().any(|&r| func.dfg.value_type(r).is_vector()))
        .collect();

    // The graph between scheduled (non-glued) instructions: a glued operand tree stands for
    // the non-glued instructions at its leaves.
    let mut deps: Vec<Vec<usize>> = vec![Vec::new(); n];
    for k in (0..n).filter(|&k| !glued[k]) {
        let mut stack: Vec<usize> = operands[k].clone();
        while let Some(p) = stack.pop() {
            if glued[p] {
                stack.extend(&operands[p]);
            } else {
                deps[k].push(p);
            }
        }
        deps[k].sort_unstable();
        deps[k].dedup();
    }
    let mut dependents: Vec<Vec<usize>> = vec![Vec::new(); n];
    for (k, ks_deps) in deps.iter().enumerate() {
        for &p in ks_deps {
            dependents[p].push(k);
        }
    }

    // Critical path: latency-weighted longest path to the end of the block.
    let mut path = vec![0u32; n];
    for k in (0..n).rev().filter(|&k| !glued[k]) {
        let own = latency(func.dfg.insts[body[k]].opcode());
        path[k] = own + dependents[k].iter().map(|&u| path[u]).max().unwrap_or(0);
    }

    let mut waiting: Vec<usize> = deps.iter().map(Vec::len).collect();
    let mut remaining_users: Vec<usize> = dependents.iter().map(Vec::len).collect();
    let mut order: Vec<usize> = Vec::with_capacity(n);
    let mut placed = vec![false; n];
    let mut live = 0i64;
    // Registers an instruction occupies (its vector result, if anything uses it) minus the
    // ones it frees (vector operands it is the last user of).
    let net = |k: usize, remaining_users: &[usize]| -> i64 {
        let frees = deps[k].iter().filter(|&&p| defines_vector[p] && remaining_users[p] == 1).count() as i64;
        i64::from(defines_vector[k] && !dependents[k].is_empty()) - frees
    };
    // The ready instructions, in two heaps (a scan of the ready list per step was quadratic:
    // in a long chain's adjoint thousands of instructions wait ready at once). By critical
    // path (fixed keys); and by net register change, whose keys only fall (an operand whose
    // other users are all placed becomes freeable), so a fall pushes a fresh entry and an
    // entry whose key is no longer current is skipped. Ties go to the lower index, as the
    // keys include it, so the order is that of picking the best of the whole ready set.
    let mut by_path: BinaryHeap<(u32, Reverse<usize>)> = BinaryHeap::new();
    let mut by_net: BinaryHeap<Reverse<(i64, usize)>> = BinaryHeap::new();
    let mut ready = 0usize;
    for k in (0..n).filter(|&k| !glued[k] && deps[k].is_empty()) {
        by_path.push((path[k], Reverse(k)));
        by_net.push(Reverse((net(k, &remaining_users), k)));
        ready += 1;
    }
    while ready > 0 {
        let k = if live >= max_live as i64 {
            loop {
                let Reverse((key, k)) = by_net.pop().expect("every ready instruction has an entry");
                if !placed[k] && key == net(k, &remaining_users) {
                    break k;
                }
            }
        } else {
            loop {
                let (_, Reverse(k)) = by_path.pop().expect("every ready instruction has an entry");
                if !placed[k] {
                    break k;
                }
            }
        };
        ready -= 1;
        live += net(k, &remaining_users);
        place(k, &glued, &operands, &mut placed, &mut order);
        for &p in &deps[k] {
            remaining_users[p] -= 1;
            if remaining_users[p] == 1 && defines_vector[p] {
                // p's last user frees it now: if that user is ready, its key fell.
                let last = dependents[p].iter().copied().find(|&u| !placed[u]).expect("one user remains");
                if waiting[last] == 0 {
                    by_net.push(Reverse((net(last, &remaining_users), last)));
                }
            }
        }
        for &u in &dependents[k] {
            waiting[u] -= 1;
            if waiting[u] == 0 {
                by_path.push((path[u], Reverse(u)));
                by_net.push(Reverse((net(u, &remaining_users), u)));
                ready += 1;
            }
        }
    }
    debug_assert_eq!(order.len(), n, "every instruction of the block is placed exactly once");

    for &inst in &insts {
        func.layout.remove_inst(inst);
    }
    for &k in &order {
        func.layout.append_inst(body[k], block);
    }
    func.layout.append_inst(terminator, block);
}

/// Appends `k` to `order`, first appending its glued operand tree (operands before users).
fn place(k: usize, glued: &[bool], operands: &[Vec<usize>], placed: &mut [bool], order: &mut Vec<usize>) {
    for &p in &operands[k] {
        if glued[p] && !placed[p] {
            place(p, glued, operands, placed, order);
        }
    }
    placed[k] = true;
    order.push(k);
}
