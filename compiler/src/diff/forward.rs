//! Forward-mode differentiation (owned by the diff work; placeholder).
