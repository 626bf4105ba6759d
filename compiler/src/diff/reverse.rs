//! Reverse-mode adjoint programs (owned by the diff work; placeholder).
