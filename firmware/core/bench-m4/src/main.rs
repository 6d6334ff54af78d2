//! Bare-metal harness counting the instructions of one `Compensator::cycle` call on a Cortex-M4F.
//!
//! Runs in QEMU (`mps2-an386`, Cortex-M4 with FPU): loads `axcomp_core::bench`'s reference image
//! (bidirectional 1024-segment table, 8 lagged sensors + expansion, 2 measured + 1 predicted
//! force) — or, built with `TABLE_ONLY=1`, the same image without the thermo-force term — applies
//! the reference process and ten temperature updates, then calls [`one_cycle`] on 64 reference
//! inputs and exits through semihosting. `count.sh` runs QEMU with one instruction per
//! translation block and counts the executed instructions whose address lies in `one_cycle`
//! (the whole call: prologue, `cycle` inlined, all outputs stored, return).
#![no_std]
#![no_main]

use axcomp_core::{Compensator, CycleInput, CycleOutput, Flags, State, bench};
use core::arch::asm;

static mut COMP: Compensator = Compensator::IDENTITY;
static mut STATE: State = State::new();
static mut IMG: [u8; 40_000] = [0; 40_000];
const N: usize = 64;

#[panic_handler]
fn panic(_: &core::panic::PanicInfo) -> ! {
    exit(1)
}

/// Semihosting SYS_EXIT_EXTENDED with ADP_Stopped_ApplicationExit.
fn exit(code: u32) -> ! {
    let block = [0x20026u32, code];
    unsafe {
        asm!("bkpt 0xAB", in("r0") 0x20u32, in("r1") &block as *const _ as u32);
    }
    loop {}
}

#[unsafe(no_mangle)]
pub extern "C" fn fault() -> ! {
    exit(2)
}

/// The measured call.
#[inline(never)]
#[unsafe(no_mangle)]
pub extern "C" fn one_cycle(
    comp: &Compensator,
    st: &mut State,
    inp: &CycleInput,
    out: &mut CycleOutput,
) {
    *out = comp.cycle(st, inp);
}

#[unsafe(no_mangle)]
pub extern "C" fn reset() -> ! {
    unsafe {
        // Enable the FPU (CPACR: CP10/CP11 full access).
        let cpacr = 0xE000_ED88 as *mut u32;
        cpacr.write_volatile(cpacr.read_volatile() | (0xF << 20));
        asm!("dsb", "isb");
        let comp = &mut *core::ptr::addr_of_mut!(COMP);
        let st = &mut *core::ptr::addr_of_mut!(STATE);
        let img = &mut *core::ptr::addr_of_mut!(IMG);
        let mut spec = bench::reference_spec();
        if option_env!("TABLE_ONLY").is_some() {
            spec.thermo = None;
        }
        let Ok(n) = axcomp_core::write_image(&spec, img) else {
            exit(3)
        };
        if comp.load(&img[..n]).is_err() {
            exit(4);
        }
        comp.set_process(st, &bench::PROCESS);
        for i in 0..10 {
            comp.update_temperatures(st, i * 100, &bench::reference_temperatures(i));
        }
        let mut out = CycleOutput {
            position_counts: 0,
            corrected_command_counts: 0,
            correction_counts: 0,
            correction_um: 0.0,
            flags: Flags::NONE,
        };
        let mut acc = 0i64;
        for i in 0..N as u32 {
            let inp = bench::reference_input(i * 97);
            one_cycle(comp, st, core::hint::black_box(&inp), &mut out);
            acc = acc.wrapping_add(core::hint::black_box(&out).corrected_command_counts);
        }
        core::hint::black_box(acc);
        exit(0)
    }
}
