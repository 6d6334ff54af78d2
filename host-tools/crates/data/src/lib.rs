//! axcomp-data (see docs/design.md).
