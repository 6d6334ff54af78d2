//! axcomp-thermal (see docs/design.md).
