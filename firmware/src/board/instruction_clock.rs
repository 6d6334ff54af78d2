//! Instruction counting for the QEMU bench bins (`axcomp-qemu-bench`, `axcomp-qemu-drive-bench`):
//! under `-icount shift=0` SysTick advances deterministically with
//! executed instructions; it is calibrated against a block of exactly 1 002 001 instructions, so a
//! measured tick count converts to instructions.
//!
//! Method (the same in every bench bin): [`start`] SysTick free-running on the core clock,
//! [`instructions_per_tick`] from [`calibrate`], then around each measured batch `t0 = now()` …
//! `ticks_since(t0)`, minus the same batch with an empty stand-in of the measured call.

use cortex_m::peripheral::{SYST, syst::SystClkSource};

/// Instructions executed by [`calibrate`]'s block: 1000 × (1000 `nop` + `subs` + `bne`) + `mov`.
pub const CALIBRATION_INSTRUCTIONS: f32 = 1_002_001.0;

/// SysTick as a free-running 24-bit down counter on the core clock.
pub fn start(syst: &mut SYST) {
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(0x00FF_FFFF);
    syst.clear_current();
    syst.enable_counter();
}

/// The SysTick counter now.
#[inline(always)]
pub fn now() -> u32 {
    SYST::get_current()
}

/// SysTick ticks since `t0` (a [`now`] value; the counter counts down and wraps at 24 bits).
#[inline(always)]
pub fn ticks_since(t0: u32) -> u32 {
    t0.wrapping_sub(now()) & 0x00FF_FFFF
}

/// SysTick ticks for [`CALIBRATION_INSTRUCTIONS`] instructions. Never inlined: LLVM sizes the
/// `.rept` block as one instruction, so a literal pool of the caller could land out of reach behind it.
#[inline(never)]
pub fn calibrate() -> u32 {
    let t0 = now();
    // SAFETY: pure register arithmetic on a scratch register.
    unsafe {
        core::arch::asm!(
            "mov {n}, #1000",
            "2:",
            ".rept 1000",
            "nop",
            ".endr",
            "subs {n}, {n}, #1",
            "bne 2b",
            n = out(reg) _,
            options(nomem, nostack),
        );
    }
    ticks_since(t0)
}

/// Calibrates and prints `calibration: T SysTick ticks for N instructions` (the bench scripts echo
/// it); returns instructions per tick.
pub fn instructions_per_tick() -> f32 {
    let cal = calibrate();
    cortex_m_semihosting::hprintln!(
        "calibration: {} SysTick ticks for {} instructions",
        cal,
        CALIBRATION_INSTRUCTIONS as u32
    );
    CALIBRATION_INSTRUCTIONS / cal as f32
}
