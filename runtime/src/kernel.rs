//! Parallel kernels over compiled graphs (placeholder).
