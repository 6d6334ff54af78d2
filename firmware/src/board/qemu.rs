//! QEMU `netduinoplus2` (STM32F405, Cortex-M4F) board: replays a host trace file through the control loop.
//!
//! Glossary:
//! - **Trace file / output file**: host files opened over semihosting; names from the semihosting command
//!   line (`-semihosting-config enable=on,target=native,arg=axcomp-qemu,arg=TRACE,arg=OUT`), defaulting to
//!   `axcomp-trace.bin` and `axcomp-out.bin` in QEMU's working directory.
//! - **SysTick clock**: the 24-bit SysTick down-counter on the core clock; under `-icount shift=0` it advances
//!   deterministically with executed instructions, so compute times are repeatable.
//!
//! Exit status: 0 when every record replayed cleanly, 1 on a panic, 2 when the files cannot be opened or
//! written, 3 when the trace had malformed records (all readable records are still replayed and written).

use cortex_m::peripheral::{SYST, syst::SystClkSource};
use cortex_m_semihosting::hprintln;

use axcomp_core::Engine;
use axcomp_core::trace::OUTPUT_RECORD_LEN;

use super::semihosting::{self, HostError, HostFile, OutBlock};
use crate::control::{ControlLoop, CycleClock, LoopSettings};
use crate::replay::{self, ByteSource, TraceStream};

/// Replay buffer: holds the largest record, a full bidirectional 1024-segment image with an 8-sensor
/// thermo-force term (about 33 KiB) plus its record header.
pub const TRACE_BUF_LEN: usize = 36 * 1024;
/// Output records are written to the host in blocks of this many.
pub const OUT_BLOCK_RECORDS: usize = 64;
/// netduinoplus2 core clock in QEMU (SysTick with CLKSOURCE = core).
pub const CORE_CLOCK_HZ: u32 = 168_000_000;

/// Device interrupts of the STM32F405 (netduinoplus2): the QEMU firmware enables none of them.
pub const INTERRUPT_COUNT: usize = 82;

/// The vector table's device part (cortex-m-rt feature `device`): every interrupt goes to
/// cortex-m-rt's `DefaultHandler`. cortex-m-rt's generic table without `device` has 240 entries.
#[used]
#[unsafe(link_section = ".vector_table.interrupts")]
#[unsafe(no_mangle)]
pub static __INTERRUPTS: [unsafe extern "C" fn(); INTERRUPT_COUNT] =
    [DefaultHandler; INTERRUPT_COUNT];

unsafe extern "C" {
    fn DefaultHandler();
}

/// SysTick as a free-running down counter.
pub struct SysTickClock;

impl SysTickClock {
    pub fn start(mut syst: SYST) -> Self {
        syst.set_clock_source(SystClkSource::Core);
        syst.set_reload(0x00FF_FFFF);
        syst.clear_current();
        syst.enable_counter();
        SysTickClock
    }
}

impl CycleClock for SysTickClock {
    fn now(&self) -> u32 {
        SYST::get_current()
    }
    fn elapsed_since(&self, earlier: u32) -> u32 {
        earlier.wrapping_sub(Self::now(self)) & 0x00FF_FFFF
    }
}

impl ByteSource for HostFile {
    type Error = HostError;
    fn read(&mut self, buf: &mut [u8]) -> Result<usize, HostError> {
        HostFile::read(self, buf)
    }
}

/// Runs the whole replay and exits QEMU with the status described in the module docs.
pub fn run(
    syst: SYST,
    engine: &'static mut Engine,
    trace_buf: &'static mut [u8; TRACE_BUF_LEN],
    out_buf: &'static mut [u8; OUT_BLOCK_RECORDS * OUTPUT_RECORD_LEN],
) -> ! {
    let mut cmd_buf = [0u8; 256];
    let (trace_path, out_path) = semihosting::trace_and_output_paths(&mut cmd_buf);

    let input = match HostFile::open_read(trace_path) {
        Ok(f) => f,
        Err(e) => {
            hprintln!(
                "axcomp-qemu: cannot open trace {}: {} (errno {})",
                trace_path,
                e.op,
                e.errno
            );
            semihosting::exit_code(2)
        }
    };
    let output = match HostFile::create(out_path) {
        Ok(f) => f,
        Err(e) => {
            hprintln!(
                "axcomp-qemu: cannot create {}: {} (errno {})",
                out_path,
                e.op,
                e.errno
            );
            semihosting::exit_code(2)
        }
    };
    let mut stream = match TraceStream::new(input, trace_buf) {
        Ok(s) => s,
        Err(e) => {
            hprintln!("axcomp-qemu: {}: {}", trace_path, e);
            semihosting::exit_code(2)
        }
    };

    let clock = SysTickClock::start(syst);
    let cfg = match LoopSettings::new(CORE_CLOCK_HZ).build() {
        Ok(c) => c,
        Err(e) => panic!("loop settings: {}", e),
    };
    let mut ctl = ControlLoop::new(engine, cfg);
    let mut out = OutBlock::new(output, out_buf);
    let sum = replay::replay(
        &mut ctl,
        &mut stream,
        &clock,
        |o| out.push(&o.encode()),
        |e| hprintln!("axcomp-qemu: {}: {}", trace_path, e),
    );
    if let Err((what, e)) = out.finish() {
        hprintln!(
            "axcomp-qemu: {} {} failed: {} (errno {})",
            what,
            out_path,
            e.op,
            e.errno
        );
        semihosting::exit_code(2)
    }
    let st = ctl.stats();
    let es = ctl.engine().stats();
    hprintln!(
        "axcomp-qemu: records={} cycles={} outputs={} errors={} images_accepted={} images_rejected={} \
         compute_ticks_max={} compute_ticks_mean={} overruns={}",
        sum.records,
        sum.cycles,
        sum.outputs,
        sum.errors,
        es.images_accepted,
        es.images_rejected,
        st.max_compute_ticks,
        st.mean_compute_ticks(),
        st.overruns
    );
    if sum.errors > 0 {
        semihosting::exit_code(3)
    }
    semihosting::exit_success()
}
