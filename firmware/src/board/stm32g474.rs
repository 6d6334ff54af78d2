//! STM32G474RE board support (NUCLEO-G474RE wiring). The only module that names this chip.
//!
//! Glossary:
//! - **QEI**: the timer in encoder mode counting the scale's A/B quadrature signals (TIM4: PB6 = A, PB7 = B);
//!   a 16-bit counter, so images for this board use `counter_bits = 16`.
//! - **RTD bus**: SPI1 (PA5 SCK, PA6 MISO, PA7 MOSI, mode 1, 1 MHz) shared by the MAX31865 converters, chip
//!   selects PB0, PB1 (sensor 0, 1).
//! - **Setpoint link**: USART1 (PA9 TX, PA10 RX, 2 Mbaud 8N1) carrying [`crate::setpoint`] frames: commands in,
//!   corrected commands out.
//! - **Cycle clock**: DWT CYCCNT at the core clock (170 MHz).
//! - **Image slots**: the two 64 KiB flash regions `__slot_a_start` / `__slot_b_start` from `memory.x`.

use core::cell::RefCell;

use embassy_embedded_hal::shared_bus::blocking::spi::SpiDevice;
use embassy_stm32::gpio::{AnyPin, Level, Output, Speed};
use embassy_stm32::mode::Blocking;
use embassy_stm32::spi::{self, Spi};
use embassy_stm32::time::Hertz;
use embassy_stm32::timer::qei::{self, Qei};
use embassy_stm32::usart::{self, BufferedUart, BufferedUartRx, BufferedUartTx};
use embassy_stm32::{Peri, bind_interrupts, peripherals};
use embassy_sync::blocking_mutex::Mutex;
use embassy_sync::blocking_mutex::raw::NoopRawMutex;
use static_cell::{ConstStaticCell, StaticCell};

use crate::control::{AxisIo, CycleClock};
use crate::max31865::{Max31865, SettingsBuilder};
use crate::setpoint;

/// Core clock after [`config`]: HSI16 → PLL → 170 MHz.
pub const CORE_CLOCK_HZ: u32 = 170_000_000;
/// Number of RTD channels wired on this board.
pub const RTD_COUNT: usize = 2;

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

/// The scale (QEI) and the setpoint link.
pub struct Axis {
    qei: Qei<'static, peripherals::TIM4>,
    rx: BufferedUartRx<'static>,
    tx: BufferedUartTx<'static>,
    decoder: setpoint::Decoder,
    command: i64,
}

impl AxisIo for Axis {
    fn read_scale(&mut self) -> u32 {
        u32::from(self.qei.count())
    }

    fn read_command(&mut self) -> i64 {
        use embedded_io::Read;
        use embedded_io_async::ReadReady;
        let mut buf = [0u8; 32];
        // Drain whatever arrived; keep the newest complete setpoint.
        while matches!(self.rx.read_ready(), Ok(true)) {
            match self.rx.read(&mut buf) {
                Ok(n) => {
                    for &b in &buf[..n] {
                        if let Some(v) = self.decoder.push(b) {
                            self.command = v;
                        }
                    }
                }
                Err(_) => break,
            }
        }
        self.command
    }

    fn write_command(&mut self, counts: i64) {
        use embedded_io::Write;
        // The TX ring holds several frames; a frame per cycle at 2 Mbaud never fills it.
        let _ = self.tx.write_all(&setpoint::encode(counts));
    }
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
    pub axis: Axis,
    pub rtds: [Rtd; RTD_COUNT],
    pub clock: DwtClock,
}

/// Brings up clocks and peripherals.
pub fn init() -> Board {
    static RTD_BUS: StaticCell<RtdBus> = StaticCell::new();
    static UART_TX_BUF: ConstStaticCell<[u8; 256]> = ConstStaticCell::new([0; 256]);
    static UART_RX_BUF: ConstStaticCell<[u8; 256]> = ConstStaticCell::new([0; 256]);

    let p = embassy_stm32::init(config());
    let core = cortex_m::Peripherals::take().expect("core peripherals taken once");

    let qei = Qei::new(p.TIM4, p.PB6, p.PB7, qei::Config::default());

    let mut ucfg = usart::Config::default();
    ucfg.baudrate = 2_000_000;
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

    Board {
        axis: Axis {
            qei,
            rx,
            tx,
            decoder: setpoint::Decoder::new(),
            command: 0,
        },
        rtds,
        clock: DwtClock::new(core),
    }
}

/// The image slots from `memory.x`.
pub fn image_slots() -> [&'static [u8]; 2] {
    unsafe extern "C" {
        static __slot_a_start: u8;
        static __slot_b_start: u8;
    }
    const SLOT_LEN: usize = 64 * 1024;
    // SAFETY: the linker script reserves 64 KiB of read-only flash at each symbol; nothing writes it while
    // the firmware runs (the host programs the slots).
    unsafe {
        [
            core::slice::from_raw_parts(&raw const __slot_a_start, SLOT_LEN),
            core::slice::from_raw_parts(&raw const __slot_b_start, SLOT_LEN),
        ]
    }
}
