//! axcomp-plot (see docs/design.md).
