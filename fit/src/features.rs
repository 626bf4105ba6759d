//! The feature loss: a fixed, weight-free, multi-scale texture descriptor with an exact adjoint.
