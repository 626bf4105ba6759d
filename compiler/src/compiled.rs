//! A compiled graph: its public description (parameters, slots) and forward program, whose
//! outputs are the [`crate::Channel`]s in order.

use std::path::PathBuf;
use std::time::Duration;

use crate::diff::reverse::Adjoint;
use crate::ir::Program;

#[derive(Clone, Debug, PartialEq)]
pub enum ParamKind {
    /// A float in `[min, max]`; differentiable.
    Continuous { min: f32, max: f32 },
    /// An integer in `[min, max]`; searched, never differentiated.
    Discrete { min: i64, max: i64 },
    /// Three linear channels, each in `[0, 1]`; differentiable.
    Color,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ParamInfo {
    pub name: String,
    pub doc: Option<String>,
    pub kind: ParamKind,
    /// One value, or three for a colour (linear).
    pub default: Vec<f32>,
    /// First IR parameter slot; a colour occupies three consecutive slots.
    pub slot: usize,
}

impl ParamInfo {
    pub fn width(&self) -> usize {
        self.default.len()
    }
    pub fn is_continuous(&self) -> bool {
        !matches!(self.kind, ParamKind::Discrete { .. })
    }
    /// The valid interval of each slot of this parameter.
    pub fn bounds(&self) -> (f32, f32) {
        match self.kind {
            ParamKind::Continuous { min, max } => (min, max),
            ParamKind::Discrete { min, max } => (min as f32, max as f32),
            ParamKind::Color => (0.0, 1.0),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct GraphInfo {
    pub name: String,
    pub category: String,
    pub description: String,
    pub doc: Option<String>,
    pub file: PathBuf,
    pub params: Vec<ParamInfo>,
    /// Whether the graph defines `height` (its normal is then derived from it).
    pub has_height: bool,
}

impl GraphInfo {
    pub fn num_slots(&self) -> usize {
        self.params.iter().map(ParamInfo::width).sum()
    }

    /// The parameter vector at every parameter's default.
    pub fn default_params(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.num_slots()];
        for p in &self.params {
            out[p.slot..p.slot + p.width()].copy_from_slice(&p.default);
        }
        out
    }

    /// Slots of continuous parameters and colour channels: the ones gradients are taken for.
    pub fn continuous_slots(&self) -> Vec<u32> {
        self.params
            .iter()
            .filter(|p| p.is_continuous())
            .flat_map(|p| (p.slot..p.slot + p.width()).map(|s| s as u32))
            .collect()
    }

    pub fn param(&self, name: &str) -> Option<&ParamInfo> {
        self.params.iter().find(|p| p.name == name)
    }
}

#[derive(Clone, Debug)]
pub struct CompileStats {
    /// Node insertions the lowering asked for, before hash-consing and folding removed any.
    pub requested_nodes: usize,
    /// The lowering's work: expressions evaluated plus nodes requested, against
    /// [`crate::lower::MAX_LOWERING_WORK`].
    pub lowering_work: usize,
    /// Nodes after hash-consing and folding, before dead-code elimination.
    pub nodes_before_dce: usize,
    /// Non-leaf nodes of the final forward program.
    pub forward_ops: usize,
    pub lower_time: Duration,
}

#[derive(Clone, Debug)]
pub struct CompiledGraph {
    pub info: GraphInfo,
    /// Outputs: [`crate::Channel::ALL`], in order.
    pub forward: Program,
    pub stats: CompileStats,
}

impl CompiledGraph {
    /// The fused forward + adjoint program for the continuous parameters, with its layout
    /// (see [`crate::diff::reverse::AdjointLayout`]).
    pub fn adjoint(&self) -> Adjoint {
        crate::diff::reverse::adjoint(&self.forward, &self.info.continuous_slots())
    }

    /// `psc compile --emit ir` for this graph: a header naming it and its file, then the
    /// forward program ([`Program`]'s `Display`, one node per line).
    pub fn ir_dump(&self) -> String {
        format!("; graph {} ({})\n{}", self.info.name, self.info.file.display(), self.forward)
    }

    /// `psc compile --emit adjoint` for this graph and its `adjoint`: a header, the layout, then
    /// the fused program.
    pub fn adjoint_dump(&self, adjoint: &Adjoint) -> String {
        format!(
            "; adjoint of graph {} ({})\n; layout: {}\n{}",
            self.info.name,
            self.info.file.display(),
            adjoint.layout,
            adjoint.program
        )
    }
}
