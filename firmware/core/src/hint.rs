//! Code-layout hints of the per-cycle path. A leaf.

/// Marks the branch that calls it as rarely taken, so the per-cycle path is laid out as the
/// fall-through (a stand-in for `core::hint::cold_path`, which needs Rust 1.95; MSRV is 1.85).
#[cold]
#[inline(never)]
pub(crate) fn cold_path() {}
