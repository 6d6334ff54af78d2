//! Linker setup for the embedded bins only (host builds are left alone).
//!
//! Copies the workspace's `memory.x` into `OUT_DIR`, puts `OUT_DIR` on the link search path and passes
//! cortex-m-rt's `link.x` (and defmt's `defmt.x` for the board bin, the only one that logs with defmt).

use std::{env, fs, path::PathBuf};

fn main() {
    let manifest_dir =
        PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let memory_x = manifest_dir.join("../memory.x");
    println!("cargo:rerun-if-changed={}", memory_x.display());
    println!("cargo:rerun-if-changed=build.rs");

    if env::var("CARGO_CFG_TARGET_OS").as_deref() != Ok("none") {
        return;
    }
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy(&memory_x, out.join("memory.x"))
        .unwrap_or_else(|e| panic!("copying {} into OUT_DIR: {e}", memory_x.display()));
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    // cortex-m-rt's `device` feature includes `device.x` (weak aliases of the interrupt handlers);
    // the board's comes with its PAC. The QEMU bins name every vector in their own table
    // (`board::qemu::__INTERRUPTS`), so theirs is empty.
    if env::var_os("CARGO_FEATURE_QEMU").is_some()
        && env::var_os("CARGO_FEATURE_BOARD_STM32G474").is_none()
    {
        fs::write(
            out.join("device.x"),
            "/* QEMU: see board::qemu::__INTERRUPTS */\n",
        )
        .expect("writing device.x into OUT_DIR");
    }
    if env::var_os("CARGO_FEATURE_BOARD_STM32G474").is_some() {
        println!("cargo:rustc-link-arg-bin=axcomp-stm32g474=-Tdefmt.x");
    }
}
