//! The drive's status word: fault flags of one cycle (and two latched ones), sent every cycle in the reply
//! frame of the setpoint link ([`crate::setpoint::ReplyFrame`]) and logged through defmt on the board.
//!
//! Every flag, its detection, the drive's behaviour and its time constants are in the fault table of
//! `docs/firmware.md`. Flags describe the cycle they are sent with, except [`Status::IMAGE_REFUSED`]
//! (latched until an image is accepted) and [`Status::WATCHDOG_RESET`] (latched from boot until power-off
//! or a reset by another cause).

/// Bit set of the drive's status in one cycle.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub struct Status(pub u32);

/// The bits in hex, then the names of the set flags.
#[cfg(feature = "defmt")]
impl defmt::Format for Status {
    fn format(&self, f: defmt::Formatter<'_>) {
        defmt::write!(f, "0x{=u32:08x}", self.0);
        for n in self.names() {
            defmt::write!(f, " {=str}", n);
        }
    }
}

impl Status {
    pub const NONE: Status = Status(0);
    /// A temperature sensor of the image is stale (no accepted reading for its `stale_timeout_ms`).
    pub const SENSOR_STALE: Status = Status(1 << 0);
    /// A sensor's last reading was rejected (non-finite, out of range or too fast) and none is stale.
    pub const SENSOR_IMPLAUSIBLE: Status = Status(1 << 1);
    /// The thermal term is frozen at its last good value (core flag THERMAL_FROZEN).
    pub const THERMAL_FROZEN: Status = Status(1 << 2);
    /// The thermal term is ramping out to its safe value. Reserved for the core's stale-sensor ramp-out
    /// (not reported by the present core, which freezes the term).
    pub const THERMAL_RAMPING: Status = Status(1 << 3);
    /// The correction was clamped to the image's `max_correction_um`.
    pub const CLAMP_ACTIVE: Status = Status(1 << 4);
    /// No fresh setpoint frame had arrived when this cycle started.
    pub const FRAME_LATE: Status = Status(1 << 5);
    /// A frame failed its CRC since the previous cycle (never applied).
    pub const FRAME_CORRUPT: Status = Status(1 << 6);
    /// A frame repeated the last sequence number since the previous cycle (never applied).
    pub const FRAME_REPEATED: Status = Status(1 << 7);
    /// The sequence counter skipped: frames were lost since the previous cycle.
    pub const FRAME_MISSING: Status = Status(1 << 8);
    /// The link supervisor holds the last good correction (link fault, within the hold time).
    pub const LINK_HOLD: Status = Status(1 << 9);
    /// The link supervisor ramps the correction (out to zero after the hold time, or back in to the
    /// engine's value after the link recovered).
    pub const LINK_RAMP: Status = Status(1 << 10);
    /// This cycle started later than its deadline by more than the tolerance.
    pub const CYCLE_LATE: Status = Status(1 << 11);
    /// The previous cycle's output was written after the next cycle's deadline (lateness + compute
    /// time > period).
    pub const OVERRUN: Status = Status(1 << 12);
    /// The last image offered was refused (invalid, or does not fit the board); the running slot is kept.
    pub const IMAGE_REFUSED: Status = Status(1 << 13);
    /// The last reset was caused by the watchdog (latched from boot).
    pub const WATCHDOG_RESET: Status = Status(1 << 14);
    /// No image loaded: identity (no correction).
    pub const NO_IMAGE: Status = Status(1 << 15);
    /// The change of the correction was slew-limited (core flag SLEWED).
    pub const SLEWED: Status = Status(1 << 16);
    /// The position is outside the table's stroke (core flag TABLE_OUTSIDE).
    pub const TABLE_OUTSIDE: Status = Status(1 << 17);
    /// A force input was invalid and ignored (core flag FORCE_INVALID).
    pub const FORCE_INVALID: Status = Status(1 << 18);
    /// The correction was not finite; the last one was held (core flag NON_FINITE).
    pub const NON_FINITE: Status = Status(1 << 19);
    /// The reply frame of the previous cycle did not fit the transmit buffer and was dropped.
    pub const REPLY_DROPPED: Status = Status(1 << 20);
    /// A probe trigger of an armed probing move was latched this cycle (the point is in the v3 reply).
    pub const PROBE_LATCHED: Status = Status(1 << 21);
    /// A probe pulse shorter than the filter's minimum width was rejected this cycle.
    pub const PROBE_GLITCH: Status = Status(1 << 22);
    /// A probe leading edge inside a contact's lockout (bounce) was ignored this cycle.
    pub const PROBE_BOUNCE: Status = Status(1 << 23);
    /// A probe trigger while no probing move was armed (axes at rest) was ignored this cycle.
    pub const PROBE_UNARMED: Status = Status(1 << 24);
    /// A probe trigger during a non-probing move (a rapid: a possible collision) was ignored this cycle.
    pub const PROBE_DURING_MOVE: Status = Status(1 << 25);
    /// Probe edges were lost (capture queue overflow, or a level contradicting the edges); a pending
    /// trigger was dropped.
    pub const PROBE_EDGES_LOST: Status = Status(1 << 26);

    /// Bits that stay set across cycles until their condition ends (see the module doc).
    pub const LATCHED: Status = Status(Self::IMAGE_REFUSED.0 | Self::WATCHDOG_RESET.0);

    /// Every flag with its name, in bit order (for logs and reports).
    pub const NAMES: [(Status, &'static str); 27] = [
        (Self::SENSOR_STALE, "SENSOR_STALE"),
        (Self::SENSOR_IMPLAUSIBLE, "SENSOR_IMPLAUSIBLE"),
        (Self::THERMAL_FROZEN, "THERMAL_FROZEN"),
        (Self::THERMAL_RAMPING, "THERMAL_RAMPING"),
        (Self::CLAMP_ACTIVE, "CLAMP_ACTIVE"),
        (Self::FRAME_LATE, "FRAME_LATE"),
        (Self::FRAME_CORRUPT, "FRAME_CORRUPT"),
        (Self::FRAME_REPEATED, "FRAME_REPEATED"),
        (Self::FRAME_MISSING, "FRAME_MISSING"),
        (Self::LINK_HOLD, "LINK_HOLD"),
        (Self::LINK_RAMP, "LINK_RAMP"),
        (Self::CYCLE_LATE, "CYCLE_LATE"),
        (Self::OVERRUN, "OVERRUN"),
        (Self::IMAGE_REFUSED, "IMAGE_REFUSED"),
        (Self::WATCHDOG_RESET, "WATCHDOG_RESET"),
        (Self::NO_IMAGE, "NO_IMAGE"),
        (Self::SLEWED, "SLEWED"),
        (Self::TABLE_OUTSIDE, "TABLE_OUTSIDE"),
        (Self::FORCE_INVALID, "FORCE_INVALID"),
        (Self::NON_FINITE, "NON_FINITE"),
        (Self::REPLY_DROPPED, "REPLY_DROPPED"),
        (Self::PROBE_LATCHED, "PROBE_LATCHED"),
        (Self::PROBE_GLITCH, "PROBE_GLITCH"),
        (Self::PROBE_BOUNCE, "PROBE_BOUNCE"),
        (Self::PROBE_UNARMED, "PROBE_UNARMED"),
        (Self::PROBE_DURING_MOVE, "PROBE_DURING_MOVE"),
        (Self::PROBE_EDGES_LOST, "PROBE_EDGES_LOST"),
    ];

    pub const fn bits(self) -> u32 {
        self.0
    }
    pub const fn contains(self, other: Status) -> bool {
        self.0 & other.0 == other.0
    }
    pub const fn intersects(self, other: Status) -> bool {
        self.0 & other.0 != 0
    }
    pub const fn is_empty(self) -> bool {
        self.0 == 0
    }
    pub fn insert(&mut self, other: Status) {
        self.0 |= other.0;
    }
    pub fn set(&mut self, other: Status, on: bool) {
        if on {
            self.0 |= other.0;
        } else {
            self.0 &= !other.0;
        }
    }
    /// Names of the set flags.
    pub fn names(self) -> impl Iterator<Item = &'static str> {
        Self::NAMES
            .into_iter()
            .filter(move |(f, _)| self.contains(*f))
            .map(|(_, n)| n)
    }
}

impl core::ops::BitOr for Status {
    type Output = Status;
    fn bitor(self, rhs: Status) -> Status {
        Status(self.0 | rhs.0)
    }
}

impl core::ops::BitOrAssign for Status {
    fn bitor_assign(&mut self, rhs: Status) {
        self.0 |= rhs.0;
    }
}

impl core::fmt::Display for Status {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        let mut first = true;
        for n in self.names() {
            if !first {
                f.write_str("|")?;
            }
            f.write_str(n)?;
            first = false;
        }
        if first {
            f.write_str("OK")?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::string::ToString;

    #[test]
    fn names_cover_distinct_bits_in_order() {
        let mut all = 0u32;
        for (i, (f, _)) in Status::NAMES.iter().enumerate() {
            assert_eq!(f.0, 1 << i, "bit order");
            all |= f.0;
        }
        assert_eq!(all.count_ones() as usize, Status::NAMES.len());
        assert_eq!(Status::NONE.to_string(), "OK");
        assert_eq!(
            (Status::FRAME_LATE | Status::LINK_HOLD).to_string(),
            "FRAME_LATE|LINK_HOLD"
        );
    }
}
