//! Logging macros: defmt on the board (feature `defmt`), nothing elsewhere, so host builds and the QEMU
//! firmware never need a defmt logger.

#[allow(unused_macros)]
macro_rules! info {
    ($($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        ::defmt::info!($($arg)*);
    }};
}

#[allow(unused_macros)]
macro_rules! warn {
    ($($arg:tt)*) => {{
        #[cfg(feature = "defmt")]
        ::defmt::warn!($($arg)*);
    }};
}
