//! Counter extension and approach direction: the scale's wrapping hardware counter becomes an
//! extended i64 position, and a hysteresis decides which table direction applies.
//!
//! # Glossary
//! - **counter width**: `counter_bits` (16..=32) of the hardware counter; it wraps at 2^bits.
//! - **extension**: the extended position adds the sign-extended counter delta each cycle, so any
//!   sequence of steps below half the counter range is followed exactly.
//! - **reversal / hysteresis**: the direction flips only after moving more than
//!   `direction_hysteresis_counts` against it (state: distance moved back since the extreme).

/// Approach direction of the axis.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Direction {
    /// Increasing scale position (also the initial direction).
    #[default]
    Forward,
    /// Decreasing scale position.
    Backward,
}
