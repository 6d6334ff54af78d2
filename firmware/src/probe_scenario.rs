//! The touch-probe drive trace: a 3-axis group with probe settings on the replay board
//! ([`crate::drive::link_trace::REPLAY_CAPS`]), probing moves at 1000 mm/min with a probe whose signal
//! arrives 850 µs after the touch, bounce, a glitch shorter than the filter, a trigger during a rapid
//! and one at rest without arming. The generator knows the true crossing of every touch
//! ([`ProbeTouch`]), so a test can hold the latched point against it.

use std::vec::Vec;

use axcomp_core::group::MAX_AXES;
use axcomp_scenario::ScenarioError;

use crate::drive::link_trace::write::LinkTraceBuilder;
use crate::drive::probe::write::{SETTINGS, UM_PER_COUNT, probe_group_image, table_error_um};
use crate::drive_scenario::{LINK_COMPUTE_TICKS, LINK_TICKS_PER_CYCLE};
use crate::setpoint::{MAX_SETPOINT_FRAME_LEN, PROBE_ARM, SetpointFrame};

/// Cycle-clock rate of the trace (170 MHz).
pub const PROBE_TICK_HZ: f64 = 170.0e6;
/// Cycles of the probe trace (0.6 s at 10 kHz).
pub const PROBE_CYCLES: u32 = 6_000;
/// 1000 mm/min in counts per second at 0.1 µm per count.
pub const PROBE_FEED_COUNTS_PER_S: f64 = 1000.0 / 60.0 * 1000.0 / 0.1;
/// The probe's signal latency of the trace (the settings' `latency_ns`, the truth of the model).
pub const PROBE_LATENCY_S: f64 = SETTINGS.latency_ns as f64 * 1e-9;

/// A true touch of the trace: when the stylus met the surface and where every axis was then.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ProbeTouch {
    /// The true crossing time, s.
    pub time_s: f64,
    /// The leading edge's tick (crossing + latency).
    pub edge_tick: u32,
    /// Every axis's true position at the crossing in the corrected coordinates (scale position ×
    /// 0.1 µm + the table's analytic error there), µm.
    pub true_um: [f64; 3],
    /// Every axis's true position at the leading edge (what a latch without latency compensation
    /// would report, to a count), µm.
    pub edge_um: [f64; 3],
    /// The speed of the probing axis, mm/min.
    pub feed_mm_per_min: f64,
}

/// What the probe trace contains besides its bytes.
#[derive(Clone, Debug, PartialEq)]
pub struct ProbeTraceTruth {
    /// The touches of armed probing moves, in order (each must latch once).
    pub touches: Vec<ProbeTouch>,
    /// Pulses shorter than the filter (rise tick, fall tick).
    pub glitches: Vec<(u32, u32)>,
    /// Leading edges inside a contact's lockout.
    pub bounces: usize,
    /// Triggers while not armed, axes at rest.
    pub unarmed: usize,
    /// Triggers during a rapid.
    pub during_move: usize,
}

/// Piecewise-constant velocities of one axis: the position in counts at any time, exactly (f64).
struct Motion {
    start_counts: f64,
    /// (from s, counts per second), ascending.
    legs: Vec<(f64, f64)>,
}

impl Motion {
    fn at(&self, t: f64) -> f64 {
        let mut x = self.start_counts;
        for (i, &(t0, v)) in self.legs.iter().enumerate() {
            if t <= t0 {
                break;
            }
            let t1 = self.legs.get(i + 1).map_or(f64::INFINITY, |l| l.0);
            x += v * (t.min(t1) - t0);
        }
        x
    }
}

fn ticks(t: f64) -> u32 {
    (t * PROBE_TICK_HZ).round() as u32
}

/// The probe trace (`AXLT` version 2, [`PROBE_CYCLES`] cycles) and its truth.
///
/// X (0.1 µm per count, from 2 mm): a probing move at 1000 mm/min from 20 ms, armed; a glitch of
/// 0.8 ms at 50 ms; the touch at 100.043 ms (edge 850 µs later), bounce 3 ms after the edge, the move
/// stops at 108.5 ms and is disarmed, a retract at 140 ms releases the probe with chatter; a rapid at
/// 10 m/min from 250 ms to 350 ms with a 3.5 ms trigger at 300 ms (not armed); a 6 ms trigger at rest
/// at 400 ms; a second probing move at 1000 mm/min in −X from 450 ms (armed from 440 ms), touch at
/// 500.077 ms, stop at 508 ms. Y moves at 100 mm/min during the first probing move (latency
/// compensation on a second axis); Z stands.
pub fn probe_link() -> Result<(Vec<u8>, ProbeTraceTruth), ScenarioError> {
    let feed = PROBE_FEED_COUNTS_PER_S;
    let motions = [
        Motion {
            start_counts: 20_000.0,
            legs: std::vec![
                (0.0, 0.0),
                (0.020, feed),
                (0.1085, 0.0),
                (0.140, -feed),
                (0.160, 0.0),
                (0.250, 10.0 * feed),
                (0.350, 0.0),
                (0.450, -feed),
                (0.508, 0.0),
            ],
        },
        Motion {
            start_counts: 10_000.0,
            legs: std::vec![(0.0, 0.0), (0.020, 0.1 * feed), (0.1085, 0.0)],
        },
        Motion {
            start_counts: 5_000.0,
            legs: std::vec![(0.0, 0.0)],
        },
    ];
    let armed = |t: f64| (0.015..0.1085).contains(&t) || (0.440..0.508).contains(&t);
    let raw = |t: f64| {
        let mut r = [0u32; MAX_AXES];
        for (k, m) in motions.iter().enumerate() {
            r[k] = (m.at(t).floor() as i64 as u32) & 0xFFFF;
        }
        r
    };
    let mut truth = ProbeTraceTruth {
        touches: Vec::new(),
        glitches: Vec::new(),
        bounces: 0,
        unarmed: 0,
        during_move: 0,
    };
    // Edges: (time s, level).
    let mut edges: Vec<(f64, bool)> = Vec::new();
    let mut touch = |t: f64, edges: &mut Vec<(f64, bool)>| {
        let te = t + PROBE_LATENCY_S;
        edges.push((te, true));
        let mut true_um = [0.0; 3];
        let mut edge_um = [0.0; 3];
        for (k, m) in motions.iter().enumerate() {
            let x = m.at(t);
            true_um[k] = x * UM_PER_COUNT as f64 + table_error_um(k, x);
            let xe = m.at(te);
            edge_um[k] = xe * UM_PER_COUNT as f64 + table_error_um(k, xe);
        }
        truth.touches.push(ProbeTouch {
            time_s: t,
            edge_tick: ticks(te),
            true_um,
            edge_um,
            feed_mm_per_min: 1000.0,
        });
        te
    };
    // Glitch while armed.
    edges.push((0.05003, true));
    edges.push((0.05083, false));
    // Touch 1, bounce, release with chatter.
    let te = touch(0.100_043, &mut edges);
    edges.push((te + 0.003, false));
    edges.push((te + 0.0032, true)); // bounce
    edges.push((0.14125, false)); // release (retract)
    edges.push((0.14150, true)); // chatter: bounce
    edges.push((0.14160, false));
    // A trigger during the rapid, one at rest without arming.
    edges.push((0.30006, true));
    edges.push((0.30356, false));
    edges.push((0.40011, true));
    edges.push((0.40611, false));
    // Touch 2, release.
    touch(0.500_077, &mut edges);
    edges.push((0.530, false));
    truth.glitches.push((ticks(0.05003), ticks(0.05083)));
    truth.bounces = 2;
    truth.unarmed = 1;
    truth.during_move = 1;

    let mut t = LinkTraceBuilder::new_probe();
    let image = probe_group_image(Some(&SETTINGS)).map_err(ScenarioError::Image)?;
    t.image(&image);
    let mut next_edge = 0;
    let period = LINK_TICKS_PER_CYCLE as f64 / PROBE_TICK_HZ;
    for k in 0..PROBE_CYCLES {
        let start = k * LINK_TICKS_PER_CYCLE;
        let now = k as f64 * period;
        while next_edge < edges.len() && ticks(edges[next_edge].0) <= start {
            let (te, level) = edges[next_edge];
            t.probe_edge(ticks(te), level, &raw(te));
            next_edge += 1;
        }
        let cmds: Vec<i32> = motions.iter().map(|m| m.at(now).round() as i32).collect();
        let frame = SetpointFrame::new(k as u8, &cmds)
            .expect("3 axes")
            .with_probe(if armed(now) { PROBE_ARM } else { 0 });
        let mut b = [0u8; MAX_SETPOINT_FRAME_LEN];
        let n = frame.encode_into(&mut b);
        t.link(&b[..n]);
        t.cycle(start, start + LINK_COMPUTE_TICKS, &raw(now));
    }
    Ok((t.finish(), truth))
}
