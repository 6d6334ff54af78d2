//! What one control cycle of an axis takes and gives: [`CycleInput`], [`CycleOutput`] and its
//! [`Flags`]. A leaf: every stage and the engines above them use these types.

use crate::MAX_FORCES;
use crate::axis::MAX_AXES;

/// Input of one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleInput {
    /// Raw hardware counter of the scale (wraps at `counter_bits`).
    pub scale_raw: u32,
    /// Commanded position, counts.
    pub command_counts: i64,
    /// Measured forces, N (only used by measured force terms; NaN = no reading).
    pub forces_n: [f32; MAX_FORCES],
}

/// Bit set recording what happened in a cycle.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct Flags(pub u16);

impl Flags {
    /// Nothing special happened.
    pub const NONE: Flags = Flags(0);
    /// The position was outside the table's stroke (hold or taper applied).
    pub const TABLE_OUTSIDE: Flags = Flags(1 << 0);
    /// The total correction was clamped to `max_correction_um`.
    pub const CLAMPED: Flags = Flags(1 << 1);
    /// The change of the applied correction was limited to `max_slew_um_per_cycle`.
    pub const SLEWED: Flags = Flags(1 << 2);
    /// A sensor is stale or its last reading was rejected.
    pub const SENSOR_FAULT: Flags = Flags(1 << 3);
    /// The thermal contribution is frozen (a sensor is stale, recovering, or has not reported yet).
    pub const THERMAL_FROZEN: Flags = Flags(1 << 4);
    /// A force value was NaN, infinite or beyond [`crate::MAX_FORCE_N`] and was ignored.
    pub const FORCE_INVALID: Flags = Flags(1 << 5);
    /// The total correction was not finite; the last applied correction was held.
    pub const NON_FINITE: Flags = Flags(1 << 6);
    /// The backward table was selected (current direction is backward).
    pub const BACKWARD: Flags = Flags(1 << 7);
    /// No image is loaded: identity correction.
    pub const IDENTITY: Flags = Flags(1 << 8);
    /// A sensor has been stale for longer than [`crate::STALE_HOLD_MS`]: the frozen thermal term
    /// (Σ b_i·ΔT_i and c·ΔT_s) is ramping out, or has ramped out, to b0 + predicted forces.
    pub const THERMAL_RAMP_OUT: Flags = Flags(1 << 9);
    /// The range guard left out at least one sensor's term b_i·ΔT_i at the last sensor update
    /// (its unlagged rise outside the image's bounds; see [`crate::image`]).
    pub const THERMAL_GUARDED: Flags = Flags(1 << 10);

    /// Raw bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// From raw bits.
    pub const fn from_bits(bits: u16) -> Flags {
        Flags(bits)
    }
    /// True if every bit of `other` is set.
    pub const fn contains(self, other: Flags) -> bool {
        self.0 & other.0 == other.0
    }
    /// True if no bit is set.
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    /// Set the bits of `other`.
    pub fn insert(&mut self, other: Flags) {
        self.0 |= other.0;
    }
}

// `Compensator::cycle` builds the BACKWARD and TABLE_OUTSIDE bits with a shift and a cast.
const _: () = assert!(Flags::BACKWARD.0 == 1 << 7 && Flags::TABLE_OUTSIDE.0 == 1);

impl core::ops::BitOr for Flags {
    type Output = Flags;
    fn bitor(self, rhs: Flags) -> Flags {
        Flags(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for Flags {
    fn bitor_assign(&mut self, rhs: Flags) {
        self.0 |= rhs.0;
    }
}

/// Output of one control cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CycleOutput {
    /// Extended scale position, counts.
    pub position_counts: i64,
    /// `command − correction_counts` (saturating).
    pub corrected_command_counts: i64,
    /// `round(correction_um / um_per_count)`, half away from zero, saturating.
    pub correction_counts: i32,
    /// Applied (clamped, slewed) correction before rounding to counts, µm.
    pub correction_um: f32,
    /// What happened.
    pub flags: Flags,
}

/// Inputs of one group cycle, by slot (entries beyond the group's axes are ignored).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupInput {
    /// Per slot.
    pub axes: [CycleInput; MAX_AXES],
}

impl GroupInput {
    /// Every axis at counter 0, command 0, no forces.
    pub const ZERO: GroupInput = GroupInput {
        axes: [CycleInput {
            scale_raw: 0,
            command_counts: 0,
            forces_n: [0.0; MAX_FORCES],
        }; MAX_AXES],
    };
}

/// Outputs of one group cycle, by slot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GroupOutput {
    /// Per slot (entries beyond the group's axes are identity outputs).
    pub axes: [CycleOutput; MAX_AXES],
}

impl GroupOutput {
    /// All zero.
    pub const ZERO: GroupOutput = GroupOutput {
        axes: [CycleOutput {
            position_counts: 0,
            corrected_command_counts: 0,
            correction_counts: 0,
            correction_um: 0.0,
            flags: Flags::NONE,
        }; MAX_AXES],
    };
}
