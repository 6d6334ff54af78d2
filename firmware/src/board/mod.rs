//! Board support: the only place that names a chip.

#[cfg(feature = "qemu")]
pub mod instruction_clock;
#[cfg(feature = "qemu")]
pub mod semihosting;

// Links cortex-m's single-core critical-section implementation (used by the executor and the HAL).
use cortex_m as _;

#[cfg(feature = "board-stm32g474")]
pub mod stm32g474;

#[cfg(feature = "qemu")]
pub mod qemu;
