//! The intrinsic functions: their names and their typing rules. Their lowering to IR lives in
//! `lower::builtins`; everything that can be written in the language lives in `graphs/std/`.

use crate::types::Ty;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Builtin {
    // Componentwise, one argument.
    Abs,
    Floor,
    Ceil,
    Fract,
    Sign,
    Sqrt,
    Sin,
    Cos,
    Exp,
    Log,
    // Componentwise, two arguments.
    Pow,
    Min,
    Max,
    Atan2,
    Step,
    // Componentwise, three arguments.
    Clamp,
    Mix,
    Smoothstep,
    // Geometric.
    Length,
    Dot,
    Distance,
    Normalize,
    Cross,
    // Other.
    Select,
    Float,
    Hash,
    Sample,
    Ddu,
    Ddv,
    Vec2,
    Vec3,
    Srgb,
    Rgb,
}

const ALL: &[(&str, Builtin)] = &[
    ("abs", Builtin::Abs),
    ("floor", Builtin::Floor),
    ("ceil", Builtin::Ceil),
    ("fract", Builtin::Fract),
    ("sign", Builtin::Sign),
    ("sqrt", Builtin::Sqrt),
    ("sin", Builtin::Sin),
    ("cos", Builtin::Cos),
    ("exp", Builtin::Exp),
    ("log", Builtin::Log),
    ("pow", Builtin::Pow),
    ("min", Builtin::Min),
    ("max", Builtin::Max),
    ("atan2", Builtin::Atan2),
    ("step", Builtin::Step),
    ("clamp", Builtin::Clamp),
    ("mix", Builtin::Mix),
    ("smoothstep", Builtin::Smoothstep),
    ("length", Builtin::Length),
    ("dot", Builtin::Dot),
    ("distance", Builtin::Distance),
    ("normalize", Builtin::Normalize),
    ("cross", Builtin::Cross),
    ("select", Builtin::Select),
    ("float", Builtin::Float),
    ("hash", Builtin::Hash),
    ("sample", Builtin::Sample),
    ("ddu", Builtin::Ddu),
    ("ddv", Builtin::Ddv),
    ("vec2", Builtin::Vec2),
    ("vec3", Builtin::Vec3),
    ("srgb", Builtin::Srgb),
    ("rgb", Builtin::Rgb),
];

impl Builtin {
    pub fn from_name(name: &str) -> Option<Builtin> {
        ALL.iter().find(|(n, _)| *n == name).map(|(_, b)| *b)
    }

    pub fn names() -> impl Iterator<Item = &'static str> {
        ALL.iter().map(|(n, _)| *n)
    }

    /// Whether the result is a compile-time constant when every argument is.
    pub fn preserves_constness(self) -> bool {
        !matches!(self, Builtin::Sample | Builtin::Ddu | Builtin::Ddv)
    }

    /// The result type for these argument types, or a message saying what was expected.
    pub fn check(self, args: &[Ty]) -> Result<Ty, String> {
        use Builtin::*;
        let arity = |n: usize| -> Result<(), String> {
            if args.len() == n {
                Ok(())
            } else {
                Err(format!("takes {n} argument{}, found {}", if n == 1 { "" } else { "s" }, args.len()))
            }
        };
        let numeric = |t: &Ty| -> Result<Ty, String> {
            if t.is_numeric() || *t == Ty::Error {
                Ok(t.to_float())
            } else {
                Err(format!("expects float, vec2 or vec3, found {t}"))
            }
        };
        let unify = |ts: &[Ty]| -> Result<Ty, String> {
            let mut acc = numeric(&ts[0])?;
            for t in &ts[1..] {
                numeric(t)?;
                acc = Ty::unify_numeric(&acc, t).ok_or_else(|| format!("cannot combine {acc} and {t}"))?;
            }
            Ok(acc.to_float())
        };
        match self {
            Abs | Floor | Ceil | Fract | Sign | Sqrt | Sin | Cos | Exp | Log | Normalize | Ddu | Ddv => {
                arity(1)?;
                numeric(&args[0])
            }
            Pow | Min | Max | Atan2 | Step => {
                arity(2)?;
                unify(args)
            }
            Clamp | Mix | Smoothstep => {
                arity(3)?;
                unify(args)
            }
            Length => {
                arity(1)?;
                numeric(&args[0]).map(|_| Ty::Float)
            }
            Dot | Distance => {
                arity(2)?;
                unify(args).map(|_| Ty::Float)
            }
            Cross => {
                arity(2)?;
                for a in args {
                    if !a.coerces_to(&Ty::Vec3) {
                        return Err(format!("expects vec3, found {a}"));
                    }
                }
                Ok(Ty::Vec3)
            }
            Select => {
                arity(3)?;
                if !args[0].coerces_to(&Ty::Bool) {
                    return Err(format!("expects a bool condition first, found {}", args[0]));
                }
                if args[1].coerces_to(&args[2]) {
                    Ok(args[2].to_float())
                } else if args[2].coerces_to(&args[1]) {
                    Ok(args[1].to_float())
                } else {
                    Err(format!("branches have different types: {} and {}", args[1], args[2]))
                }
            }
            Float => {
                arity(1)?;
                match &args[0] {
                    Ty::Int | Ty::Float | Ty::Error => Ok(Ty::Float),
                    Ty::Bool => Ok(Ty::Float),
                    t => Err(format!("expects int, float or bool, found {t}")),
                }
            }
            Hash => {
                arity(2)?;
                for a in args {
                    if !a.coerces_to(&Ty::Float) {
                        return Err(format!("expects two scalars, found {a}"));
                    }
                }
                Ok(Ty::Float)
            }
            Sample => {
                arity(2)?;
                if !args[1].coerces_to(&Ty::Vec2) {
                    return Err(format!("expects a vec2 position second, found {}", args[1]));
                }
                Ok(args[0].to_float())
            }
            Vec2 | Vec3 => {
                let want = if self == Vec2 { 2 } else { 3 };
                let mut total = 0;
                for a in args {
                    match a.width() {
                        Some(w) => total += w,
                        None if *a == Ty::Error => return Ok(Ty::of_width(want)),
                        None => return Err(format!("expects scalars or vectors, found {a}")),
                    }
                }
                if total == want || (args.len() == 1 && total == 1) {
                    Ok(Ty::of_width(want))
                } else {
                    Err(format!("needs 1 or {want} components in all, found {total}"))
                }
            }
            Srgb | Rgb => {
                arity(3)?;
                for a in args {
                    if !a.coerces_to(&Ty::Float) {
                        return Err(format!("expects three scalars, found {a}"));
                    }
                }
                Ok(Ty::Vec3)
            }
        }
    }
}
