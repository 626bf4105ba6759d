//! The checker's types and their conversion rules.

use std::fmt;
use std::rc::Rc;

#[derive(Clone, Debug, PartialEq)]
pub enum Ty {
    Float,
    Int,
    Bool,
    Vec2,
    Vec3,
    /// An anonymous record; field order is the order written.
    Record(Rc<[(String, Ty)]>),
    /// The type of an expression that already produced an error: compatible with everything,
    /// so that one mistake is reported once.
    Error,
}

impl Ty {
    /// Number of scalar components of a numeric type (float and int are 1).
    pub fn width(&self) -> Option<usize> {
        match self {
            Ty::Float | Ty::Int => Some(1),
            Ty::Vec2 => Some(2),
            Ty::Vec3 => Some(3),
            _ => None,
        }
    }

    pub fn is_numeric(&self) -> bool {
        self.width().is_some()
    }

    /// The float type of a width (1 → float).
    pub fn of_width(width: usize) -> Ty {
        match width {
            1 => Ty::Float,
            2 => Ty::Vec2,
            _ => Ty::Vec3,
        }
    }

    /// Whether a value of type `self` may be used where `target` is expected: identical types,
    /// int → float, and scalar → vector broadcast.
    pub fn coerces_to(&self, target: &Ty) -> bool {
        match (self, target) {
            (Ty::Error, _) | (_, Ty::Error) => true,
            (a, b) if a == b => true,
            (Ty::Int, Ty::Float) => true,
            (Ty::Int | Ty::Float, Ty::Vec2 | Ty::Vec3) => true,
            (Ty::Record(a), Ty::Record(b)) => {
                a.len() == b.len() && a.iter().zip(b.iter()).all(|(x, y)| x.0 == y.0 && x.1.coerces_to(&y.1))
            }
            _ => false,
        }
    }

    /// The result type of componentwise arithmetic between two numeric types.
    pub fn unify_numeric(a: &Ty, b: &Ty) -> Option<Ty> {
        match (a, b) {
            (Ty::Error, _) | (_, Ty::Error) => Some(Ty::Error),
            (Ty::Int, Ty::Int) => Some(Ty::Int),
            _ => {
                let (wa, wb) = (a.width()?, b.width()?);
                match (wa, wb) {
                    (x, y) if x == y => Some(Ty::of_width(x)),
                    (1, y) => Some(Ty::of_width(y)),
                    (x, 1) => Some(Ty::of_width(x)),
                    _ => None,
                }
            }
        }
    }

    /// `int` becomes `float`; everything else is unchanged.
    pub fn to_float(&self) -> Ty {
        if *self == Ty::Int {
            Ty::Float
        } else {
            self.clone()
        }
    }
}

impl fmt::Display for Ty {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Ty::Float => write!(f, "float"),
            Ty::Int => write!(f, "int"),
            Ty::Bool => write!(f, "bool"),
            Ty::Vec2 => write!(f, "vec2"),
            Ty::Vec3 => write!(f, "vec3"),
            Ty::Error => write!(f, "{{error}}"),
            Ty::Record(fields) => {
                write!(f, "(")?;
                for (i, (name, ty)) in fields.iter().enumerate() {
                    write!(f, "{}{name}: {ty}", if i == 0 { "" } else { ", " })?;
                }
                write!(f, ")")
            }
        }
    }
}

/// Parses a swizzle (`x`, `xy`, `zyx`, `rgb`, …) into component indices, for a vector of
/// `width` components. `None` if the name is not a valid swizzle of that width.
pub fn swizzle(name: &str, width: usize) -> Option<Vec<usize>> {
    if name.is_empty() || name.len() > 3 {
        return None;
    }
    let sets = ["xyz", "rgb"];
    for set in sets {
        let idx: Option<Vec<usize>> = name.chars().map(|c| set.find(c)).collect();
        if let Some(idx) = idx {
            if idx.iter().all(|&i| i < width) {
                return Some(idx);
            }
            return None;
        }
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn broadcast_and_promotion() {
        assert!(Ty::Int.coerces_to(&Ty::Float));
        assert!(Ty::Float.coerces_to(&Ty::Vec3));
        assert!(!Ty::Vec2.coerces_to(&Ty::Vec3));
        assert!(!Ty::Float.coerces_to(&Ty::Int));
        assert_eq!(Ty::unify_numeric(&Ty::Float, &Ty::Vec2), Some(Ty::Vec2));
        assert_eq!(Ty::unify_numeric(&Ty::Vec2, &Ty::Vec3), None);
        assert_eq!(Ty::unify_numeric(&Ty::Int, &Ty::Int), Some(Ty::Int));
    }

    #[test]
    fn swizzles() {
        assert_eq!(swizzle("zyx", 3), Some(vec![2, 1, 0]));
        assert_eq!(swizzle("rg", 3), Some(vec![0, 1]));
        assert_eq!(swizzle("z", 2), None);
        assert_eq!(swizzle("xr", 3), None);
        assert_eq!(swizzle("xyzw", 3), None);
    }
}
