//! STM32G474RE board support (NUCLEO-G474RE wiring). The only module that names this chip.
//!
//! Glossary:
//! - **Scale inputs**: three timers in encoder mode counting A/B quadrature signals, 16-bit counters, so
//!   images for this board use `counter_bits = 16` ([`CAPS`] refuses others). Input 0: TIM4 (PB6 = A,
//!   PB7 = B); input 1: TIM3 (PB4 = A, PB5 = B; Arduino D5/D4); input 2: TIM8 (PC6 = A, PC7 = B; CN10,
//!   Arduino D9 = PC7). TIM2 is embassy's time driver; TIM1's encoder pins collide with USART1 (PA9).
//! - **RTD bus**: SPI1 (PA5 SCK, PA6 MISO, PA7 MOSI, mode 1, 1 MHz) shared by the MAX31865 converters, chip
//!   selects PB0, PB1 (sensor 0, 1).
//! - **Setpoint link**: USART1 (PA9 TX, PA10 RX, [`LINK_BAUD`] 8N1) carrying [`crate::setpoint`] frames:
//!   the group's commands in, one reply frame (corrected command + status word) out per cycle.
//! - **Cycle clock**: DWT CYCCNT at the core clock (170 MHz).
//! - **Watchdog**: the IWDG (LSI ≈ 32 kHz), [`WATCHDOG_TIMEOUT_US`]; the reset flags in RCC_CSR tell the
//!   next boot whether it fired ([`take_reset_cause`]).
//! - **Loop priority**: the control loop runs on an interrupt-mode executor (pended through the unused
//!   UART4 interrupt at [`LOOP_PRIORITY`]); the RTD task's blocking SPI reads stay in thread mode, so the
//!   loop preempts them.
//! - **Image slots**: the two 128 KiB flash regions `__slot_a_start` / `__slot_b_start` from `memory.x`.
//! - **Touch probe** ([`BoardProbe`]): deflected = high (pull-down; an SSR/open-collector probe
//!   interface switches 3.3 V). With [`PROBE_INPUT_CAPTURE`] (the default) the probe signal is wired to
//!   three pins, one capture channel beside each encoder: **PB8 = TIM4_CH3** (AF2), **PC8 = TIM3_CH3**
//!   (AF2), **PC9 = TIM8_CH4** (AF4) — the pin alternates are checked at compile time by embassy's
//!   `TimerPin` traits (ST's data). Each channel captures its timer's counter on both edges in
//!   hardware (CCR3 / CCR3 / CCR4); TIM3's capture interrupt ([`PROBE_CAPTURE_PRIORITY`], above the
//!   loop) reads the three captures, stamps the DWT time at its entry and queues the edge
//!   ([`crate::probe_capture`], host-tested); the drive takes the queue once per cycle. PB8 is also
//!   the BOOT0 pin: a probe deflected at reset would start the ROM bootloader unless the option bytes
//!   ignore the pin (nSWBOOT0 = 0, nBOOT0 = 1; `STM32_Programmer_CLI -c port=SWD -ob nSWBOOT0=0
//!   nBOOT0=1`). Without the fan-out, set [`PROBE_INPUT_CAPTURE`] to false: PC8 alone is then *polled*
//!   once per cycle and an edge takes that cycle's counters and time (up to one cycle late, 100 µs:
//!   1.7 µm at 1000 mm/min).
use core::cell::RefCell;

use embassy_embedded_hal::shared_bus::blocking::spi::SpiDevice;
use embassy_stm32::gpio::{AnyPin, Input, Level, Output, Pull, Speed};
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer;
use embassy_stm32::timer::input_capture::CapturePin;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::usart::{self, BufferedUart, BufferedUartRx, BufferedUartTx};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{Peri, bind_interrupts, peripherals};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::{CriticalSectionRawMutex, NoopRawMutex};
use static_cell::{ConstStaticCell, StaticCell};

use crate::control::CycleClock;
use crate::drive::probe::{CapturedEdge, ProbeIo};
use crate::drive::{DriveIo, ResetCause, Watchdog};
use crate::max31865::{Max31865, SettingsBuilder};
use crate::probe_capture::{CaptureQueue, CaptureReading};

/// Core clock after [`config`]: HSI16 → PLL → 170 MHz.
pub const CORE_CLOCK_HZ: u32 = 170_000_000;
// What the board has (RTDs, scale inputs, axis ids, caps, named sensor inputs, pool): in the portable
// `crate::board_caps`, so that the host checks images against the same values with the same code.
pub use crate::board_caps::stm32g474::{
    AXIS_IDS, CAPS, POOL, RTD_COUNT, SCALE_INPUTS, SENSOR_INPUTS,
};
/// Setpoint link rate (see the link budget in [`crate::setpoint`]).
pub const LINK_BAUD: u32 = 2_000_000;
/// Watchdog timeout: 100 cycles at 10 kHz.
pub const WATCHDOG_TIMEOUT_US: u32 = 10_000;
/// NVIC priority of the loop's executor interrupt: above thread mode (the RTD task), below the
/// peripherals' interrupts (USART1, the TIM2 time driver: priority 0), so received bytes are never lost
/// to a long cycle.
pub const LOOP_PRIORITY: embassy_stm32::interrupt::Priority =
    embassy_stm32::interrupt::Priority::P6;

bind_interrupts!(struct Irqs {
    USART1 => usart::BufferedInterruptHandler<peripherals::USART1>;
});

/// Clock tree: 170 MHz system clock from HSI16 via the PLL (boost mode is set by embassy-stm32).
pub fn config() -> embassy_stm32::Config {
    use embassy_stm32::rcc::*;
    let mut c = embassy_stm32::Config::default();
    c.rcc.hsi = true;
    c.rcc.pll = Some(Pll {
        source: PllSource::HSI,
        prediv: PllPreDiv::DIV4,
        mul: PllMul::MUL85,
        divp: None,
        divq: None,
        divr: Some(PllRDiv::DIV2),
    });
    c.rcc.sys = Sysclk::PLL1_R;
    c
}

/// The scale inputs and the setpoint link.
pub struct BoardIo {
    qei0: Qei<'static, peripherals::TIM4>,
    qei1: Qei<'static, peripherals::TIM3>,
    qei2: Qei<'static, peripherals::TIM8>,
    rx: BufferedUartRx<'static>,
    tx: BufferedUartTx<'static>,
}

impl DriveIo for BoardIo {
    fn read_scale(&mut self, input: usize) -> u32 {
        u32::from(match input {
            0 => self.qei0.count(),
            1 => self.qei1.count(),
            _ => self.qei2.count(),
        })
    }

    fn read_link(&mut self, buf: &mut [u8]) -> usize {
        use embedded_io::Read;
        use embedded_io_async::ReadReady;
        // Only what has arrived: `read` blocks on an empty buffer, so ask first.
        if !matches!(self.rx.read_ready(), Ok(true)) {
            return 0;
        }
        self.rx.read(buf).unwrap_or(0)
    }

    /// The received bytes where they lie in the driver's receive ring (its `fill_buf`, polled once:
    /// only what has arrived), then dropped from it (`consume`): no copy. At the ring's end the
    /// bytes before the wrap come first, the rest on the next call.
    fn take_link(&mut self, max: usize, take: impl FnOnce(&[u8])) -> usize {
        use core::future::Future;
        use core::task::{Context, Poll, Waker};
        use embedded_io_async::{BufRead, ReadReady};
        // `fill_buf` pends on an empty ring (it would register the waker), so ask first.
        if !matches!(self.rx.read_ready(), Ok(true)) {
            return 0;
        }
        let n = {
            let mut fut = core::pin::pin!(self.rx.fill_buf());
            match fut.as_mut().poll(&mut Context::from_waker(Waker::noop())) {
                Poll::Ready(Ok(bytes)) => {
                    let n = bytes.len().min(max);
                    if n > 0 {
                        take(&bytes[..n]);
                    }
                    n
                }
                _ => 0,
            }
        };
        if n > 0 {
            self.rx.consume(n);
        }
        n
    }

    fn write_link(&mut self, frame: &[u8]) -> bool {
        use core::future::Future;
        use core::task::{Context, Poll, Waker};
        // The async write queues the whole frame, or pends (without writing) when the ring lacks room:
        // polled once, it is "queue or drop". The blocking `embedded_io::Write` would instead spin until
        // the line has sent enough, and a cycle must never wait for the line.
        let mut fut = core::pin::pin!(embedded_io_async::Write::write(&mut self.tx, frame));
        matches!(
            fut.as_mut().poll(&mut Context::from_waker(Waker::noop())),
            Poll::Ready(Ok(n)) if n == frame.len()
        )
    }
}

/// True: the probe edges are captured by the encoder timers in hardware (PB8, PC8, PC9 wired together:
/// see the module doc); false: PC8 alone is polled once per cycle (the fallback for a board without
/// the fan-out).
pub const PROBE_INPUT_CAPTURE: bool = true;
/// NVIC priority of the probe capture interrupt (TIM3): above the loop's executor ([`LOOP_PRIORITY`]),
/// below USART1 and the time driver (P0). Its latency delays only the edge's time stamp (used by the
/// filter and the lockout, in µs-to-ms terms), never the captured counters.
pub const PROBE_CAPTURE_PRIORITY: embassy_stm32::interrupt::Priority =
    embassy_stm32::interrupt::Priority::P1;

/// The edges between the capture interrupt and the drive (see [`crate::probe_capture`]).
static CAPTURE_QUEUE: Mutex<CriticalSectionRawMutex, RefCell<CaptureQueue>> =
    Mutex::new(RefCell::new(CaptureQueue::new(false)));

/// Capture channel (0-based index: CH3 = 2, CH4 = 3) of each encoder timer wired to the probe.
const TIM4_PROBE_CH: usize = 2;
const TIM3_PROBE_CH: usize = 2;
const TIM8_PROBE_CH: usize = 3;
/// Core cycles the capture interrupt waits for the capture path to settle (~190 ns at 170 MHz, over
/// twice the input filter's and synchroniser's ~70 ns).
const CAPTURE_SETTLE_CYCLES: u32 = 32;
/// The defined flag bits of TIMx_SR (RM0440): writing them as 1 leaves them (rc_w0), so a write with
/// only one of them 0 clears that flag without racing the others.
const SR_FLAGS: u32 = 0x00F3_3FFF;

/// One timer's capture channel in the capture interrupt: (captured, overcaptured, CCR, CNT). The
/// capture register is read only when its flag is set (reading it clears the flag); an overcapture
/// flag is cleared by writing it 0.
macro_rules! read_capture {
    ($tim:expr, $ch:expr, $sr:path) => {{
        let tim = $tim;
        let sr = tim.sr().read();
        let captured = sr.ccif($ch);
        let ccr = if captured {
            tim.ccr($ch).read().ccr() as u16
        } else {
            0
        };
        let overcaptured = sr.ccof($ch);
        if overcaptured {
            tim.sr().write_value($sr(SR_FLAGS & !(1 << (9 + $ch))));
        }
        (captured, overcaptured, ccr, tim.cnt().read().cnt() as u16)
    }};
}

/// The probe capture interrupt's work (the bin's `TIM3` handler calls it): the three captures, the
/// time, the pin, into [`CAPTURE_QUEUE`].
pub fn on_probe_capture_interrupt() {
    use embassy_stm32::pac;
    let time = cortex_m::peripheral::DWT::cycle_count();
    let t4 = read_capture!(pac::TIM4, TIM4_PROBE_CH, pac::timer::regs::SrGp16);
    let t3 = read_capture!(pac::TIM3, TIM3_PROBE_CH, pac::timer::regs::SrGp16);
    let t8 = read_capture!(pac::TIM8, TIM8_PROBE_CH, pac::timer::regs::SrAdv);
    // The capture path (synchroniser + the 8-clock input filter, ~70 ns) lags the pin's input data
    // register (2 clocks): wait longer than that before and after reading the pin, so an edge the
    // pin shows has set the capture flag by the time the flags are read again.
    cortex_m::asm::delay(CAPTURE_SETTLE_CYCLES);
    // PC8's input data register (the pin stays readable in alternate-function mode).
    let level_after = pac::GPIOC.idr().read().idr(8) == pac::gpio::vals::Idr::HIGH;
    cortex_m::asm::delay(CAPTURE_SETTLE_CYCLES);
    let sr3 = pac::TIM3.sr().read();
    let reading = CaptureReading {
        time,
        captured: [t4.0, t3.0, t8.0],
        overcaptured: [t4.1, t3.1, t8.1],
        ccr: [t4.2, t3.2, t8.2],
        cnt: [t4.3, t3.3, t8.3],
        level_after,
        next_pending: sr3.ccif(TIM3_PROBE_CH),
        raced: t3.0 && sr3.ccof(TIM3_PROBE_CH),
    };
    if reading.raced {
        // Cleared here: the loss is reported with this reading, not again with the next edge.
        pac::TIM3.sr().write_value(pac::timer::regs::SrGp16(
            SR_FLAGS & !(1 << (9 + TIM3_PROBE_CH)),
        ));
    }
    CAPTURE_QUEUE.lock(|q| {
        q.borrow_mut().on_capture(&reading);
    });
}

/// Puts channel `ch` (index) of an encoder timer in input-capture mode on both edges of its own
/// input (TIx), with the input filter `fCK_INT, N = 8` (a pulse must last 8 timer clocks, 47 ns at
/// 170 MHz: the same on the three timers, which run on the same clock).
macro_rules! configure_capture {
    ($tim:expr, $ch:expr) => {{
        use embassy_stm32::pac::timer::vals::{CcmrInputCcs, FilterValue};
        let tim = $tim;
        // CCxS = 01: input, ICx mapped on TIx (the metapac names the value TI4).
        tim.ccmr_input($ch / 2).modify(|w| {
            w.set_ccs($ch % 2, CcmrInputCcs::TI4);
            w.set_icf($ch % 2, FilterValue::FCK_INT_N8);
            w.set_icpsc($ch % 2, 0);
        });
        tim.ccer().modify(|w| {
            w.set_ccp($ch, true);
            w.set_ccnp($ch, true);
            w.set_cce($ch, true);
        });
        // Flags of captures before now are not edges of this run.
        let _ = tim.ccr($ch).read();
        tim.sr()
            .modify(|w| w.0 &= !((1 << (1 + $ch)) | (1 << (9 + $ch))));
    }};
}

/// The touch-probe input: hardware capture or the polled fallback ([`PROBE_INPUT_CAPTURE`]).
pub enum BoardProbe {
    /// The encoder timers capture the edges (PB8, PC8, PC9).
    Capture(CaptureProbe),
    /// PC8 polled once per cycle.
    Polled(PolledProbe),
}

/// The probe pins in capture mode (held so they stay in their alternate function).
pub struct CaptureProbe {
    _pins: (
        CapturePin<'static, peripherals::TIM4, timer::Ch3>,
        CapturePin<'static, peripherals::TIM3, timer::Ch3>,
        CapturePin<'static, peripherals::TIM8, timer::Ch4>,
    ),
}

impl CaptureProbe {
    /// Configures the capture channels beside the encoders (after `Qei::new`, which leaves CH3/CH4
    /// alone) and enables TIM3's capture interrupt; `level` = the probe pin now.
    fn start(
        pins: (
            CapturePin<'static, peripherals::TIM4, timer::Ch3>,
            CapturePin<'static, peripherals::TIM3, timer::Ch3>,
            CapturePin<'static, peripherals::TIM8, timer::Ch4>,
        ),
    ) -> Self {
        use embassy_stm32::interrupt::InterruptExt;
        use embassy_stm32::pac;
        let level = pac::GPIOC.idr().read().idr(8) == pac::gpio::vals::Idr::HIGH;
        CAPTURE_QUEUE.lock(|q| *q.borrow_mut() = CaptureQueue::new(level));
        configure_capture!(pac::TIM4, TIM4_PROBE_CH);
        configure_capture!(pac::TIM3, TIM3_PROBE_CH);
        configure_capture!(pac::TIM8, TIM8_PROBE_CH);
        // Only TIM3's channel interrupts; the ISR reads all three timers.
        pac::TIM3.dier().modify(|w| w.set_ccie(TIM3_PROBE_CH, true));
        embassy_stm32::interrupt::TIM3.set_priority(PROBE_CAPTURE_PRIORITY);
        embassy_stm32::interrupt::TIM3.unpend();
        // SAFETY: the bin's TIM3 handler only calls `on_probe_capture_interrupt`, whose state (the
        // queue) is behind a critical-section mutex; nothing else uses TIM3's interrupt.
        unsafe { embassy_stm32::interrupt::TIM3.enable() };
        CaptureProbe { _pins: pins }
    }
}

/// The probe input PC8, polled each cycle (the fallback).
pub struct PolledProbe {
    pin: Input<'static>,
    last: bool,
}

impl ProbeIo for BoardProbe {
    fn read_edges(
        &mut self,
        out: &mut [CapturedEdge; axcomp_core::probe::MAX_EDGES_PER_CYCLE],
    ) -> (usize, bool) {
        match self {
            BoardProbe::Capture(_) => CAPTURE_QUEUE.lock(|q| q.borrow_mut().take(out)),
            BoardProbe::Polled(p) => p.read_edges(out),
        }
    }

    fn level(&mut self) -> bool {
        match self {
            BoardProbe::Capture(_) => CAPTURE_QUEUE.lock(|q| q.borrow().level()),
            BoardProbe::Polled(p) => p.last,
        }
    }
}

impl PolledProbe {
    fn read_edges(
        &mut self,
        out: &mut [CapturedEdge; axcomp_core::probe::MAX_EDGES_PER_CYCLE],
    ) -> (usize, bool) {
        let level = self.pin.is_high();
        if level == self.last {
            return (0, false);
        }
        self.last = level;
        // Polled: the counters and the time of this cycle stand in for the edge's.
        let cnt = |t: embassy_stm32::pac::timer::TimGp16| u32::from(t.cnt().read().cnt() as u16);
        out[0] = CapturedEdge {
            time: cortex_m::peripheral::DWT::cycle_count(),
            level,
            scale_raw: [
                cnt(embassy_stm32::pac::TIM4),
                cnt(embassy_stm32::pac::TIM3),
                u32::from(embassy_stm32::pac::TIM8.cnt().read().cnt() as u16),
                0,
                0,
            ],
        };
        (1, false)
    }
}

/// The independent watchdog, started.
pub struct Iwdg(IndependentWatchdog<'static, peripherals::IWDG>);

impl Iwdg {
    /// Starts the IWDG with [`WATCHDOG_TIMEOUT_US`]; from now on the loop must feed it.
    pub fn start(&mut self) {
        self.0.unleash();
    }
}

impl Watchdog for Iwdg {
    fn feed(&mut self) {
        self.0.pet();
    }
}

/// Reads why the chip reset (RCC_CSR: IWDGRSTF, WWDGRSTF) and clears the flags (RMVF), so a later reset
/// by another cause is not mistaken for a watchdog one.
pub fn take_reset_cause() -> ResetCause {
    let rcc = embassy_stm32::pac::RCC;
    let csr = rcc.csr().read();
    let cause = ResetCause {
        watchdog: csr.iwdgrstf() || csr.wwdgrstf(),
    };
    rcc.csr().modify(|w| w.set_rmvf(true));
    cause
}

/// DWT cycle counter at [`CORE_CLOCK_HZ`].
pub struct DwtClock;

impl DwtClock {
    /// Enables the cycle counter.
    pub fn new(mut core: cortex_m::Peripherals) -> Self {
        core.DCB.enable_trace();
        core.DWT.enable_cycle_counter();
        DwtClock
    }
}

impl CycleClock for DwtClock {
    fn now(&self) -> u32 {
        cortex_m::peripheral::DWT::cycle_count()
    }
}

type RtdBus = Mutex<NoopRawMutex, RefCell<Spi<'static, Blocking, spi::mode::Master>>>;
/// One MAX31865 on the shared RTD bus.
pub type Rtd = Max31865<
    SpiDevice<'static, NoopRawMutex, Spi<'static, Blocking, spi::mode::Master>, Output<'static>>,
>;

/// Peripherals the application tasks use.
pub struct Board {
    pub io: BoardIo,
    /// The touch-probe input.
    pub probe: BoardProbe,
    pub rtds: [Rtd; RTD_COUNT],
    pub clock: DwtClock,
    /// Configured, not started ([`Iwdg::start`]).
    pub watchdog: Iwdg,
    /// Why the chip last reset (read before anything else, flags cleared).
    pub reset_cause: ResetCause,
}

/// Brings up clocks and peripherals.
pub fn init() -> Board {
    static RTD_BUS: StaticCell<RtdBus> = StaticCell::new();
    static UART_TX_BUF: ConstStaticCell<[u8; 256]> = ConstStaticCell::new([0; 256]);
    static UART_RX_BUF: ConstStaticCell<[u8; 256]> = ConstStaticCell::new([0; 256]);

    let p = embassy_stm32::init(config());
    let reset_cause = take_reset_cause();
    let core = cortex_m::Peripherals::take().expect("core peripherals taken once");

    let qei0 = Qei::new(p.TIM4, p.PB6, p.PB7, qei::Config::default());
    let qei1 = Qei::new(p.TIM3, p.PB4, p.PB5, qei::Config::default());
    let qei2 = Qei::new(p.TIM8, p.PC6, p.PC7, qei::Config::default());
    let watchdog = Iwdg(IndependentWatchdog::new(p.IWDG, WATCHDOG_TIMEOUT_US));

    let mut ucfg = usart::Config::default();
    ucfg.baudrate = LINK_BAUD;
    let uart = BufferedUart::new(
        p.USART1,
        p.PA10,
        p.PA9,
        UART_TX_BUF.take(),
        UART_RX_BUF.take(),
        Irqs,
        ucfg,
    )
    .expect("USART1 config");
    let (tx, rx) = uart.split();

    let mut scfg = spi::Config::default();
    scfg.mode = spi::MODE_1;
    scfg.frequency = Hertz(1_000_000);
    let spi = Spi::new_blocking(p.SPI1, p.PA5, p.PA7, p.PA6, scfg);
    let bus: &'static RtdBus = RTD_BUS.init(Mutex::new(RefCell::new(spi)));
    let settings = SettingsBuilder::PT100.build().expect("PT100 settings");
    let rtd = |cs: Peri<'static, AnyPin>| {
        Max31865::new(
            SpiDevice::new(bus, Output::new(cs, Level::High, Speed::VeryHigh)),
            settings,
        )
    };
    let rtds = [rtd(p.PB0.into()), rtd(p.PB1.into())];

    let probe = if PROBE_INPUT_CAPTURE {
        BoardProbe::Capture(CaptureProbe::start((
            CapturePin::new(p.PB8, Pull::Down),
            CapturePin::new(p.PC8, Pull::Down),
            CapturePin::new(p.PC9, Pull::Down),
        )))
    } else {
        let pin = Input::new(p.PC8, Pull::Down);
        let last = pin.is_high();
        BoardProbe::Polled(PolledProbe { pin, last })
    };

    Board {
        probe,
        io: BoardIo {
            qei0,
            qei1,
            qei2,
            rx,
            tx,
        },
        rtds,
        clock: DwtClock::new(core),
        watchdog,
        reset_cause,
    }
}

/// The image slots from `memory.x`, each cut to the image it holds: the length declared in the
/// image's header ([`axcomp_core::declared_image_len`]), or the whole slot when the header is not
/// an image's (erased flash, a corrupt header), so that the loader reports why.
pub fn image_slots() -> [&'static [u8]; 2] {
    unsafe extern "C" {
        static __slot_a_start: u8;
        static __slot_b_start: u8;
    }
    const SLOT_LEN: usize = axcomp_core::IMAGE_SLOT_LEN;
    // SAFETY: the linker script reserves `IMAGE_SLOT_LEN` (128 KiB) of read-only flash at each
    // symbol; nothing writes it while the firmware runs (the host programs the slots).
    let slots = unsafe {
        [
            core::slice::from_raw_parts(&raw const __slot_a_start, SLOT_LEN),
            core::slice::from_raw_parts(&raw const __slot_b_start, SLOT_LEN),
        ]
    };
    slots.map(|s| match axcomp_core::declared_image_len(s) {
        Ok(n) => s.get(..n).unwrap_or(s),
        Err(_) => s,
    })
}
