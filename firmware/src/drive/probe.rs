//! The touch-probe input of the group drive ([`super::group::GroupDrive`]): the board hook
//! ([`ProbeIo`]: edges with every encoder's captured counter value and their time), the drive's side
//! of the latch ([`ProbeDrive`]: arming from the setpoint frames, captured counters extended per axis,
//! the core's [`axcomp_core::probe::Probe`] with the group engine's correction, the v3 reply block,
//! the status-word flags).
//!
//! The logic is the core's, so the host replay and the firmware latch the same point bit for bit;
//! this module only maps board inputs to group slots and frames to commands.
//!
//! - **Time base**: the drive's cycle clock (`CycleClock` ticks: DWT at 170 MHz on the STM32G474);
//!   edges are stamped on the same clock, the cycle's time is its start tick. The probe settings (µs,
//!   ns) are converted with the clock's rate ([`ProbeDrive::new`]).
//! - **Arming**: the probe byte of the newest fresh setpoint frame (v3; a v2 frame disarms); held
//!   while frames are late, like the commands.
//! - **Without probe settings** in the running image, nothing is read, counted or reported, and the
//!   replies stay v2 byte for byte.

use axcomp_core::group::{GroupEngine, MAX_AXES};
use axcomp_core::probe::{
    GroupCorrection, MAX_EDGES_PER_CYCLE, Probe, ProbeConfig, ProbeEdge, ProbeEvent, ProbeFlags,
    ProbeInput, ProbeSettings, ProbeState, extend_captured_in_group,
};

use crate::setpoint::{PROBE_ITEM_COUNTER, ProbeReply, SetpointFrame};
use crate::status::Status;

/// One edge of the probe input as the board captured it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CapturedEdge {
    /// Cycle-clock ticks at the edge.
    pub time: u32,
    /// Level after the edge (true = deflected).
    pub level: bool,
    /// Every scale input's raw counter at the edge, by board input (hardware input capture).
    pub scale_raw: [u32; MAX_AXES],
}

/// The board's probe input: on the STM32G474 an EXTI/timer-capture interrupt that latches every
/// encoder timer's counter (input capture) and the cycle clock at each edge into a small queue.
pub trait ProbeIo {
    /// Moves the edges captured since the last call (oldest first) into `out`; returns how many, and
    /// true if the queue overflowed (edges were lost).
    fn read_edges(&mut self, out: &mut [CapturedEdge; MAX_EDGES_PER_CYCLE]) -> (usize, bool);
    /// The input's level now (true = deflected).
    fn level(&mut self) -> bool;
}

/// A board without a probe input.
#[derive(Clone, Copy, Debug, Default)]
pub struct NoProbe;

impl ProbeIo for NoProbe {
    fn read_edges(&mut self, _: &mut [CapturedEdge; MAX_EDGES_PER_CYCLE]) -> (usize, bool) {
        (0, false)
    }
    fn level(&mut self) -> bool {
        false
    }
}

/// Host fake of the probe input: a queue the test (or the trace replay) fills.
#[derive(Clone, Debug, Default)]
pub struct FakeProbe {
    queue: [CapturedEdge; 32],
    len: usize,
    level: bool,
    lost: bool,
}

impl FakeProbe {
    /// Empty queue, level low.
    pub const fn new() -> Self {
        FakeProbe {
            queue: [CapturedEdge {
                time: 0,
                level: false,
                scale_raw: [0; MAX_AXES],
            }; 32],
            len: 0,
            level: false,
            lost: false,
        }
    }
    /// An edge happens (queued for the next cycle; a full queue loses it, as the board's would).
    pub fn push(&mut self, edge: CapturedEdge) {
        self.level = edge.level;
        if let Some(slot) = self.queue.get_mut(self.len) {
            *slot = edge;
            self.len += 1;
        } else {
            self.lost = true;
        }
    }
}

impl ProbeIo for FakeProbe {
    fn read_edges(&mut self, out: &mut [CapturedEdge; MAX_EDGES_PER_CYCLE]) -> (usize, bool) {
        let n = self.len.min(MAX_EDGES_PER_CYCLE);
        out[..n].copy_from_slice(&self.queue[..n]);
        self.queue.copy_within(n..self.len, 0);
        self.len -= n;
        // More than a cycle takes stays queued for the next one (not lost).
        (n, core::mem::take(&mut self.lost))
    }
    fn level(&mut self) -> bool {
        // The level after the last edge handed out (queued edges have not happened for the drive).
        if self.len == 0 {
            self.level
        } else {
            !self.queue[0].level
        }
    }
}

/// The drive's side of the probe latch.
#[derive(Clone, Debug)]
pub struct ProbeDrive {
    probe: Probe,
    state: ProbeState,
    tick_hz: u32,
    settings: Option<ProbeSettings>,
    arm: bool,
    next_item: u8,
}

impl ProbeDrive {
    /// Disabled until an image with probe settings runs; `tick_hz` = cycle-clock ticks per second.
    pub const fn new(tick_hz: u32) -> Self {
        ProbeDrive {
            probe: Probe::DISABLED,
            state: ProbeState::new(),
            tick_hz,
            settings: None,
            arm: false,
            next_item: 0,
        }
    }

    /// The running image's probe settings (`None`: no probe). The latch state (a pending edge, the
    /// latched point, the counters) carries over an image swap with the same settings; other settings
    /// start a fresh state.
    pub fn configure(&mut self, settings: Option<ProbeSettings>) {
        if settings == self.settings {
            return;
        }
        self.settings = settings;
        self.probe = settings
            .and_then(|s| ProbeConfig::new(&s, self.tick_hz).ok())
            .map_or(Probe::DISABLED, |config| Probe { config });
        self.state = ProbeState::new();
        self.next_item = 0;
    }

    /// True while the running image has probe settings.
    pub fn enabled(&self) -> bool {
        self.probe.config.enabled
    }

    /// The latch's state (phase, latched point, counters).
    pub fn state(&self) -> &ProbeState {
        &self.state
    }

    /// A fresh setpoint frame: its probe command (a v2 frame disarms).
    pub fn take_frame(&mut self, frame: &SetpointFrame) {
        self.arm = frame.probe_armed();
    }

    /// One cycle after the engine's: the edges since the last cycle with their counters extended
    /// against each axis's state of this cycle, the arm command, the latch with the engine's
    /// correction. `now` = the cycle's start tick; `inputs` = the board input of each group slot.
    #[inline(never)]
    pub fn cycle<const POOL: usize, P: ProbeIo>(
        &mut self,
        engine: &GroupEngine<POOL>,
        io: &mut P,
        now: u32,
        inputs: &[u8],
    ) -> ProbeFlags {
        if !self.enabled() {
            return ProbeFlags::NONE;
        }
        let group = engine.active();
        let st = engine.state();
        let n = inputs.len().min(MAX_AXES).min(group.axis_count());
        let mut raw = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        let (got, lost) = io.read_edges(&mut raw);
        let mut edges = [ProbeEdge {
            time: 0,
            level: false,
            counts: [0; MAX_AXES],
        }; MAX_EDGES_PER_CYCLE];
        for (e, r) in edges.iter_mut().zip(raw.iter()).take(got) {
            e.time = r.time;
            e.level = r.level;
            for (slot, &input) in inputs.iter().enumerate().take(n) {
                let captured = r.scale_raw.get(usize::from(input)).copied().unwrap_or(0);
                e.counts[slot] = extend_captured_in_group(group, st, slot, captured);
            }
        }
        let mut positions = [0i64; MAX_AXES];
        for (slot, p) in positions.iter_mut().enumerate().take(n) {
            *p = st.axes[slot].position_counts();
        }
        let input = ProbeInput {
            now,
            positions,
            arm: self.arm,
            edges: &edges[..got.min(MAX_EDGES_PER_CYCLE)],
            edges_lost: lost,
            level: io.level(),
        };
        self.probe.step(
            &mut self.state,
            &input,
            &GroupCorrection { group, state: st },
        )
    }

    /// The status-word bits of a cycle's probe flags.
    #[inline(never)]
    pub fn status(flags: ProbeFlags) -> Status {
        let mut s = Status::NONE;
        s.set(Status::PROBE_LATCHED, flags.has(ProbeEvent::Latched));
        s.set(Status::PROBE_GLITCH, flags.has(ProbeEvent::Glitch));
        s.set(Status::PROBE_BOUNCE, flags.has(ProbeEvent::Bounce));
        s.set(Status::PROBE_UNARMED, flags.has(ProbeEvent::UnarmedTrigger));
        s.set(
            Status::PROBE_DURING_MOVE,
            flags.has(ProbeEvent::TriggerDuringMove),
        );
        s.set(Status::PROBE_EDGES_LOST, flags.has(ProbeEvent::EdgesLost));
        s
    }

    /// The v3 reply block of this cycle: the flags, the latch sequence and the next item round robin
    /// (the latched point of each of the `n_inputs` board inputs, then the event counters).
    /// `inputs` = the board input of each group slot.
    #[inline(never)]
    pub fn reply(&mut self, flags: ProbeFlags, inputs: &[u8], n_inputs: usize) -> ProbeReply {
        let n_items = n_inputs + ProbeEvent::ALL.len();
        let k = usize::from(self.next_item) % n_items.max(1);
        self.next_item = ((k + 1) % n_items.max(1)) as u8;
        let (item, value) = if k < n_inputs {
            let nm = inputs
                .iter()
                .position(|&i| usize::from(i) == k)
                .and_then(|slot| self.state.latch().map(|l| l.point_nm[slot]))
                .unwrap_or(0);
            (k as u8, nm.clamp(i32::MIN as i64, i32::MAX as i64) as i32)
        } else {
            let e = ProbeEvent::ALL[k - n_inputs];
            (
                PROBE_ITEM_COUNTER + e as u8,
                self.state.counters().get(e) as i32,
            )
        };
        ProbeReply {
            flags: flags.bits(),
            latch_seq: self.state.latch_seq(),
            item,
            value,
        }
    }
}

/// The probe traces' group image (host only): X, Y, Z with axis ids 1, 2, 3 (the replay board's
/// wiring), 16-bit counters, 0.1 µm per count, one linear table per axis (error = a + b·x, so that a
/// test knows the true error analytically: [`write::table_error_um`]), and the probe settings.
#[cfg(any(test, feature = "std"))]
pub mod write {
    extern crate std;
    use std::vec::Vec;

    use axcomp_core::group::AxisName;
    use axcomp_core::group_image::{
        AxisSectionSpec, group_image_len_with_probe, write_group_image_with_probe,
    };
    use axcomp_core::probe::ProbeSettings;
    use axcomp_core::{
        ImageError, ImageSpec, LimitSpec, OutsideStroke, TableSpec, image_len, write_image,
    };

    /// µm per count of every axis.
    pub const UM_PER_COUNT: f32 = 0.1;
    /// Knot spacing, counts (1 mm).
    pub const SEGMENT_COUNTS: u32 = 10_000;
    /// Segments (stroke 0…100 mm).
    pub const SEGMENTS: usize = 100;
    /// Error at 0 (µm) and per segment (µm per mm) of X, Y, Z.
    pub const TABLE_LINES: [(f32, f32); 3] = [(2.0, 0.01), (-1.5, 0.02), (0.5, -0.01)];
    /// The probe settings of the probe traces: the seed's 2 ms filter, 850 µs latency (a radio
    /// probe's receiver), 20 ms lockout, 50 µm/s for "moving".
    pub const SETTINGS: ProbeSettings = ProbeSettings {
        min_pulse_us: 2_000,
        latency_ns: 850_000,
        lockout_us: 20_000,
        moving_um_per_s: 50.0,
    };

    /// The table's error of axis `k` at `counts` (f64, analytic: a + b·counts/segment), µm.
    pub fn table_error_um(k: usize, counts: f64) -> f64 {
        let (a, b) = TABLE_LINES[k];
        a as f64 + b as f64 * counts / SEGMENT_COUNTS as f64
    }

    /// The group image, with `probe` settings (section kind 4) or without.
    pub fn probe_group_image(probe: Option<&ProbeSettings>) -> Result<Vec<u8>, ImageError> {
        let tables: Vec<Vec<[f32; 4]>> = TABLE_LINES
            .iter()
            .map(|&(a, b)| {
                (0..SEGMENTS)
                    .map(|k| [a + b * k as f32, b, 0.0, 0.0])
                    .collect()
            })
            .collect();
        let mut images = Vec::new();
        for (k, t) in tables.iter().enumerate() {
            let spec = ImageSpec {
                axis_id: k as u16 + 1,
                um_per_count: UM_PER_COUNT,
                counter_bits: 16,
                table: Some(TableSpec {
                    start_counts: 0,
                    segment_counts: SEGMENT_COUNTS,
                    forward: t,
                    backward: &[],
                    outside: OutsideStroke::Hold,
                }),
                thermo: None,
                limits: LimitSpec {
                    max_correction_um: 50.0,
                    max_slew_um_per_cycle: 0.5,
                    direction_hysteresis_counts: 20,
                },
            };
            let mut buf = std::vec![0u8; image_len(&spec)];
            let n = write_image(&spec, &mut buf)?;
            buf.truncate(n);
            images.push(buf);
        }
        let names = [AxisName::X, AxisName::Y, AxisName::Z];
        let axes: Vec<AxisSectionSpec> = images
            .iter()
            .zip(names)
            .map(|(img, name)| AxisSectionSpec {
                name,
                counts_per_rev: 0,
                stroke_counts: None,
                image: img,
                sensor_names: &[],
            })
            .collect();
        let mut out = std::vec![0u8; group_image_len_with_probe(&axes, None, probe)];
        let n = write_group_image_with_probe(&axes, None, probe, &mut out)?;
        out.truncate(n);
        Ok(out)
    }
}

#[cfg(test)]
mod tests {
    extern crate std;
    use core::cell::Cell;
    use std::vec::Vec;

    use super::*;
    use crate::control::CycleClock;
    use crate::drive::NoWatchdog;
    use crate::drive::fake::FakeDriveIo;
    use crate::drive::group::GroupDrive;
    use crate::drive::link_trace::replay_drive;
    use crate::setpoint::{
        MAX_SETPOINT_FRAME_LEN, PROBE_ARM, ReplyDecoder, ReplyFrame, VERSION, VERSION_PROBE,
    };
    use axcomp_core::probe::ProbeEvent;

    /// 170 MHz cycle clock, 17 000 ticks per 10 kHz cycle (the replay board's).
    const TICKS: u32 = 17_000;
    const POOL: usize = 1024;

    struct Clock(Cell<u32>);
    impl CycleClock for Clock {
        fn now(&self) -> u32 {
            self.0.get()
        }
    }

    /// A 3-axis drive with the probe image, X moving at `counts_per_cycle`, frames armed or not.
    struct Bench {
        drive: GroupDrive,
        engine: std::boxed::Box<GroupEngine<POOL>>,
        io: FakeDriveIo,
        probe: FakeProbe,
        /// Edges that have not happened yet at the present cycle.
        future: Vec<CapturedEdge>,
        clock: Clock,
        cycle: u32,
        seq: u8,
        x0: f64,
        counts_per_cycle: f64,
        arm: Option<bool>,
    }

    impl Bench {
        fn new(settings: Option<&ProbeSettings>) -> Bench {
            let mut drive = replay_drive();
            let mut engine = std::boxed::Box::new(GroupEngine::<POOL>::new());
            engine.init();
            let image = write::probe_group_image(settings).unwrap();
            drive.offer_image(&mut engine, &image).unwrap();
            Bench {
                drive,
                engine,
                io: FakeDriveIo::default(),
                probe: FakeProbe::new(),
                future: Vec::new(),
                clock: Clock(Cell::new(0)),
                cycle: 0,
                seq: 0,
                x0: 20_000.0,
                counts_per_cycle: 0.0,
                arm: Some(false),
            }
        }
        fn x_at(&self, ticks: u32) -> f64 {
            self.x0 + self.counts_per_cycle * ticks as f64 / TICKS as f64
        }
        fn raw_at(&self, ticks: u32) -> [u32; MAX_AXES] {
            [
                (self.x_at(ticks).floor() as i64 as u32) & 0xFFFF,
                10_000,
                5_000,
                0,
                0,
            ]
        }
        /// An edge at `cycle` + `frac` of a cycle.
        fn edge(&mut self, cycle: f64, level: bool) {
            let t = (cycle * TICKS as f64) as u32;
            self.future.push(CapturedEdge {
                time: t,
                level,
                scale_raw: self.raw_at(t),
            });
        }
        fn run(&mut self, cycles: u32) -> (Status, Vec<Vec<u8>>) {
            let mut status = Status::NONE;
            let mut replies = Vec::new();
            for _ in 0..cycles {
                let now = self.cycle * TICKS;
                // Edges up to this cycle's start have happened: the board captured them.
                let (happened, future): (Vec<_>, Vec<_>) =
                    self.future.iter().partition(|e| e.time <= now);
                self.future = future;
                for e in happened {
                    self.probe.push(e);
                }
                self.seq = self.seq.wrapping_add(1);
                let x = self.x_at(now);
                let cmds = [x.round() as i32, 10_000, 5_000];
                let mut f = SetpointFrame::new(self.seq, &cmds).unwrap();
                if let Some(a) = self.arm {
                    f = f.with_probe(if a { PROBE_ARM } else { 0 });
                }
                let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
                let n = f.encode_into(&mut b);
                self.io.rx.extend(&b[..n]);
                self.io.scales = self.raw_at(now);
                self.clock.0.set(now);
                let c = self.drive.cycle_with_probe(
                    &mut self.engine,
                    &mut self.io,
                    &mut self.probe,
                    &self.clock,
                    &mut NoWatchdog,
                );
                status.insert(c.status);
                replies.push(self.io.tx.pop().unwrap());
                self.cycle += 1;
            }
            (status, replies)
        }
    }

    fn decode(replies: &[Vec<u8>]) -> Vec<ReplyFrame> {
        let mut d = ReplyDecoder::new();
        replies.iter().filter_map(|r| d.push_bytes(r)).collect()
    }

    /// An armed probing move at 1000 mm/min: the latched point goes out in the v3 replies (every
    /// board input's point, then the counters) and the status word flags the latch cycle.
    #[test]
    fn the_drive_latches_reports_and_flags_a_trigger() {
        let mut b = Bench::new(Some(&write::SETTINGS));
        b.counts_per_cycle = 16.666_667; // 1000 mm/min at 0.1 µm per count
        b.arm = Some(true);
        b.run(100);
        b.edge(100.37, true);
        // Leading edge at tick 1 706 290; 2 ms = 340 000 ticks later is in cycle 120: the latch is
        // taken at the start of cycle 121.
        let (status, _) = b.run(21);
        assert!(!status.contains(Status::PROBE_LATCHED), "before 2 ms");
        let (status, _) = b.run(1);
        assert!(status.contains(Status::PROBE_LATCHED));
        let latch = *b.drive.probe().state().latch().unwrap();
        let (_, replies) = b.run(12);
        let frames = decode(&replies);
        assert_eq!(frames.len(), 12);
        for f in &frames {
            let p = f.probe.expect("v3 reply");
            assert_eq!(p.latch_seq, 1);
            assert!(ProbeFlags(p.flags).contains(ProbeFlags::LATCHED));
            if usize::from(p.item) < 3 {
                assert_eq!(i64::from(p.value), latch.point_nm[usize::from(p.item)]);
            } else if p.item == PROBE_ITEM_COUNTER + ProbeEvent::Latched as u8 {
                assert_eq!(p.value, 1);
            }
        }
        let items: std::collections::BTreeSet<u8> =
            frames.iter().map(|f| f.probe.unwrap().item).collect();
        assert_eq!(
            items.len(),
            3 + 6,
            "every input and counter within n + 6 cycles"
        );
        // The point: within 0.5 µm of the true touch (850 µs before the edge), corrected by the
        // table (reference: the bench's exact motion and the table's analytic error).
        let t_touch = 100.37 * TICKS as f64 - 850e-6 * 170e6;
        let x = b.x0 + b.counts_per_cycle * t_touch / TICKS as f64;
        let truth_um = x * 0.1 + write::table_error_um(0, x);
        let got_um = latch.point_nm[0] as f64 / 1000.0;
        assert!((got_um - truth_um).abs() <= 0.5, "{got_um} vs {truth_um}");
    }

    /// A glitch shorter than the filter, bounce, an unarmed trigger and one during a rapid: flagged in
    /// the status word of their cycle, counted, never latched.
    #[test]
    fn rejected_triggers_are_flagged_in_the_status_word() {
        let mut b = Bench::new(Some(&write::SETTINGS));
        b.arm = Some(true);
        b.run(50);
        b.edge(50.5, true);
        b.edge(50.5 + 19.0, false); // 1.9 ms
        let (status, _) = b.run(30);
        assert!(status.contains(Status::PROBE_GLITCH) && !status.contains(Status::PROBE_LATCHED));
        b.edge(80.2, true);
        b.edge(120.0, false);
        b.edge(121.0, true); // bounce
        b.edge(125.0, false);
        let (status, _) = b.run(100);
        assert!(status.contains(Status::PROBE_LATCHED) && status.contains(Status::PROBE_BOUNCE));
        b.arm = Some(false);
        b.run(400);
        b.edge(600.1, true);
        b.edge(700.1, false);
        let (status, _) = b.run(400);
        assert!(status.contains(Status::PROBE_UNARMED));
        b.counts_per_cycle = 166.7; // 10 m/min
        b.x0 -= 166.7 * 1000.0;
        b.run(100);
        b.edge(1100.3, true);
        b.edge(1140.3, false);
        let (status, _) = b.run(100);
        assert!(status.contains(Status::PROBE_DURING_MOVE));
        let c = b.drive.probe().state().counters();
        assert_eq!(
            ProbeEvent::ALL.map(|e| c.get(e)),
            [1, 1, 1, 1, 1, 0],
            "latched, glitch, bounce, unarmed, during a move, lost"
        );
    }

    /// Without probe settings the drive sends v2 replies, byte for byte those of `cycle` (no probe
    /// input); with them, v3.
    #[test]
    fn without_probe_settings_replies_stay_v2() {
        let mut a = Bench::new(None);
        a.arm = None;
        a.counts_per_cycle = 3.0;
        let (_, with_probe_io) = a.run(50);
        assert!(with_probe_io.iter().all(|r| r[1] >> 4 == VERSION));
        let mut b = Bench::new(None);
        b.arm = None;
        b.counts_per_cycle = 3.0;
        let mut plain = Vec::new();
        for _ in 0..50 {
            let now = b.cycle * TICKS;
            b.seq = b.seq.wrapping_add(1);
            let f =
                SetpointFrame::new(b.seq, &[b.x_at(now).round() as i32, 10_000, 5_000]).unwrap();
            let mut buf = [0u8; MAX_SETPOINT_FRAME_LEN];
            let n = f.encode_into(&mut buf);
            b.io.rx.extend(&buf[..n]);
            b.io.scales = b.raw_at(now);
            b.clock.0.set(now);
            b.drive
                .cycle(&mut b.engine, &mut b.io, &b.clock, &mut NoWatchdog);
            plain.push(b.io.tx.pop().unwrap());
            b.cycle += 1;
        }
        assert_eq!(with_probe_io, plain);
        let mut c = Bench::new(Some(&write::SETTINGS));
        let (_, r) = c.run(3);
        assert!(r.iter().all(|r| r[1] >> 4 == VERSION_PROBE));
    }
}
