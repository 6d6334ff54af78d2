//! axcomp-twin (see docs/design.md).
