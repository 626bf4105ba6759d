//! Lowering checked graphs to IR: every function call is inlined, every loop unrolled, every
//! value becomes one IR node per scalar component.
//!
//! Runs only on modules that checked clean; the only errors it reports are resource limits.

mod builtins;
mod expr;

use std::cell::RefCell;
use std::collections::HashMap;
use std::rc::Rc;
use std::time::Instant;

use psc_grammar::ast::{self, GraphMember, Span};

use crate::channel::Channel;
use crate::compiled::{CompileStats, CompiledGraph, GraphInfo, ParamInfo, ParamKind};
use crate::diag::{Diagnostic, FileId};
use crate::diff::forward::{ForwardDiff, Wrt};
use crate::ir::{Builder, NodeId, Output};
use crate::module::{ItemRef, ModuleId, ModuleSet};

/// Lowering stops with an error past this many IR nodes: no material needs anywhere near it.
pub const MAX_IR_NODES: usize = 2_000_000;

/// Lowering stops with an error past this much work: expressions evaluated plus IR nodes
/// requested (before hash-consing shares them). The node limit alone cannot bound the work,
/// because hash-consing can fold an exponential number of requests into a few nodes (a
/// function that calls the one below it twice, forty levels deep, is 2^40 inlined calls that
/// share a few hundred nodes). The largest library graph uses under 4,000 (marble, 3,960;
/// `psc compile` prints each graph's figure): a margin of 2,000 times, while running out
/// takes about a second.
pub const MAX_LOWERING_WORK: usize = 8_000_000;

/// A lowered value: one IR node per scalar component, or a record of values.
#[derive(Clone, Debug)]
pub(crate) enum Value {
    /// float, int and bool are one component; vec2 and vec3 two and three.
    Num(Vec<NodeId>),
    Record(Rc<[(String, Value)]>),
}

impl Value {
    pub(crate) fn scalar(id: NodeId) -> Value {
        Value::Num(vec![id])
    }

    pub(crate) fn comps(&self) -> &[NodeId] {
        match self {
            Value::Num(c) => c,
            Value::Record(_) => &[],
        }
    }

    /// Component `k`, broadcasting scalars.
    pub(crate) fn comp(&self, k: usize) -> NodeId {
        let c = self.comps();
        if c.len() == 1 {
            c[0]
        } else {
            c[k]
        }
    }

    pub(crate) fn map_nodes(&self, f: &mut impl FnMut(NodeId) -> NodeId) -> Value {
        match self {
            Value::Num(c) => Value::Num(c.iter().map(|&id| f(id)).collect()),
            Value::Record(fields) => Value::Record(fields.iter().map(|(n, v)| (n.clone(), v.map_nodes(f))).collect()),
        }
    }

    pub(crate) fn for_each_node(&self, f: &mut impl FnMut(NodeId)) {
        match self {
            Value::Num(c) => c.iter().for_each(|&id| f(id)),
            Value::Record(fields) => fields.iter().for_each(|(_, v)| v.for_each_node(f)),
        }
    }
}

/// Boxed: lowering errors are rare, and the happy path should not carry their size.
type Lowered<T> = Result<T, Box<Diagnostic>>;

/// The names a graph body binds, with node values computed on first use.
struct GraphEnv {
    params: HashMap<String, Value>,
    nodes: HashMap<String, ast::Expr>,
    consts: HashMap<String, ast::Expr>,
    values: RefCell<HashMap<String, Value>>,
}

pub(crate) struct Lowerer<'a> {
    set: &'a ModuleSet,
    b: Builder,
    module: ModuleId,
    file: FileId,
    locals: Vec<(String, Value)>,
    graph: Option<Rc<GraphEnv>>,
    consts: HashMap<ItemRef, Value>,
    d_du: ForwardDiff,
    d_dv: ForwardDiff,
    /// Expressions evaluated so far (the other half of the work, besides requested nodes).
    visits: usize,
    /// Call sites being inlined, outermost first: where a budget error came from.
    calls: Vec<(FileId, Span)>,
}

impl<'a> Lowerer<'a> {
    fn new(set: &'a ModuleSet, module: ModuleId) -> Self {
        Lowerer {
            set,
            b: Builder::new(),
            module,
            file: set.module(module).file,
            locals: Vec::new(),
            graph: None,
            consts: HashMap::new(),
            d_du: ForwardDiff::new(Wrt::U),
            d_dv: ForwardDiff::new(Wrt::V),
            visits: 0,
            calls: Vec::new(),
        }
    }

    /// Work done so far, in the units of [`MAX_LOWERING_WORK`].
    fn work(&self) -> usize {
        self.visits + self.b.requested()
    }

    /// Fails once the work budget is spent, at `span` (a call about to be inlined, or a loop
    /// about to run another iteration), naming the outermost call that led there.
    fn check_work(&self, span: Span) -> Lowered<()> {
        if self.work() <= MAX_LOWERING_WORK {
            return Ok(());
        }
        let depth = self.calls.len();
        let mut e = Diagnostic::error(
            self.file,
            span,
            format!(
                "lowering this graph takes more than {MAX_LOWERING_WORK} steps (expressions evaluated and IR nodes \
                 requested); the budget runs out here, {depth} inlined call{} deep",
                if depth == 1 { "" } else { "s" }
            ),
        )
        .with_label("budget exceeded here")
        .with_hint(
            "every call is inlined, so a function that calls another several times, nested level after level, \
             multiplies the work at each level (two calls per level, 40 levels deep, are 2^40 calls); \
             compute a shared value once with `let`, or reduce the nesting, loop counts or octaves",
        );
        if let Some(&(file, outer)) = self.calls.first().filter(|&&(f, s)| (f, s) != (self.file, span)) {
            e = e.with_related(file, outer, "inlined from this call in the graph");
        }
        Err(Box::new(e))
    }

    fn error(&self, span: Span, message: impl Into<String>) -> Box<Diagnostic> {
        Box::new(Diagnostic::error(self.file, span, message))
    }

    fn check_size(&self, span: Span) -> Lowered<()> {
        if self.b.len() > MAX_IR_NODES {
            let mut e = self.error(span, format!("the graph grows past {MAX_IR_NODES} IR nodes here"));
            e.hint = Some("reduce loop counts, octaves or blur taps".into());
            return Err(e);
        }
        Ok(())
    }
}

/// Evaluates a checked, constant expression of `module` to its components (`None` if it is
/// not constant after all).
pub fn const_value(set: &ModuleSet, module: ModuleId, e: &ast::Expr) -> Option<Vec<f32>> {
    let mut l = Lowerer::new(set, module);
    let v = l.lower_expr(e).ok()?;
    v.comps().iter().map(|&id| l.b.const_of(id)).collect()
}

/// Lowers one checked graph to its forward program.
pub fn lower_graph(set: &ModuleSet, module: ModuleId, g: &ast::GraphDef) -> Result<CompiledGraph, Box<Diagnostic>> {
    let started = Instant::now();
    let mut l = Lowerer::new(set, module);
    let mut params = Vec::new();
    let mut env = GraphEnv {
        params: HashMap::new(),
        nodes: HashMap::new(),
        consts: HashMap::new(),
        values: RefCell::new(HashMap::new()),
    };
    let (mut category, mut description) = (String::from("uncategorised"), String::new());
    let mut slot = 0u32;
    for member in &g.members {
        match member {
            GraphMember::Category(c, _) => category = c.name.clone(),
            GraphMember::Description(d, _) => description = d.clone(),
            GraphMember::Param(p) => {
                let default = const_value(set, module, &p.default)
                    .ok_or_else(|| l.error(p.default.span, "internal: parameter default is not constant"))?;
                let range = p.range.as_ref().map(|(lo, hi, _)| {
                    (
                        const_value(set, module, lo).and_then(|v| v.first().copied()).unwrap_or(0.0),
                        const_value(set, module, hi).and_then(|v| v.first().copied()).unwrap_or(1.0),
                    )
                });
                let kind = match (default.len(), range) {
                    (3, _) => ParamKind::Color,
                    (_, Some((min, max))) if p.is_int => ParamKind::Discrete { min: min as i64, max: max as i64 },
                    (_, Some((min, max))) => ParamKind::Continuous { min, max },
                    (_, None) => ParamKind::Continuous { min: 0.0, max: 1.0 },
                };
                let width = default.len() as u32;
                let value = Value::Num((0..width).map(|k| l.b.param(slot + k)).collect());
                env.params.insert(p.name.name.clone(), value);
                params.push(ParamInfo {
                    name: p.name.name.clone(),
                    doc: p.doc.clone(),
                    kind,
                    default,
                    slot: slot as usize,
                });
                slot += width;
            }
            GraphMember::Node { name, value, .. } => {
                env.nodes.insert(name.name.clone(), value.clone());
            }
            GraphMember::Const(c) => {
                env.consts.insert(c.name.name.clone(), c.value.clone());
            }
            GraphMember::Output { .. } => {}
        }
    }
    l.b.reserve_params(slot as usize);
    l.graph = Some(Rc::new(env));
    let mut outs: HashMap<&str, Value> = HashMap::new();
    for member in &g.members {
        if let GraphMember::Output { name, value, .. } = member {
            let v = l.lower_expr(value)?;
            outs.insert(name.name.as_str(), v);
        }
    }
    let zero = l.b.constant(0.0);
    let height = outs.get("height").cloned().unwrap_or(Value::scalar(zero));
    let normal = match outs.get("normal") {
        Some(n) => builtins::normalize(&mut l.b, n),
        None => {
            let du = builtins::partial(&mut l.b, &mut l.d_du, &height).comp(0);
            let dv = builtins::partial(&mut l.b, &mut l.d_dv, &height).comp(0);
            let one = l.b.constant(1.0);
            let nx = l.b.neg(du);
            let ny = l.b.neg(dv);
            builtins::normalize(&mut l.b, &Value::Num(vec![nx, ny, one]))
        }
    };
    let albedo = outs.get("albedo").cloned().unwrap_or(Value::Num(vec![zero; 3]));
    let roughness = outs.get("roughness").cloned().unwrap_or(Value::scalar(zero));
    let metallic = outs.get("metallic").cloned().unwrap_or(Value::scalar(zero));
    let node_of = |c: Channel| match c {
        Channel::AlbedoR => albedo.comp(0),
        Channel::AlbedoG => albedo.comp(1),
        Channel::AlbedoB => albedo.comp(2),
        Channel::Roughness => roughness.comp(0),
        Channel::NormalX => normal.comp(0),
        Channel::NormalY => normal.comp(1),
        Channel::NormalZ => normal.comp(2),
        Channel::Height => height.comp(0),
        Channel::Metallic => metallic.comp(0),
    };
    l.check_size(g.span)?;
    let (requested, work) = (l.b.requested(), l.work());
    let outputs = Channel::ALL.into_iter().map(|c| Output { name: c.name().into(), node: node_of(c) }).collect();
    let mut forward = l.b.finish(outputs);
    let nodes_before_dce = forward.nodes.len();
    forward.eliminate_dead_code();
    // Cheap next to lowering (one hash per node), and what every consumer relies on.
    if let Err(e) = forward.validate() {
        let message = format!("internal compiler error: graph `{}` lowered to an invalid program: {e}", g.name.name);
        return Err(Box::new(
            Diagnostic::error(l.file, g.name.span, message).with_hint("please report this with the input file"),
        ));
    }
    let module_ref = set.module(module);
    Ok(CompiledGraph {
        info: GraphInfo {
            name: g.name.name.clone(),
            category,
            description,
            doc: g.doc.clone(),
            file: module_ref.path.clone(),
            params,
            has_height: outs.contains_key("height"),
        },
        stats: CompileStats {
            requested_nodes: requested,
            lowering_work: work,
            nodes_before_dce,
            forward_ops: forward.op_count(),
            lower_time: started.elapsed(),
        },
        forward,
    })
}
