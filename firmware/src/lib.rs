//! axcomp-firmware: see docs/design.md.
#![no_std]
