"""Super-helix rod kernels (numba): evaluation, frames, Jacobians, statics."""
