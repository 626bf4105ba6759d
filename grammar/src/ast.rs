//! The abstract syntax tree of a `.psg` file.
//!
//! Invariants the parser establishes (and the checker relies on):
//! - every node carries the byte [`Span`] of the source text it came from;
//! - spans index into the exact text handed to [`crate::parse`];
//! - nothing here is resolved: names are plain strings, types are as written.

/// A half-open byte range `[start, end)` into the source text.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub struct Span {
    pub start: usize,
    pub end: usize,
}

impl Span {
    pub fn new(start: usize, end: usize) -> Self {
        Span { start, end }
    }
    /// The smallest span covering both.
    pub fn to(self, other: Span) -> Span {
        Span { start: self.start.min(other.start), end: self.end.max(other.end) }
    }
}

/// A name with where it was written.
#[derive(Clone, Debug, PartialEq)]
pub struct Ident {
    pub name: String,
    pub span: Span,
}

/// One parsed source file.
#[derive(Clone, Debug, PartialEq)]
pub struct File {
    pub items: Vec<Item>,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Item {
    Import(Import),
    Const(ConstDef),
    Fn(FnDef),
    Graph(GraphDef),
}

/// `import std.noise;` — a dotted module path, resolved against the library root.
#[derive(Clone, Debug, PartialEq)]
pub struct Import {
    pub path: Vec<Ident>,
    pub span: Span,
}

/// `const NAME = expr;` at file level or inside a graph.
#[derive(Clone, Debug, PartialEq)]
pub struct ConstDef {
    pub doc: Option<String>,
    pub name: Ident,
    pub value: Expr,
    pub span: Span,
}

/// Types as written in source.
#[derive(Clone, Debug, PartialEq)]
pub enum TypeExpr {
    /// `float`, `int`, `bool`, `vec2`, `vec3`, `color`.
    Named(Ident),
    /// `(f1: float, id: vec2)` — an anonymous record type.
    Record(Vec<(Ident, TypeExpr)>, Span),
}

impl TypeExpr {
    pub fn span(&self) -> Span {
        match self {
            TypeExpr::Named(i) => i.span,
            TypeExpr::Record(_, s) => *s,
        }
    }
}

/// `fn name(p: vec2, const octaves: int = 4) -> float { stmts; tail }`
#[derive(Clone, Debug, PartialEq)]
pub struct FnDef {
    pub doc: Option<String>,
    pub name: Ident,
    pub params: Vec<FnParam>,
    pub ret: TypeExpr,
    pub body: Block,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub struct FnParam {
    /// `const` parameters must receive compile-time constant arguments (they drive unrolling).
    pub is_const: bool,
    pub name: Ident,
    pub ty: TypeExpr,
    pub default: Option<Expr>,
    pub span: Span,
}

/// Statements followed by a value: `{ let a = 1.0; var s = 0.0; for i in 0..4 { s += a; } s }`.
#[derive(Clone, Debug, PartialEq)]
pub struct Block {
    pub stmts: Vec<Stmt>,
    /// The block's value. Absent only in `for` bodies.
    pub tail: Option<Box<Expr>>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum Stmt {
    /// `let x = e;` (immutable) or `var x = e;` (mutable).
    Let { mutable: bool, name: Ident, ty: Option<TypeExpr>, value: Expr, span: Span },
    /// `x = e;`, `x += e;`, `x -= e;`, `x *= e;`, `x /= e;` (op is None for plain `=`).
    Assign { target: Ident, op: Option<BinOp>, value: Expr, span: Span },
    /// `for i in start..end { … }` — bounds must be compile-time integers; unrolled.
    For { var: Ident, start: Expr, end: Expr, body: Block, span: Span },
}

/// `graph oak_planks { … }`
#[derive(Clone, Debug, PartialEq)]
pub struct GraphDef {
    pub doc: Option<String>,
    pub name: Ident,
    pub members: Vec<GraphMember>,
    pub span: Span,
}

#[derive(Clone, Debug, PartialEq)]
pub enum GraphMember {
    /// `category wood` (an identifier).
    Category(Ident, Span),
    /// `description "text"`.
    Description(String, Span),
    Param(ParamDef),
    /// `node name = expr` and `let name = expr` are the same thing.
    Node {
        name: Ident,
        value: Expr,
        span: Span,
    },
    Const(ConstDef),
    /// `output albedo = expr`.
    Output {
        name: Ident,
        value: Expr,
        span: Span,
    },
}

/// `param name = default in [lo, hi] int` / `param tint = srgb(0.5, 0.4, 0.3)`.
#[derive(Clone, Debug, PartialEq)]
pub struct ParamDef {
    pub doc: Option<String>,
    pub name: Ident,
    pub default: Expr,
    /// `in [lo, hi]`.
    pub range: Option<(Expr, Expr, Span)>,
    /// `int` after the range: a discrete parameter.
    pub is_int: bool,
    pub span: Span,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BinOp {
    Add,
    Sub,
    Mul,
    Div,
    /// `%`: floored modulo, `a - b * floor(a / b)`.
    Rem,
    Lt,
    Le,
    Gt,
    Ge,
    Eq,
    Ne,
    And,
    Or,
}

impl BinOp {
    pub fn symbol(self) -> &'static str {
        match self {
            BinOp::Add => "+",
            BinOp::Sub => "-",
            BinOp::Mul => "*",
            BinOp::Div => "/",
            BinOp::Rem => "%",
            BinOp::Lt => "<",
            BinOp::Le => "<=",
            BinOp::Gt => ">",
            BinOp::Ge => ">=",
            BinOp::Eq => "==",
            BinOp::Ne => "!=",
            BinOp::And => "&&",
            BinOp::Or => "||",
        }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum UnOp {
    Neg,
    Not,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Arg {
    /// `Some` for a named argument `octaves: 4`.
    pub name: Option<Ident>,
    pub value: Expr,
}

#[derive(Clone, Debug, PartialEq)]
pub enum ExprKind {
    /// A float literal (has a `.` or exponent): `1.0`, `2e-3`.
    Float(f64),
    /// An integer literal: `4`.
    Int(i64),
    Bool(bool),
    Name(Ident),
    Unary(UnOp, Box<Expr>),
    Binary(BinOp, Box<Expr>, Box<Expr>),
    /// `f(a, b, k: c)`; also vector constructors `vec2(…)`, `vec3(…)`, `srgb(…)`.
    Call(Ident, Vec<Arg>),
    /// `e.name`: a record field or a swizzle (`.x`, `.xy`, `.rgb`, `.zyx`).
    Field(Box<Expr>, Ident),
    /// `(f1: a, id: b)`: a record literal.
    Record(Vec<(Ident, Expr)>),
    /// `if c { a } else { b }` — both branches are evaluated; the result is selected.
    If(Box<Expr>, Box<Block>, Box<Block>),
    /// `{ let a = …; a * 2.0 }`
    Block(Box<Block>),
}

#[derive(Clone, Debug, PartialEq)]
pub struct Expr {
    pub kind: ExprKind,
    pub span: Span,
}
