//! axcomp-core: see docs/design.md.
#![no_std]
#![forbid(unsafe_code)]
