//! QEMU netduinoplus2 firmware: replays an axis-group trace (records `GroupCycle`,
//! `AxisTemperatures`, `GroupReset`, `Process`, `Image`) through a `GroupEngine`, driven directly
//! by `axcomp_firmware::replay::replay_group` (the single-axis control loop stays in `axcomp-qemu`).
//! A separate program because the group engine and the single-axis engine do not both fit the
//! 128 KiB of RAM beside the replay buffers.
//!
//! Run: `qemu-system-arm -machine netduinoplus2 -nographic -icount shift=0 \
//!   -semihosting-config enable=on,target=native,arg=axcomp-qemu-group,arg=TRACE,arg=OUT -kernel axcomp-qemu-group`
//!
//! A drive trace (`axcomp_firmware::drive::link_trace`, magic `AXLT`) is replayed instead through the
//! group drive (`GroupDrive`: setpoint link, supervisors, status word, reply frame), one 128-byte drive
//! output record per cycle; a probe trace (`AXLT` version 2) also a 128-byte probe output record after
//! each (`ProbeOutputRecord`: probe flags, latch, counters, the whole reply frame).
//!
//! Exit status: 0 when every record replayed cleanly, 1 on a panic, 2 when the files cannot be
//! opened or written, 3 when the trace had malformed records (the readable ones are still
//! replayed and written).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use axcomp_core::group::GroupEngine;
    use axcomp_core::trace::OUTPUT_RECORD_LEN;
    use axcomp_firmware::board::semihosting::{self, HostError, HostFile, OutBlock};
    use axcomp_firmware::drive::link_trace::{self, LinkStream, ProbeOutputRecord};
    use axcomp_firmware::replay::{self, TraceStream};
    use cortex_m_rt::entry;
    use cortex_m_semihosting::hprintln;
    use static_cell::ConstStaticCell;

    /// Coefficient pool of the group (segments): the `group3`/`group5` scenarios need 512.
    const POOL: usize = 1024;
    /// Replay window: the largest record is a five-axis group image (about 12 KiB).
    const TRACE_BUF_LEN: usize = 24 * 1024;
    const OUT_BLOCK_RECORDS: usize = 64;

    static ENGINE: ConstStaticCell<GroupEngine<POOL>> = ConstStaticCell::new(GroupEngine::new());
    static TRACE_BUF: ConstStaticCell<[u8; TRACE_BUF_LEN]> =
        ConstStaticCell::new([0; TRACE_BUF_LEN]);
    static OUT_BUF: ConstStaticCell<[u8; OUT_BLOCK_RECORDS * OUTPUT_RECORD_LEN]> =
        ConstStaticCell::new([0; OUT_BLOCK_RECORDS * OUTPUT_RECORD_LEN]);

    fn fail(what: &str, path: &str, e: HostError) -> ! {
        hprintln!(
            "axcomp-qemu-group: {} {}: {} (errno {})",
            what,
            path,
            e.op,
            e.errno
        );
        semihosting::exit_code(2)
    }

    #[entry]
    fn main() -> ! {
        let mut cmd_buf = [0u8; 256];
        let (trace_path, out_path) = semihosting::trace_and_output_paths(&mut cmd_buf);

        let mut head = [0u8; 4];
        let mut input =
            HostFile::open_read(trace_path).unwrap_or_else(|e| fail("cannot open", trace_path, e));
        let got = input.read_full(&mut head).unwrap_or(0);
        drop(input);
        let input =
            HostFile::open_read(trace_path).unwrap_or_else(|e| fail("cannot open", trace_path, e));
        let output =
            HostFile::create(out_path).unwrap_or_else(|e| fail("cannot create", out_path, e));
        if link_trace::is_link_trace(&head[..got]) {
            replay_drive_trace(input, output, trace_path, out_path)
        }
        let mut stream = match TraceStream::new(input, TRACE_BUF.take()) {
            Ok(s) => s,
            Err(e) => {
                hprintln!("axcomp-qemu-group: {}: {}", trace_path, e);
                semihosting::exit_code(2)
            }
        };
        let engine = ENGINE.take();
        let mut out = OutBlock::new(output, OUT_BUF.take());
        let sum = replay::replay_group(
            engine,
            &mut stream,
            |o| out.push(&o.encode()),
            |e| hprintln!("axcomp-qemu-group: {}: {}", trace_path, e),
        );
        if let Err((what, e)) = out.finish() {
            fail(what, out_path, e)
        }
        let s = engine.stats();
        hprintln!(
            "axcomp-qemu-group: records={} cycles={} outputs={} errors={} images_accepted={} images_rejected={}",
            sum.records,
            sum.cycles,
            sum.outputs,
            sum.errors,
            s.images_accepted,
            s.images_rejected
        );
        if sum.errors > 0 {
            semihosting::exit_code(3)
        }
        semihosting::exit_success()
    }

    /// A drive trace (`axcomp_firmware::drive::link_trace`): setpoint-link bytes, scale counters and
    /// cycle times through the group drive; one 128-byte drive output record per cycle.
    fn replay_drive_trace(
        input: HostFile,
        output: HostFile,
        trace_path: &str,
        out_path: &str,
    ) -> ! {
        let mut stream = match LinkStream::new(input, TRACE_BUF.take()) {
            Ok(s) => s,
            Err(e) => {
                hprintln!("axcomp-qemu-group: {}: {}", trace_path, e);
                semihosting::exit_code(2)
            }
        };
        let engine = ENGINE.take();
        let mut drive = link_trace::replay_drive();
        let mut out = OutBlock::new(output, OUT_BUF.take());
        let probe = stream.is_probe_trace();
        let sum = link_trace::replay_link(
            &mut drive,
            engine,
            &mut stream,
            |o| {
                out.push(&o.encode());
                if probe {
                    out.push(&ProbeOutputRecord::encode(o));
                }
            },
            |e| hprintln!("axcomp-qemu-group: {}: {}", trace_path, e),
        );
        if let Err((what, e)) = out.finish() {
            fail(what, out_path, e)
        }
        hprintln!(
            "axcomp-qemu-group: drive trace records={} cycles={} images_refused={} errors={}",
            sum.records,
            sum.cycles,
            sum.images_refused,
            sum.errors
        );
        if sum.errors > 0 {
            semihosting::exit_code(3)
        }
        semihosting::exit_success()
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        semihosting::report_panic("axcomp-qemu-group", info)
    }
}

/// Host builds (e.g. `cargo build --all-features`) get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!(
        "axcomp-qemu-group is firmware: build it with `cargo qemu-build` (thumbv7em-none-eabihf)"
    );
    std::process::exit(2);
}
