//! Symbolic differentiation of IR: forward mode (d/du, d/dv, used for normals from height and
//! for `ddu`/`ddv`) and reverse mode (adjoints of every output with respect to parameters and uv).

pub mod forward;
pub mod reverse;
