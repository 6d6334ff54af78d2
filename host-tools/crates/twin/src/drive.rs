//! The compensated drive: the twin positions the axis through `axcomp_core::Compensator::cycle`, the
//! same code the firmware runs.
//!
//! Glossary:
//! - *cycle*: one call of `Compensator::cycle` with the scale's raw counter and the command.
//! - *ideal servo*: within one cycle the carriage reaches the corrected command, so the next cycle's
//!   scale reading is the previous corrected command (the simplest honest drive model).
//! - *approach path*: the commands of one move, [`PATH_CYCLES`] evenly spaced cycles from where the
//!   axis is to the approach start, then to the target, then [`SETTLE_CYCLES`]+ cycles at the target
//!   until the corrected command no longer changes (slew-limited corrections need several).

use axcomp_core::{Compensator, CycleInput, MAX_FORCES, State};

use crate::axis::Axis;
use crate::plan::Sample;
use crate::sim::{Drive, SENSOR_PERIOD_MS};
use crate::thermal::ThermalState;

/// Cycles per straight move of the approach path.
pub const PATH_CYCLES: i64 = 16;
/// Minimum cycles spent at the target.
pub const SETTLE_CYCLES: usize = 4;
/// Maximum cycles spent at the target (slew limit reached).
pub const MAX_SETTLE_CYCLES: usize = 10_000;

pub(crate) struct Compensated<'a> {
    comp: &'a Compensator,
    state: State,
    scale_counts: Option<i64>,
    period_s: f64,
    next_feed_s: f64,
    mask: u32,
}

impl<'a> Compensated<'a> {
    pub(crate) fn new(comp: &'a Compensator) -> Self {
        let bits = comp.counter_bits();
        let mask = if bits == 0 || bits >= 32 {
            u32::MAX
        } else {
            (1u32 << bits) - 1
        };
        let period_ms = if comp.has_thermo() && comp.sensor_period_ms() > 0 {
            comp.sensor_period_ms()
        } else {
            SENSOR_PERIOD_MS
        };
        let period_s = f64::from(period_ms) * 1e-3;
        Compensated {
            comp,
            state: State::new(),
            scale_counts: None,
            period_s,
            next_feed_s: period_s,
            mask,
        }
    }

    fn raw(&self, counts: i64) -> u32 {
        (counts as u32) & self.mask
    }

    /// One cycle at the current scale position; the ideal servo then sits at the corrected command.
    fn cycle(&mut self, command: i64, force_n: f64) -> (i64, f32) {
        let scale = self.scale_counts.unwrap_or(command);
        let mut forces_n = [0.0f32; MAX_FORCES];
        forces_n[0] = force_n as f32;
        let input = CycleInput {
            scale_raw: self.raw(scale),
            command_counts: command,
            forces_n,
        };
        let out = self.comp.cycle(&mut self.state, &input);
        self.scale_counts = Some(out.corrected_command_counts);
        (out.corrected_command_counts, out.correction_um)
    }

    fn move_to(&mut self, to: i64, force_n: f64) {
        let from = self.scale_counts.unwrap_or(to);
        for k in 1..=PATH_CYCLES {
            let c = from + (to - from) * k / PATH_CYCLES;
            self.cycle(c, force_n);
        }
    }
}

impl Drive for Compensated<'_> {
    fn on_thermal_step(
        &mut self,
        st: &ThermalState,
        readings: &mut dyn FnMut(&ThermalState) -> [f64; 3],
    ) {
        if !self.comp.has_thermo() {
            return;
        }
        while st.t_s + 1e-9 >= self.next_feed_s {
            let now_ms = (self.next_feed_s * 1e3).round() as u64 as u32;
            let values = readings(st).map(|v| v as f32);
            let n = self.comp.sensor_count().min(values.len());
            self.comp
                .update_temperatures(&mut self.state, now_ms, &values[..n]);
            self.next_feed_s += self.period_s;
        }
    }

    fn position(&mut self, axis: &Axis, sample: &Sample, force_n: f64) -> (i64, f64) {
        let target = axis.counts(sample.target_mm);
        if self.scale_counts.is_none() {
            let start = axis.counts(sample.approach_from_mm.unwrap_or(sample.target_mm));
            self.state.reset(self.raw(start));
            self.scale_counts = Some(start);
        }
        if let Some(from_mm) = sample.approach_from_mm {
            self.move_to(axis.counts(from_mm), force_n);
        }
        self.move_to(target, force_n);
        let mut last = self.cycle(target, force_n);
        let mut unchanged = 0;
        for i in 0..MAX_SETTLE_CYCLES {
            let next = self.cycle(target, force_n);
            unchanged = if next == last { unchanged + 1 } else { 0 };
            last = next;
            if i + 1 >= SETTLE_CYCLES && unchanged >= 2 {
                break;
            }
        }
        (last.0, f64::from(last.1))
    }
}
