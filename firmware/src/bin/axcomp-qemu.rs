//! QEMU netduinoplus2 firmware: replays a trace file through the control loop (see `board::qemu`).
//!
//! Run: `qemu-system-arm -machine netduinoplus2 -nographic -icount shift=0 \
//!   -semihosting-config enable=on,target=native,arg=axcomp-qemu,arg=TRACE,arg=OUT -kernel axcomp-qemu`
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod firmware {
    use axcomp_core::Engine;
    use axcomp_core::trace::OUTPUT_RECORD_LEN;
    use axcomp_firmware::board::qemu::{self, OUT_BLOCK_RECORDS, TRACE_BUF_LEN};
    use axcomp_firmware::board::semihosting;
    use embassy_executor::Spawner;
    use static_cell::ConstStaticCell;

    /// The engine (two compensator slots with their tables) is built by the const constructor into `.bss`.
    static ENGINE: ConstStaticCell<Engine> = ConstStaticCell::new(Engine::new());
    static TRACE_BUF: ConstStaticCell<[u8; TRACE_BUF_LEN]> =
        ConstStaticCell::new([0; TRACE_BUF_LEN]);
    static OUT_BUF: ConstStaticCell<[u8; OUT_BLOCK_RECORDS * OUTPUT_RECORD_LEN]> =
        ConstStaticCell::new([0; OUT_BLOCK_RECORDS * OUTPUT_RECORD_LEN]);

    #[embassy_executor::main]
    async fn main(_spawner: Spawner) {
        let core = cortex_m::Peripherals::take().expect("core peripherals taken once");
        qemu::run(core.SYST, ENGINE.take(), TRACE_BUF.take(), OUT_BUF.take())
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo) -> ! {
        semihosting::report_panic("axcomp-qemu", info)
    }
}

/// Host builds (e.g. `cargo build --all-features`) get a stub: this program only runs on the target.
#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("axcomp-qemu is firmware: build it with `cargo qemu-build` (thumbv7em-none-eabihf)");
    std::process::exit(2);
}
