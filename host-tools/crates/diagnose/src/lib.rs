//! axcomp-diagnose (see docs/design.md).
