//! The touch-probe settings an image carries (section kind 4, version 1) and their limits: the
//! format's part of the probe, below both the group image parser and the probe's runtime
//! ([`crate::probe`], which re-exports them).

use crate::error::{Field, ImageError};

/// Length of the probe settings section (image section kind 4, version 1).
pub const PROBE_SECTION_LEN: usize = 20;
/// Largest `min_pulse_us`, µs (100 ms).
pub const MAX_MIN_PULSE_US: u32 = 100_000;
/// Largest `latency_ns`, ns (100 ms).
pub const MAX_LATENCY_NS: u32 = 100_000_000;
/// Largest `lockout_us`, µs (5 s: well inside the half range of a 170 MHz wrapping tick clock).
pub const MAX_LOCKOUT_US: u32 = 5_000_000;
/// Largest `moving_um_per_s` (10 m/s).
pub const MAX_MOVING_UM_PER_S: f32 = 1.0e7;
/// Velocity window: positions sampled every this many cycles.
pub const VELOCITY_STRIDE: u32 = 16;
/// Velocity window: samples kept (the velocity spans `VELOCITY_SAMPLES − 1` strides: 48 cycles,
/// 4.8 ms at 10 kHz).
pub const VELOCITY_SAMPLES: usize = 4;
/// Most edges one [`crate::probe::Probe::step`] takes (more are reported lost by the board's hook).
pub const MAX_EDGES_PER_CYCLE: usize = 8;

/// The probe settings of an image (section kind 4, version 1).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeSettings {
    /// Minimum pulse width of a trigger, µs (0..=[`MAX_MIN_PULSE_US`]).
    pub min_pulse_us: u32,
    /// Signal latency of the probe (touch → input edge), ns (0..=[`MAX_LATENCY_NS`]).
    pub latency_ns: u32,
    /// Lockout window after each edge of a contact, µs (`min_pulse_us`..=[`MAX_LOCKOUT_US`]).
    pub lockout_us: u32,
    /// Speed above which an unarmed trigger counts as one during a move, µm/s (finite, > 0,
    /// ≤ [`MAX_MOVING_UM_PER_S`]; a rotary axis's "µm" are arc-seconds).
    pub moving_um_per_s: f32,
}

impl ProbeSettings {
    /// The recommended settings: the seed's 2 ms filter (harmless: see the module doc), no
    /// latency (set the probe's), 20 ms lockout, 50 µm/s (3 mm/min) for "moving".
    pub const RECOMMENDED: ProbeSettings = ProbeSettings {
        min_pulse_us: 2_000,
        latency_ns: 0,
        lockout_us: 20_000,
        moving_um_per_s: 50.0,
    };

    /// Range checks (the image's section is refused on the first failing field).
    pub fn validate(&self) -> Result<(), ImageError> {
        let bad = |field| Err(ImageError::OutOfRange { field, index: 0 });
        if self.min_pulse_us > MAX_MIN_PULSE_US {
            return bad(Field::ProbeMinPulse);
        }
        if self.latency_ns > MAX_LATENCY_NS {
            return bad(Field::ProbeLatency);
        }
        if self.lockout_us < self.min_pulse_us || self.lockout_us > MAX_LOCKOUT_US {
            return bad(Field::ProbeLockout);
        }
        if !self.moving_um_per_s.is_finite() {
            return Err(ImageError::NonFinite {
                field: Field::ProbeMovingSpeed,
                index: 0,
            });
        }
        if self.moving_um_per_s <= 0.0 || self.moving_um_per_s > MAX_MOVING_UM_PER_S {
            return bad(Field::ProbeMovingSpeed);
        }
        Ok(())
    }

    /// The section bytes (little endian): `min_pulse_us` u32, `latency_ns` u32, `lockout_us`
    /// u32, `moving_um_per_s` f32, reserved u32 = 0.
    pub fn to_bytes(&self) -> [u8; PROBE_SECTION_LEN] {
        let mut b = [0u8; PROBE_SECTION_LEN];
        b[0..4].copy_from_slice(&self.min_pulse_us.to_le_bytes());
        b[4..8].copy_from_slice(&self.latency_ns.to_le_bytes());
        b[8..12].copy_from_slice(&self.lockout_us.to_le_bytes());
        b[12..16].copy_from_slice(&self.moving_um_per_s.to_bits().to_le_bytes());
        b
    }

    /// From the section bytes, validated.
    pub fn from_bytes(b: &[u8]) -> Result<ProbeSettings, ImageError> {
        if b.len() != PROBE_SECTION_LEN {
            return Err(ImageError::BadLength);
        }
        let u = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        if u(16) != 0 {
            return Err(ImageError::OutOfRange {
                field: Field::Reserved,
                index: 0,
            });
        }
        let s = ProbeSettings {
            min_pulse_us: u(0),
            latency_ns: u(4),
            lockout_us: u(8),
            moving_um_per_s: f32::from_bits(u(12)),
        };
        s.validate()?;
        Ok(s)
    }
}
