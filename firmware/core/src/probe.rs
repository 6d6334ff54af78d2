//! Touch-probe latch of an axis group: every axis's counts captured at the trigger's leading edge,
//! a minimum-pulse-width filter that only decides *acceptance* afterwards, latency compensation,
//! arming, bounce lockout and the loop's own correction applied to the latched point.
//!
//! Portable logic (integer ticks, `f64`/`f32` with `+ − × /` and `libm`), so the host replays the
//! firmware bit for bit. Coefficients in [`ProbeConfig`] (`&self`), everything that changes in
//! [`ProbeState`] (`&mut`).
//!
//! # Glossary
//! - **level**: the probe input, `true` = deflected (triggered); the board maps its polarity.
//! - **edge**: a change of the level with its time (cycle-clock ticks, wrapping `u32`) and the
//!   counts of every axis captured by hardware at that instant ([`ProbeEdge`]; on the STM32G474
//!   timer input capture on the encoder timers).
//! - **leading edge**: false → true. The counts latched for a trigger are always the leading
//!   edge's; nothing read later enters the position.
//! - **filter**: a leading edge becomes a **trigger** only if the level stays true for at least
//!   `min_pulse` (checked at the falling edge, or at a cycle when the pulse is already that long);
//!   a shorter pulse is a **glitch** (counted, flagged, never latched).
//! - **armed**: the CNC's command for a probing move (G31 / SKIP), bit 0 of the setpoint frame's
//!   probe byte. A trigger is latched only if the move was armed at its leading edge, and at most
//!   once per armed move: after the latch the move is **latched** (no longer armed) until the
//!   CNC arms the next one.
//! - **contact**: from a trigger's leading edge while the input stays deflected, through its
//!   release, until `lockout` has passed without an edge. **Lockout**: every edge of a contact
//!   restarts it (a deflection held for long keeps the contact; the release starts a last
//!   window); a leading edge inside it is **bounce** (counted, flagged, never a new trigger).
//! - **unarmed trigger**: a trigger while not armed with every axis slower than `moving_um_per_s`;
//!   **trigger during a move**: the same while some axis moves faster (a rapid or feed move
//!   that is not a probing move: a possible collision). Both counted and flagged, never latched.
//! - **latency compensation**: the probe's signal reaches the input `latency` after the stylus
//!   touched; the latched position is the captured counts minus velocity × latency.
//! - **latched point**: per axis, (captured counts − v·latency)·µm per count + the loop's error
//!   at the captured counts ([`LatchCorrection`], for a group [`crate::group::Group::error_at`]):
//!   the position of the machine in the corrected (true) coordinates, nanometres.
//!
//! # Why a filter of its own and where the position comes from
//! Seed 003's controller accepts a skip pulse only if it lasts ≥ 2 ms. If the position were read
//! when the filter accepts, a 2 ms filter at 1000 mm/min (16.7 µm/ms) would put the point 33 µm
//! beyond the touch, and at F100 vs F400 the offset would differ by 25 µm (the grbl users' shift).
//! Here the counts are captured by hardware at the leading edge and the filter only decides
//! afterwards whether that edge was a real trigger, so the filter width costs acceptance delay
//! (the CNC learns of the latch `min_pulse` later), never position. The recommended setting
//! ([`ProbeSettings::RECOMMENDED`]) therefore keeps the seed's 2 ms: long enough to reject EMI
//! spikes and wireless-receiver glitches (µs to a few hundred µs), short against a real contact,
//! which stays deflected until the CNC has stopped the move (tens of ms).

use crate::error::{Field, ImageError};
use crate::group::{Group, GroupState, MAX_AXES};
pub use crate::probe_settings::{
    MAX_EDGES_PER_CYCLE, MAX_LATENCY_NS, MAX_LOCKOUT_US, MAX_MIN_PULSE_US, MAX_MOVING_UM_PER_S,
    PROBE_SECTION_LEN, ProbeSettings, VELOCITY_SAMPLES, VELOCITY_STRIDE,
};

/// The coefficients of a probe input: settings converted to cycle-clock ticks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProbeConfig {
    /// False: no probe (every edge ignored, nothing counted).
    pub enabled: bool,
    min_pulse_ticks: u32,
    lockout_ticks: u32,
    latency_s: f32,
    moving_um_per_s: f32,
    tick_hz: u32,
}

impl ProbeConfig {
    /// No probe configured.
    pub const DISABLED: ProbeConfig = ProbeConfig {
        enabled: false,
        min_pulse_ticks: 0,
        lockout_ticks: 0,
        latency_s: 0.0,
        moving_um_per_s: 0.0,
        tick_hz: 1,
    };

    /// `settings` (validated) on a clock of `tick_hz` ticks per second (> 0).
    pub fn new(settings: &ProbeSettings, tick_hz: u32) -> Result<ProbeConfig, ImageError> {
        settings.validate()?;
        if tick_hz == 0 {
            return Err(ImageError::OutOfRange {
                field: Field::ProbeMinPulse,
                index: 1,
            });
        }
        let ticks = |us: u32| {
            let t = us as u64 * tick_hz as u64 / 1_000_000;
            t.min(i32::MAX as u64) as u32
        };
        Ok(ProbeConfig {
            enabled: true,
            min_pulse_ticks: ticks(settings.min_pulse_us),
            lockout_ticks: ticks(settings.lockout_us),
            latency_s: (settings.latency_ns as f64 * 1e-9) as f32,
            moving_um_per_s: settings.moving_um_per_s,
            tick_hz,
        })
    }
    /// Minimum pulse width, ticks.
    pub fn min_pulse_ticks(&self) -> u32 {
        self.min_pulse_ticks
    }
    /// Lockout window, ticks.
    pub fn lockout_ticks(&self) -> u32 {
        self.lockout_ticks
    }
}

/// One edge of the probe input as the board captured it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ProbeEdge {
    /// When, cycle-clock ticks (wrapping).
    pub time: u32,
    /// The level after the edge (true = deflected).
    pub level: bool,
    /// Every axis's extended counts at the edge, by group slot.
    pub counts: [i64; MAX_AXES],
}

/// What the latch does with a trigger, and what the flags report.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub enum ProbeEvent {
    /// A trigger of an armed probing move: latched.
    Latched = 0,
    /// A pulse shorter than the filter: rejected.
    Glitch = 1,
    /// A leading edge inside the lockout of a contact: counted, not latched.
    Bounce = 2,
    /// A trigger while not armed, every axis at rest.
    UnarmedTrigger = 3,
    /// A trigger while not armed and some axis moving (a rapid or another non-probing move).
    TriggerDuringMove = 4,
    /// Edges were lost (more than the hook could hold, or a level that contradicts the edges):
    /// a pending leading edge is dropped, never latched.
    EdgesLost = 5,
}

impl ProbeEvent {
    /// Every event, in code order.
    pub const ALL: [ProbeEvent; 6] = [
        ProbeEvent::Latched,
        ProbeEvent::Glitch,
        ProbeEvent::Bounce,
        ProbeEvent::UnarmedTrigger,
        ProbeEvent::TriggerDuringMove,
        ProbeEvent::EdgesLost,
    ];
    /// Its flag in [`ProbeFlags`].
    pub const fn flag(self) -> ProbeFlags {
        ProbeFlags(1 << (4 + self as u16))
    }
    /// Name for reports.
    pub const fn name(self) -> &'static str {
        match self {
            ProbeEvent::Latched => "latched",
            ProbeEvent::Glitch => "glitch",
            ProbeEvent::Bounce => "bounce",
            ProbeEvent::UnarmedTrigger => "unarmed trigger",
            ProbeEvent::TriggerDuringMove => "trigger during a move",
            ProbeEvent::EdgesLost => "edges lost",
        }
    }
}

/// Where the probing move stands.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
#[repr(u8)]
pub enum ProbePhase {
    /// No probing move.
    #[default]
    Disarmed = 0,
    /// A probing move, waiting for its trigger.
    Armed = 1,
    /// The probing move's trigger is latched ([`ProbeState::latch`]); the CNC still arms it.
    Latched = 2,
}

/// Per-cycle probe flags (bits): the phase, then one bit per [`ProbeEvent`] of this cycle, then
/// the latch's quality.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Hash)]
pub struct ProbeFlags(pub u16);

impl ProbeFlags {
    /// Nothing.
    pub const NONE: ProbeFlags = ProbeFlags(0);
    /// Phase [`ProbePhase::Armed`].
    pub const ARMED: ProbeFlags = ProbeFlags(1 << 0);
    /// Phase [`ProbePhase::Latched`]: the latched point belongs to the present probing move.
    pub const LATCHED: ProbeFlags = ProbeFlags(1 << 1);
    /// A leading edge waits for the filter.
    pub const PENDING: ProbeFlags = ProbeFlags(1 << 2);
    /// The input is deflected (level true) at the end of the cycle.
    pub const LEVEL: ProbeFlags = ProbeFlags(1 << 3);
    /// The latched point has no latency compensation (no velocity estimate yet).
    pub const NO_VELOCITY: ProbeFlags = ProbeFlags(1 << 10);
    /// The loop's error at the latched counts was clamped or not finite.
    pub const CORRECTION_LIMITED: ProbeFlags = ProbeFlags(1 << 11);
    /// The bits.
    pub const fn bits(self) -> u16 {
        self.0
    }
    /// True if every bit of `other` is set.
    pub const fn contains(self, other: ProbeFlags) -> bool {
        self.0 & other.0 == other.0
    }
    /// Sets the bits of `other`.
    pub fn insert(&mut self, other: ProbeFlags) {
        self.0 |= other.0;
    }
    /// True if `event` happened this cycle.
    pub const fn has(self, event: ProbeEvent) -> bool {
        self.contains(event.flag())
    }
}

/// Counters since start (wrapping).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ProbeCounters {
    /// By [`ProbeEvent`] code.
    pub events: [u32; 6],
}

impl ProbeCounters {
    /// How often `event` happened.
    pub fn get(&self, event: ProbeEvent) -> u32 {
        self.events[event as usize]
    }
    fn count(&mut self, event: ProbeEvent) {
        let c = &mut self.events[event as usize];
        *c = c.wrapping_add(1);
    }
}

/// A latched trigger.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Latch {
    /// Leading edge's time, ticks.
    pub time: u32,
    /// Counts captured at the leading edge, by slot.
    pub captured_counts: [i64; MAX_AXES],
    /// Velocity estimate at the leading edge, counts per second, by slot.
    pub velocity_counts_per_s: [f32; MAX_AXES],
    /// The loop's error at the captured counts, µm, by slot.
    pub error_um: [f32; MAX_AXES],
    /// The latched point: (captured − v·latency)·µm per count + error, nanometres, by slot.
    pub point_nm: [i64; MAX_AXES],
    /// Axes (slots `..n_axes` valid).
    pub n_axes: u8,
    /// [`ProbeFlags::NO_VELOCITY`], [`ProbeFlags::CORRECTION_LIMITED`].
    pub quality: ProbeFlags,
}

/// The loop's correction the latched point gets.
pub trait LatchCorrection {
    /// Axes of the group.
    fn axis_count(&self) -> usize;
    /// µm per count of slot `i`.
    fn um_per_count(&self, i: usize) -> f32;
    /// The loop's error (µm) by slot at `positions_counts`, and whether one was limited.
    fn error_um(&self, positions_counts: &[i64; MAX_AXES]) -> ([f32; MAX_AXES], bool);
}

/// The group engine's correction: [`Group::error_at`] with the running [`GroupState`].
pub struct GroupCorrection<'a, const POOL: usize> {
    /// The active group.
    pub group: &'a Group<POOL>,
    /// Its state after this cycle.
    pub state: &'a GroupState,
}

impl<const POOL: usize> LatchCorrection for GroupCorrection<'_, POOL> {
    fn axis_count(&self) -> usize {
        self.group.axis_count()
    }
    fn um_per_count(&self, i: usize) -> f32 {
        self.group.axis(i).map_or(0.0, |a| a.um_per_count())
    }
    fn error_um(&self, positions_counts: &[i64; MAX_AXES]) -> ([f32; MAX_AXES], bool) {
        self.group.error_at(self.state, positions_counts)
    }
}

/// No correction (tests; a group without an image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Uncorrected {
    /// µm per count by slot.
    pub um_per_count: [f32; MAX_AXES],
    /// Axes.
    pub n_axes: usize,
}

impl LatchCorrection for Uncorrected {
    fn axis_count(&self) -> usize {
        self.n_axes
    }
    fn um_per_count(&self, i: usize) -> f32 {
        self.um_per_count.get(i).copied().unwrap_or(0.0)
    }
    fn error_um(&self, _: &[i64; MAX_AXES]) -> ([f32; MAX_AXES], bool) {
        ([0.0; MAX_AXES], false)
    }
}

/// Extends a counter value captured at an edge against an axis's extended position at its last
/// cycle (`position`, counter `last_raw`): exact while the axis moved less than half the counter
/// range between the edge and that cycle. `counter_bits` 1..=32.
pub fn extend_captured(position: i64, last_raw: u32, captured_raw: u32, counter_bits: u8) -> i64 {
    let shift = 32 - u32::from(counter_bits.clamp(1, 32));
    let delta = ((captured_raw.wrapping_sub(last_raw) << shift) as i32) >> shift;
    position.wrapping_add(i64::from(delta))
}

/// Extends a counter value captured at an edge for slot `i` of a loaded group against its state.
pub fn extend_captured_in_group<const POOL: usize>(
    group: &Group<POOL>,
    st: &GroupState,
    i: usize,
    captured_raw: u32,
) -> i64 {
    let (Some(a), Some(s)) = (group.axis(i), st.axes.get(i)) else {
        return 0;
    };
    extend_captured(
        s.position_counts(),
        s.counter_raw(),
        captured_raw,
        a.counter_bits(),
    )
}

/// Positions sampled every [`VELOCITY_STRIDE`] cycles, for the velocity at a leading edge.
#[derive(Debug, Clone, Copy, PartialEq)]
struct VelocityWindow {
    times: [u32; VELOCITY_SAMPLES],
    /// Low 32 bits of the extended positions (differences over the window are exact while an axis
    /// moves less than 2^31 counts in 4.8 ms).
    positions: [[i32; MAX_AXES]; VELOCITY_SAMPLES],
    /// Samples held (≤ VELOCITY_SAMPLES).
    held: u8,
    /// Index of the newest.
    newest: u8,
    /// Cycles since the newest sample.
    since: u32,
}

impl VelocityWindow {
    const NEW: VelocityWindow = VelocityWindow {
        times: [0; VELOCITY_SAMPLES],
        positions: [[0; MAX_AXES]; VELOCITY_SAMPLES],
        held: 0,
        newest: 0,
        since: 0,
    };

    fn push_cycle(&mut self, now: u32, positions: &[i64; MAX_AXES]) {
        if self.held > 0 && self.since + 1 < VELOCITY_STRIDE {
            self.since += 1;
            return;
        }
        self.since = 0;
        let next = if self.held == 0 {
            0
        } else {
            (self.newest as usize + 1) % VELOCITY_SAMPLES
        };
        self.times[next] = now;
        self.positions[next] = positions.map(|p| p as i32);
        self.newest = next as u8;
        self.held = (self.held + 1).min(VELOCITY_SAMPLES as u8);
    }

    /// Velocity (counts per second) by slot from the oldest to the newest sample; None with
    /// fewer than two samples.
    fn velocity(&self, tick_hz: u32) -> Option<[f32; MAX_AXES]> {
        if self.held < 2 {
            return None;
        }
        let newest = self.newest as usize;
        let oldest = (newest + VELOCITY_SAMPLES + 1 - self.held as usize) % VELOCITY_SAMPLES;
        let dt = self.times[newest].wrapping_sub(self.times[oldest]);
        if dt == 0 || dt > i32::MAX as u32 {
            return None;
        }
        // f32 (one hardware division; relative error ~1e-7, far below the counter's quantisation
        // over the window).
        let per_second = tick_hz as f32 / dt as f32;
        let mut v = [0.0f32; MAX_AXES];
        for (k, vk) in v.iter_mut().enumerate() {
            let d = self.positions[newest][k].wrapping_sub(self.positions[oldest][k]);
            *vk = d as f32 * per_second;
        }
        Some(v)
    }
}

/// A leading edge waiting for the filter.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Pending {
    time: u32,
    counts: [i64; MAX_AXES],
    velocity: Option<[f32; MAX_AXES]>,
    armed: bool,
    moving: bool,
}

/// Everything that changes while the probe input runs.
#[derive(Debug, Clone, PartialEq)]
pub struct ProbeState {
    level: bool,
    phase: ProbePhase,
    arm_command: bool,
    pending: Option<Pending>,
    /// Lockout of a contact: until this tick (valid while `in_contact`).
    lockout_until: u32,
    in_contact: bool,
    latch: Option<Latch>,
    latch_seq: u8,
    counters: ProbeCounters,
    window: VelocityWindow,
}

impl Default for ProbeState {
    fn default() -> Self {
        ProbeState::new()
    }
}

impl ProbeState {
    /// Level low, disarmed, nothing latched.
    pub const fn new() -> ProbeState {
        ProbeState {
            level: false,
            phase: ProbePhase::Disarmed,
            arm_command: false,
            pending: None,
            lockout_until: 0,
            in_contact: false,
            latch: None,
            latch_seq: 0,
            counters: ProbeCounters { events: [0; 6] },
            window: VelocityWindow::NEW,
        }
    }
    /// The phase of the probing move.
    pub fn phase(&self) -> ProbePhase {
        self.phase
    }
    /// The last latched trigger (kept after disarming, replaced by the next latch).
    pub fn latch(&self) -> Option<&Latch> {
        self.latch.as_ref()
    }
    /// Latches since start (wrapping `u8`: the CNC sees a new latch when it changes).
    pub fn latch_seq(&self) -> u8 {
        self.latch_seq
    }
    /// Event counters.
    pub fn counters(&self) -> &ProbeCounters {
        &self.counters
    }
    /// The filtered level's input level (true = deflected).
    pub fn level(&self) -> bool {
        self.level
    }
}

/// Inputs of one probe step (one drive cycle).
#[derive(Debug, Clone, Copy)]
pub struct ProbeInput<'a> {
    /// The cycle's time, ticks (every edge given is at or before it).
    pub now: u32,
    /// Every axis's extended position this cycle, by slot.
    pub positions: [i64; MAX_AXES],
    /// The CNC's arm command of this cycle (the last fresh one while frames are late).
    pub arm: bool,
    /// Edges since the previous step, oldest first.
    pub edges: &'a [ProbeEdge],
    /// The hook dropped edges since the previous step.
    pub edges_lost: bool,
    /// The input's level now (checked against the edges).
    pub level: bool,
}

/// The probe latch of a group (coefficients).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Probe {
    /// Settings in ticks.
    pub config: ProbeConfig,
}

impl Probe {
    /// No probe.
    pub const DISABLED: Probe = Probe {
        config: ProbeConfig::DISABLED,
    };

    /// One cycle: the edges since the last cycle in time order (filter, lockout, classification,
    /// latch), the pending edge's filter at `now`, then this cycle's arm command (edges happened
    /// under the previous command), then the velocity window. Returns this cycle's flags.
    pub fn step<C: LatchCorrection>(
        &self,
        st: &mut ProbeState,
        input: &ProbeInput,
        correction: &C,
    ) -> ProbeFlags {
        let mut flags = ProbeFlags::NONE;
        if !self.config.enabled {
            return flags;
        }
        let n = correction.axis_count().min(MAX_AXES);
        for e in input.edges.iter().take(MAX_EDGES_PER_CYCLE) {
            self.filter_until(st, e.time, correction, n, &mut flags);
            if e.level == st.level {
                // Two edges of the same direction: one in between was lost.
                self.lose_edges(st, &mut flags);
                continue;
            }
            st.level = e.level;
            // Part of the contact: its release (a falling edge while the contact is held), or
            // any edge within the lockout of the contact's previous edge.
            let in_lockout =
                st.in_contact && (!e.level || (e.time.wrapping_sub(st.lockout_until) as i32) < 0);
            if in_lockout {
                // An edge of the same contact: restart the lockout from it.
                st.lockout_until = e.time.wrapping_add(self.config.lockout_ticks);
                if e.level {
                    st.counters.count(ProbeEvent::Bounce);
                    flags.insert(ProbeEvent::Bounce.flag());
                }
                continue;
            }
            st.in_contact = false;
            if e.level {
                let velocity = st.window.velocity(self.config.tick_hz);
                let moving = velocity.is_some_and(|v| {
                    (0..n).any(|k| {
                        let s = v[k] * correction.um_per_count(k);
                        libm::fabsf(s) > self.config.moving_um_per_s
                    })
                });
                st.pending = Some(Pending {
                    time: e.time,
                    counts: e.counts,
                    velocity,
                    armed: st.phase == ProbePhase::Armed,
                    moving,
                });
            } else if st.pending.take().is_some() {
                st.counters.count(ProbeEvent::Glitch);
                flags.insert(ProbeEvent::Glitch.flag());
            }
        }
        if input.edges_lost || input.edges.len() > MAX_EDGES_PER_CYCLE || input.level != st.level {
            self.lose_edges(st, &mut flags);
            st.level = input.level;
        }
        self.filter_until(st, input.now, correction, n, &mut flags);

        // The arm command of this cycle.
        if input.arm && !st.arm_command {
            st.phase = ProbePhase::Armed;
        } else if !input.arm {
            st.phase = ProbePhase::Disarmed;
        }
        st.arm_command = input.arm;
        st.window.push_cycle(input.now, &input.positions);

        match st.phase {
            ProbePhase::Armed => flags.insert(ProbeFlags::ARMED),
            ProbePhase::Latched => flags.insert(ProbeFlags::LATCHED),
            ProbePhase::Disarmed => {}
        }
        if st.pending.is_some() {
            flags.insert(ProbeFlags::PENDING);
        }
        if st.level {
            flags.insert(ProbeFlags::LEVEL);
        }
        flags
    }

    /// Lost edges: the pending leading edge cannot be trusted (dropped); counted once per cycle.
    fn lose_edges(&self, st: &mut ProbeState, flags: &mut ProbeFlags) {
        st.pending = None;
        if !flags.has(ProbeEvent::EdgesLost) {
            st.counters.count(ProbeEvent::EdgesLost);
            flags.insert(ProbeEvent::EdgesLost.flag());
        }
    }

    /// Accepts the pending leading edge if the level has stayed true for `min_pulse` by `t`.
    fn filter_until<C: LatchCorrection>(
        &self,
        st: &mut ProbeState,
        t: u32,
        correction: &C,
        n: usize,
        flags: &mut ProbeFlags,
    ) {
        let Some(p) = st.pending else { return };
        let width = t.wrapping_sub(p.time);
        if width > i32::MAX as u32 || width < self.config.min_pulse_ticks {
            return;
        }
        st.pending = None;
        // A trigger: the contact's lockout runs from its leading edge.
        st.in_contact = true;
        st.lockout_until = p.time.wrapping_add(self.config.lockout_ticks);
        let event = if p.armed && st.phase == ProbePhase::Armed {
            st.latch = Some(self.latch_point(&p, correction, n));
            st.latch_seq = st.latch_seq.wrapping_add(1);
            st.phase = ProbePhase::Latched;
            ProbeEvent::Latched
        } else if p.moving {
            ProbeEvent::TriggerDuringMove
        } else {
            ProbeEvent::UnarmedTrigger
        };
        st.counters.count(event);
        flags.insert(event.flag());
    }

    /// The latched point of a trigger: captured counts − v·latency, in µm, + the loop's error at
    /// the captured counts, rounded to nanometres (v·latency in f32, the sum in f64: the counts are
    /// exact below 2^53).
    fn latch_point<C: LatchCorrection>(&self, p: &Pending, correction: &C, n: usize) -> Latch {
        let (error_um, limited) = correction.error_um(&p.counts);
        let mut quality = ProbeFlags::NONE;
        if limited {
            quality.insert(ProbeFlags::CORRECTION_LIMITED);
        }
        let v = p.velocity.unwrap_or_else(|| {
            quality.insert(ProbeFlags::NO_VELOCITY);
            [0.0; MAX_AXES]
        });
        let mut point_nm = [0i64; MAX_AXES];
        for k in 0..n {
            let upc = correction.um_per_count(k) as f64;
            let counts = p.counts[k] as f64 - (v[k] * self.config.latency_s) as f64;
            let um = counts * upc + error_um[k] as f64;
            point_nm[k] = libm::round(um * 1000.0) as i64;
        }
        Latch {
            time: p.time,
            captured_counts: p.counts,
            velocity_counts_per_s: v,
            error_um,
            point_nm,
            n_axes: n as u8,
            quality,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// 1 MHz ticks: one tick = 1 µs, easy to read.
    const HZ: u32 = 1_000_000;
    const UPC: f32 = 0.1;

    fn probe(min_pulse_us: u32, latency_ns: u32, lockout_us: u32) -> Probe {
        Probe {
            config: ProbeConfig::new(
                &ProbeSettings {
                    min_pulse_us,
                    latency_ns,
                    lockout_us,
                    moving_um_per_s: 50.0,
                },
                HZ,
            )
            .unwrap(),
        }
    }

    fn one_axis() -> Uncorrected {
        Uncorrected {
            um_per_count: [UPC; MAX_AXES],
            n_axes: 1,
        }
    }

    /// A host fake of the board: one axis moving at `v` counts per second from 0, cycles of
    /// 100 µs, edges at given times with the counts at that instant (floor, as a counter).
    struct Rig {
        probe: Probe,
        st: ProbeState,
        v: f64,
        t: u32,
        pending_edges: std::vec::Vec<ProbeEdge>,
        level: bool,
        arm: bool,
    }

    extern crate std;

    impl Rig {
        fn new(probe: Probe, v: f64) -> Rig {
            Rig {
                probe,
                st: ProbeState::new(),
                v,
                t: 0,
                pending_edges: std::vec::Vec::new(),
                level: false,
                arm: false,
            }
        }
        fn pos(&self, t: u32) -> i64 {
            libm::floor(self.v * t as f64 / HZ as f64) as i64
        }
        fn edge(&mut self, t: u32, level: bool) {
            let mut counts = [0; MAX_AXES];
            counts[0] = self.pos(t);
            self.pending_edges.push(ProbeEdge {
                time: t,
                level,
                counts,
            });
        }
        /// Runs cycles up to time `until`; returns the OR of the flags.
        fn run_to(&mut self, until: u32) -> ProbeFlags {
            let mut all = ProbeFlags::NONE;
            while self.t < until {
                self.t += 100;
                let (now_edges, later): (std::vec::Vec<_>, std::vec::Vec<_>) =
                    self.pending_edges.iter().partition(|e| e.time <= self.t);
                self.pending_edges = later;
                if let Some(e) = now_edges.last() {
                    self.level = e.level;
                }
                let level = self.level;
                let mut positions = [0; MAX_AXES];
                positions[0] = self.pos(self.t);
                let f = self.probe.step(
                    &mut self.st,
                    &ProbeInput {
                        now: self.t,
                        positions,
                        arm: self.arm,
                        edges: &now_edges,
                        edges_lost: false,
                        level,
                    },
                    &one_axis(),
                );
                all.insert(f);
            }
            all
        }
    }

    /// A pulse shorter than the filter never latches, even while armed; one as long latches
    /// the counts of its leading edge (not those at acceptance, 2 ms later).
    #[test]
    fn glitch_shorter_than_the_filter_never_latches() {
        // 1000 mm/min = 16 666.7 µm/s = 166 667 counts/s at 0.1 µm per count.
        let mut r = Rig::new(probe(2_000, 0, 20_000), 166_666.7);
        r.arm = true;
        r.run_to(10_000);
        for (start, width) in [(10_050u32, 1_999u32), (20_000, 1), (30_020, 500)] {
            r.edge(start, true);
            r.edge(start + width, false);
            let f = r.run_to(start + 5_000);
            assert!(f.has(ProbeEvent::Glitch), "{start}");
            assert!(!f.has(ProbeEvent::Latched));
        }
        assert_eq!(r.st.latch(), None);
        assert_eq!(r.st.counters().get(ProbeEvent::Glitch), 3);
        assert_eq!(r.st.phase(), ProbePhase::Armed);
        // Exactly the filter width: accepted, latched at the leading edge's counts.
        r.edge(40_030, true);
        let f = r.run_to(42_000);
        assert!(!f.has(ProbeEvent::Latched), "not before 2 ms");
        let f = r.run_to(42_100);
        assert!(f.has(ProbeEvent::Latched));
        let l = *r.st.latch().unwrap();
        assert_eq!(l.captured_counts[0], r.pos(40_030));
        assert_eq!(l.time, 40_030);
        assert_eq!(r.st.phase(), ProbePhase::Latched);
    }

    /// Bounce inside the lockout never latches twice; the lockout restarts at each edge of the
    /// contact and the release starts a last window (release chatter is bounce too); after it,
    /// a new contact while latched (not armed) is an unarmed trigger, never a second latch.
    #[test]
    fn bounce_never_latches_twice() {
        let mut r = Rig::new(probe(2_000, 0, 20_000), 0.0);
        r.arm = true;
        r.run_to(1_000);
        r.edge(1_050, true);
        // Bounce during deceleration: 3 ms later, and 5 ms after (each pulse ≥ the filter).
        r.edge(4_000, false);
        r.edge(4_100, true);
        r.edge(9_000, false);
        r.edge(9_200, true);
        let f = r.run_to(30_000);
        assert!(f.has(ProbeEvent::Latched) && f.has(ProbeEvent::Bounce));
        assert_eq!(r.st.counters().get(ProbeEvent::Latched), 1);
        assert_eq!(r.st.counters().get(ProbeEvent::Bounce), 2);
        assert_eq!(r.st.latch().unwrap().time, 1_050);
        // Held 30 ms (beyond the lockout), then released with chatter: still the same contact.
        r.edge(40_000, false);
        r.edge(41_000, true);
        r.edge(44_500, false);
        let f = r.run_to(50_000);
        assert!(f.has(ProbeEvent::Bounce) && !f.has(ProbeEvent::Glitch));
        assert_eq!(r.st.counters().get(ProbeEvent::Bounce), 3);
        assert_eq!(r.st.counters().get(ProbeEvent::Latched), 1);
        // A new contact after the lockout while latched (not armed): an unarmed trigger.
        r.edge(100_000, true);
        r.edge(105_000, false);
        let f = r.run_to(110_000);
        assert!(f.has(ProbeEvent::UnarmedTrigger));
        assert_eq!(r.st.counters().get(ProbeEvent::Latched), 1);
        assert_eq!(r.st.latch().unwrap().time, 1_050);
        // Re-arming starts a new probing move: the next trigger latches.
        r.arm = false;
        r.run_to(110_100);
        r.arm = true;
        r.edge(130_000, true);
        r.run_to(135_000);
        assert_eq!(r.st.counters().get(ProbeEvent::Latched), 2);
        assert_eq!(r.st.latch_seq(), 2);
        assert_eq!(r.st.latch().unwrap().time, 130_000);
    }

    /// A trigger while not armed is counted as unarmed at rest and as a trigger during a move
    /// while an axis moves (a rapid), never latched.
    #[test]
    fn unarmed_and_rapid_triggers_are_counted_not_latched() {
        // At rest.
        let mut r = Rig::new(probe(2_000, 0, 20_000), 0.0);
        r.run_to(10_000);
        r.edge(10_000, true);
        r.edge(15_000, false);
        let f = r.run_to(20_000);
        assert!(f.has(ProbeEvent::UnarmedTrigger) && !f.has(ProbeEvent::TriggerDuringMove));
        assert_eq!(r.st.latch(), None);
        // A rapid at 10 m/min (1 666 667 counts/s).
        let mut r = Rig::new(probe(2_000, 0, 20_000), 1_666_667.0);
        r.run_to(10_000);
        r.edge(10_000, true);
        r.edge(15_000, false);
        let f = r.run_to(20_000);
        assert!(f.has(ProbeEvent::TriggerDuringMove));
        assert_eq!(r.st.counters().get(ProbeEvent::TriggerDuringMove), 1);
        assert_eq!(r.st.counters().get(ProbeEvent::Latched), 0);
        assert_eq!(r.st.latch(), None);
    }

    /// Latency compensation: the probe's signal arrives 1 ms after the touch; the latched point
    /// is within one count (the counter's quantisation, 0.1 µm) of the true touch position.
    /// Reference: the rig's exact position v·t at the touch; tolerance 0.1 µm + 0.01 µm for the
    /// velocity window (a 1-count error over 48 cycles, times 1 ms).
    #[test]
    fn latency_compensation_recovers_the_touch() {
        let v = 166_666.7; // counts/s: 1000 mm/min at 0.1 µm per count
        let mut r = Rig::new(probe(2_000, 1_000_000, 20_000), v);
        r.arm = true;
        r.run_to(20_000);
        let touch = 23_456u32;
        r.edge(touch + 1_000, true);
        r.run_to(30_000);
        let l = *r.st.latch().unwrap();
        let truth_um = v * touch as f64 / HZ as f64 * UPC as f64;
        let got_um = l.point_nm[0] as f64 / 1000.0;
        let uncompensated_um = l.captured_counts[0] as f64 * UPC as f64;
        assert!(
            (got_um - truth_um).abs() <= 0.11,
            "latched {got_um} µm, true {truth_um} µm"
        );
        assert!(
            (uncompensated_um - truth_um - 16.67).abs() < 0.2,
            "1 ms at 16.7 µm/ms"
        );
        assert!(!l.quality.contains(ProbeFlags::NO_VELOCITY));
    }

    /// Edges lost or a level contradicting them: the pending edge is dropped, never latched.
    #[test]
    fn lost_edges_drop_the_pending_trigger() {
        let p = probe(2_000, 0, 20_000);
        let mut st = ProbeState::new();
        let c = one_axis();
        let mut inp = ProbeInput {
            now: 100,
            positions: [0; MAX_AXES],
            arm: true,
            edges: &[],
            edges_lost: false,
            level: false,
        };
        p.step(&mut st, &inp, &c);
        let e = [ProbeEdge {
            time: 150,
            level: true,
            counts: [7; MAX_AXES],
        }];
        inp.now = 200;
        inp.edges = &e;
        inp.level = true;
        assert!(p.step(&mut st, &inp, &c).contains(ProbeFlags::PENDING));
        inp.now = 300;
        inp.edges = &[];
        inp.edges_lost = true;
        let f = p.step(&mut st, &inp, &c);
        assert!(f.has(ProbeEvent::EdgesLost) && !f.contains(ProbeFlags::PENDING));
        inp.edges_lost = false;
        inp.now = 5_000;
        assert!(!p.step(&mut st, &inp, &c).has(ProbeEvent::Latched));
        assert_eq!(st.latch(), None);
    }

    #[test]
    fn settings_roundtrip_and_are_validated() {
        let s = ProbeSettings::RECOMMENDED;
        assert_eq!(ProbeSettings::from_bytes(&s.to_bytes()), Ok(s));
        let bad = |f: fn(&mut ProbeSettings)| {
            let mut t = s;
            f(&mut t);
            ProbeSettings::from_bytes(&t.to_bytes()).unwrap_err()
        };
        assert!(matches!(
            bad(|t| t.min_pulse_us = 100_001),
            ImageError::OutOfRange {
                field: Field::ProbeMinPulse,
                ..
            }
        ));
        assert!(matches!(
            bad(|t| t.lockout_us = 1_000),
            ImageError::OutOfRange {
                field: Field::ProbeLockout,
                ..
            }
        ));
        assert!(matches!(
            bad(|t| t.moving_um_per_s = f32::NAN),
            ImageError::NonFinite {
                field: Field::ProbeMovingSpeed,
                ..
            }
        ));
        assert!(matches!(
            bad(|t| t.latency_ns = u32::MAX),
            ImageError::OutOfRange {
                field: Field::ProbeLatency,
                ..
            }
        ));
        let mut b = s.to_bytes();
        b[16] = 1;
        assert!(ProbeSettings::from_bytes(&b).is_err(), "reserved");
        assert_eq!(
            ProbeSettings::from_bytes(&b[..19]),
            Err(ImageError::BadLength)
        );
    }

    #[test]
    fn captured_counts_extend_through_the_counter_wrap() {
        // 16-bit counter: last cycle at raw 0xFFF0 = extended 65 520; captured 0x0010 after the wrap.
        assert_eq!(extend_captured(65_520, 0xFFF0, 0x0010, 16), 65_552);
        assert_eq!(extend_captured(65_520, 0xFFF0, 0xFFE0, 16), 65_504);
        assert_eq!(extend_captured(-5, 0xFFFF_FFFB, 0xFFFF_FFF0, 32), -16);
    }
}
