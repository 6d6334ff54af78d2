//! axcomp-positioning (see docs/design.md).
