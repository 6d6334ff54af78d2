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
//! - **Touch probe** ([`BoardProbe`]): PC8 (CN10), deflected = high (pull-down; an SSR/open-collector
//!   probe interface switches 3.3 V). Today the input is *polled* once per cycle and an edge takes that
//!   cycle's counters and DWT time: the latched point can be up to one cycle late (100 µs: 1.7 µm at
//!   1000 mm/min), so it does not meet the 0.5 µm on this board yet. TODO (hardware input
//!   capture, needs the probe signal fanned out on the board): TIM4_CH3 (PB8), TIM3_CH3 (PC8) and
//!   TIM8_CH4 (PC9) in input-capture mode beside their encoder channels latch each counter at the edge
//!   in hardware (CCR3/CCR4), and an EXTI interrupt on the same signal stamps the DWT time and queues
//!   the [`crate::drive::probe::CapturedEdge`] with the three CCR values; the drive side (filter,
//!   latency, lockout, correction) is unchanged and tested on the host and in QEMU.

use core::cell::RefCell;

use embassy_embedded_hal::shared_bus::blocking::spi::SpiDevice;
use embassy_stm32::gpio::{AnyPin, Input, Level, Output, Pull, Speed};
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::usart::{self, BufferedUart, BufferedUartRx, BufferedUartTx};
use embassy_stm32::wdg::IndependentWatchdog;
use embassy_stm32::{Peri, bind_interrupts, peripherals};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use static_cell::{ConstStaticCell, StaticCell};

use crate::control::CycleClock;
use crate::drive::probe::{CapturedEdge, ProbeIo};
use crate::drive::{BoardCaps, DriveIo, ResetCause, Watchdog};
use crate::max31865::{Max31865, SettingsBuilder};

/// Core clock after [`config`]: HSI16 → PLL → 170 MHz.
pub const CORE_CLOCK_HZ: u32 = 170_000_000;
/// Number of RTD channels wired on this board.
pub const RTD_COUNT: usize = 2;
/// Scale inputs (timers in encoder mode) wired on this board.
pub const SCALE_INPUTS: usize = 3;
/// Axis id of each scale input (and its position in the setpoint frame): set them to the machine's.
pub const AXIS_IDS: [u16; SCALE_INPUTS] = [1, 2, 3];
/// What this board has: every image is checked against it before it is applied.
pub const CAPS: BoardCaps = BoardCaps {
    counter_bits: 16,
    axis_ids: &AXIS_IDS,
    sensors: RTD_COUNT as u16,
};
/// The board's sensor inputs by name and unit, in reading order (RTD on chip select PB0, PB1): an
/// image's sensors are wired to them by name at load, and a sensor none of them can feed (e.g. a
/// `warmup` input: this board has no drive-enable input wired) is refused
/// ([`crate::drive::ImageRefusal::SensorNotOnBoard`]). Like [`AXIS_IDS`], name them after what is
/// wired on the machine (the replays name them `spindle`, `column`:
/// [`crate::drive::link_trace::REPLAY_SENSOR_INPUTS`]).
pub const SENSOR_INPUTS: [axcomp_core::wiring::BoardInput<'static>; RTD_COUNT] = [
    axcomp_core::wiring::BoardInput {
        name: "rtd0",
        unit: axcomp_core::wiring::InputUnit::DegC,
    },
    axcomp_core::wiring::BoardInput {
        name: "rtd1",
        unit: axcomp_core::wiring::InputUnit::DegC,
    },
];
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

/// The touch-probe input (PC8, polled each cycle; see the module doc for the input-capture TODO).
pub struct BoardProbe {
    pin: Input<'static>,
    last: bool,
}

impl ProbeIo for BoardProbe {
    fn read_edges(
        &mut self,
        out: &mut [CapturedEdge; axcomp_core::probe::MAX_EDGES_PER_CYCLE],
    ) -> (usize, bool) {
        let level = self.pin.is_high();
        if level == self.last {
            return (0, false);
        }
        self.last = level;
        // Polled: the counters and the time of this cycle stand in for the edge's (TODO above).
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

    fn level(&mut self) -> bool {
        self.last
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

    let probe = BoardProbe {
        pin: Input::new(p.PC8, Pull::Down),
        last: false,
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
