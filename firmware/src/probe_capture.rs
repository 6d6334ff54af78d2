//! The chip-independent half of the STM32G474's touch-probe input capture
//! (`board::stm32g474::CaptureProbe`): what the capture interrupt read from the encoder timers becomes
//! a [`CapturedEdge`] in a queue the drive empties once per cycle ([`crate::drive::probe::ProbeIo`]).
//! Pure bookkeeping, so it is unit-tested on the host; the register reads are the board's.
//!
//! - **Reading** ([`CaptureReading`]): one capture interrupt. Per scale input, the capture channel's
//!   flag (CCxIF: the timer latched its counter at a probe edge), its overcapture flag (CCxOF: a
//!   second edge was latched before the first was read), the capture register (CCRx: the 16-bit
//!   counter at the edge) and the counter now (CNT); the cycle clock at the interrupt's entry; then,
//!   after a settling delay longer than the capture path's, the probe pin's level and the
//!   interrupting channel's flags again (a newer edge pending; an overcapture that raced the reads).
//! - **Edge direction**: the channels capture both edges, which the capture itself does not tell
//!   apart; each edge toggles the level after the previous one (the level read at start-up).
//! - **Lost edges**: an overcapture on any channel (before or during the reads) means edges came
//!   faster than the interrupt read them: the reading is not queued as an edge, the queue reports
//!   edges lost (the core drops a pending leading edge and never latches it,
//!   `ProbeEvent::EdgesLost`) and resynchronises its level to the pin's. So does a settled pin level
//!   that differs from the queued edge's with no newer capture pending (an edge escaped the
//!   capture), after queuing the edge. A full queue also loses the edge.
//! - **A channel that missed the edge** (only possible for a pulse at the timers' input-filter
//!   boundary, tens of ns: such a pulse is a glitch for the core's filter): its counter now (CNT,
//!   read in the interrupt, about a microsecond after the edge) stands in for the capture.
//! - **No capture at all** (a spurious interrupt): nothing is queued.

use axcomp_core::group::MAX_AXES;
use axcomp_core::probe::MAX_EDGES_PER_CYCLE;

use crate::drive::probe::CapturedEdge;

/// Scale inputs with a capture channel on the probe signal (the board's encoder timers).
pub const CAPTURE_INPUTS: usize = 3;

/// What one capture interrupt read (see the module doc).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CaptureReading {
    /// Cycle-clock ticks at the interrupt's entry (the edge's time stamp).
    pub time: u32,
    /// Per scale input: the capture flag (CCxIF) was set.
    pub captured: [bool; CAPTURE_INPUTS],
    /// Per scale input: the overcapture flag (CCxOF) was set.
    pub overcaptured: [bool; CAPTURE_INPUTS],
    /// Per scale input: the capture register (the counter at the edge; meaningful when captured).
    pub ccr: [u16; CAPTURE_INPUTS],
    /// Per scale input: the counter when the interrupt read it.
    pub cnt: [u16; CAPTURE_INPUTS],
    /// The probe pin's level, read after the captures and a settling delay longer than the capture
    /// path's (input filter and synchroniser), so an edge the pin shows has been captured by then.
    pub level_after: bool,
    /// Read after `level_after`: a newer edge has been captured (the interrupting channel's flag is
    /// set again, so the interrupt runs again for it).
    pub next_pending: bool,
    /// Read after `level_after`: the interrupting channel overcaptured while this reading was taken
    /// (an edge between its status and capture reads): edges were lost.
    pub raced: bool,
}

/// What a reading did to the queue.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum CaptureOutcome {
    /// No channel had captured: nothing queued.
    NoEdge,
    /// An edge was queued.
    Queued,
    /// Edges were lost (overcapture or a full queue).
    Lost,
}

/// A queued edge, compact (12 bytes: the queue lives in the board's static RAM).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
struct QueuedEdge {
    time: u32,
    counts: [u16; CAPTURE_INPUTS],
    level: bool,
}

/// Edges between the capture interrupt and the drive's cycle.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CaptureQueue {
    edges: [QueuedEdge; MAX_EDGES_PER_CYCLE],
    len: u8,
    lost: bool,
    /// The level after the last edge queued (or the resynchronised pin level after a loss).
    level: bool,
    /// The level after the last edge handed to the drive.
    level_out: bool,
}

impl CaptureQueue {
    /// An empty queue; `level` = the probe pin's level at start-up.
    pub const fn new(level: bool) -> Self {
        CaptureQueue {
            edges: [QueuedEdge {
                time: 0,
                counts: [0; CAPTURE_INPUTS],
                level: false,
            }; MAX_EDGES_PER_CYCLE],
            len: 0,
            lost: false,
            level,
            level_out: level,
        }
    }

    /// One capture interrupt's reading (see the module doc).
    pub fn on_capture(&mut self, r: &CaptureReading) -> CaptureOutcome {
        if !r.captured.iter().any(|&c| c) {
            return CaptureOutcome::NoEdge;
        }
        if r.raced || r.overcaptured.iter().any(|&o| o) {
            return self.lose(r.level_after);
        }
        let level = !self.level;
        self.level = level;
        let Some(slot) = self.edges.get_mut(usize::from(self.len)) else {
            self.lost = true;
            return CaptureOutcome::Lost;
        };
        let mut counts = [0u16; CAPTURE_INPUTS];
        for (i, c) in counts.iter_mut().enumerate() {
            *c = if r.captured[i] { r.ccr[i] } else { r.cnt[i] };
        }
        *slot = QueuedEdge {
            time: r.time,
            counts,
            level,
        };
        self.len += 1;
        if !r.next_pending && r.level_after != level {
            // The pin moved on without a capture that explains it: an edge escaped the capture.
            return self.lose(r.level_after);
        }
        CaptureOutcome::Queued
    }

    /// Edges were lost: report it, take the pin's level.
    fn lose(&mut self, pin_level: bool) -> CaptureOutcome {
        self.lost = true;
        self.level = pin_level;
        CaptureOutcome::Lost
    }

    /// Moves the queued edges (oldest first) into `out` as the drive takes them: the 16-bit captures
    /// as raw counter values of scale inputs 0..[`CAPTURE_INPUTS`] (the drive extends them against each
    /// axis's counter like a polled read); returns how many and whether edges were lost since the
    /// last call.
    pub fn take(&mut self, out: &mut [CapturedEdge; MAX_EDGES_PER_CYCLE]) -> (usize, bool) {
        let n = usize::from(self.len).min(MAX_EDGES_PER_CYCLE);
        for (o, e) in out.iter_mut().zip(&self.edges[..n]) {
            let mut scale_raw = [0u32; MAX_AXES];
            for (s, &c) in scale_raw.iter_mut().zip(&e.counts) {
                *s = u32::from(c);
            }
            *o = CapturedEdge {
                time: e.time,
                level: e.level,
                scale_raw,
            };
        }
        self.len = 0;
        self.level_out = self.level;
        (n, core::mem::take(&mut self.lost))
    }

    /// The level after the last edge handed to the drive (edges still queued have not happened for
    /// it), or the pin's after a loss. (Not the field `level`, the level after the last queued edge.)
    #[allow(clippy::misnamed_getters)]
    pub fn level(&self) -> bool {
        self.level_out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A clean edge to `level` (the pin still there when read, nothing newer pending).
    fn edge_reading(time: u32, ccr: [u16; 3], level: bool) -> CaptureReading {
        CaptureReading {
            time,
            captured: [true; 3],
            overcaptured: [false; 3],
            ccr,
            // The counters moved on after the edge: never what is queued when the channel captured.
            cnt: ccr.map(|c| c.wrapping_add(7)),
            level_after: level,
            next_pending: false,
            raced: false,
        }
    }

    #[test]
    fn captures_become_alternating_edges_with_the_captured_counters() {
        let mut q = CaptureQueue::new(false);
        // The pin already fell again when the interrupt read it, and that edge is pending: the
        // direction comes from the alternation, not from the pin.
        let mut r = edge_reading(1000, [10, 65535, 3], false);
        r.next_pending = true;
        assert_eq!(q.on_capture(&r), CaptureOutcome::Queued);
        assert_eq!(
            q.on_capture(&edge_reading(1200, [12, 0, 4], false)),
            CaptureOutcome::Queued
        );
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        assert_eq!(q.take(&mut out), (2, false));
        assert_eq!(
            out[0],
            CapturedEdge {
                time: 1000,
                level: true,
                scale_raw: [10, 65535, 3, 0, 0],
            }
        );
        assert_eq!(
            out[1],
            CapturedEdge {
                time: 1200,
                level: false,
                scale_raw: [12, 0, 4, 0, 0],
            }
        );
        assert!(!q.level());
        assert_eq!(q.take(&mut out), (0, false));
    }

    #[test]
    fn the_level_follows_only_the_edges_handed_out() {
        let mut q = CaptureQueue::new(false);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        q.on_capture(&edge_reading(5, [1, 2, 3], true));
        assert!(!q.level(), "a queued edge has not happened for the drive");
        assert_eq!(q.take(&mut out).0, 1);
        assert!(q.level());
    }

    #[test]
    fn a_channel_that_missed_the_edge_reports_its_counter_now() {
        let mut q = CaptureQueue::new(false);
        let mut r = edge_reading(7, [100, 200, 300], true);
        r.captured[1] = false;
        assert_eq!(q.on_capture(&r), CaptureOutcome::Queued);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        q.take(&mut out);
        assert_eq!(out[0].scale_raw[..3], [100, 207, 300]);
    }

    #[test]
    fn no_capture_queues_nothing() {
        let mut q = CaptureQueue::new(true);
        let mut r = edge_reading(7, [1, 2, 3], false);
        r.captured = [false; 3];
        assert_eq!(q.on_capture(&r), CaptureOutcome::NoEdge);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        assert_eq!(q.take(&mut out), (0, false));
        assert!(q.level());
    }

    #[test]
    fn an_overcapture_loses_the_edges_and_resynchronises_to_the_pin() {
        let mut q = CaptureQueue::new(false);
        q.on_capture(&edge_reading(1, [1, 1, 1], true));
        let mut r = edge_reading(2, [2, 2, 2], true);
        r.overcaptured[2] = true;
        assert_eq!(q.on_capture(&r), CaptureOutcome::Lost);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        // The edge before the loss is still handed out, then the loss; the level is the pin's.
        assert_eq!(q.take(&mut out), (1, true));
        assert!(out[0].level);
        assert!(q.level());
        // The next edge toggles from the resynchronised level.
        q.on_capture(&edge_reading(3, [3, 3, 3], false));
        q.take(&mut out);
        assert!(!out[0].level);
        assert_eq!(q.take(&mut out), (0, false), "the loss is reported once");
    }

    #[test]
    fn a_full_queue_loses_the_edge_but_keeps_the_direction() {
        let mut q = CaptureQueue::new(false);
        for t in 0..MAX_EDGES_PER_CYCLE as u32 {
            assert_eq!(
                q.on_capture(&edge_reading(t, [0; 3], t % 2 == 0)),
                CaptureOutcome::Queued
            );
        }
        assert_eq!(
            q.on_capture(&edge_reading(99, [0; 3], true)),
            CaptureOutcome::Lost
        );
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        assert_eq!(q.take(&mut out), (MAX_EDGES_PER_CYCLE, true));
        // 9 edges from low: high after the last one.
        assert!(q.level());
    }

    #[test]
    fn an_edge_between_the_status_and_capture_reads_is_lost_never_merged() {
        // A glitch: its rising edge is read, its falling edge is captured between the status read
        // and the capture read (the capture register then holds the falling edge's counter and the
        // overcapture flag is set): losing it keeps the core from filtering a rising edge that never
        // stayed high.
        let mut q = CaptureQueue::new(false);
        let mut r = edge_reading(10, [5, 5, 5], false);
        r.raced = true;
        assert_eq!(q.on_capture(&r), CaptureOutcome::Lost);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        assert_eq!(q.take(&mut out), (0, true));
        assert!(!q.level());
    }

    #[test]
    fn a_pin_that_moved_without_a_pending_capture_loses_edges() {
        // The rising edge is captured; by the settled pin read the pin is low again but no capture
        // is pending: the falling edge escaped the capture.
        let mut q = CaptureQueue::new(false);
        let mut r = edge_reading(10, [5, 6, 7], true);
        r.level_after = false;
        assert_eq!(q.on_capture(&r), CaptureOutcome::Lost);
        let mut out = [CapturedEdge::default(); MAX_EDGES_PER_CYCLE];
        // The rising edge is handed out, then the loss: the core drops it (never latches it).
        assert_eq!(q.take(&mut out), (1, true));
        assert!(out[0].level);
        assert!(!q.level());
    }
}
