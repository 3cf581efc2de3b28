//! Work-precision benchmark of the pair runs.
