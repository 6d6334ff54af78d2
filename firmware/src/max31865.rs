//! MAX31865 RTD-to-digital converter driver, generic over an embedded-hal 1.0 [`SpiDevice`].
//!
//! Glossary:
//! - **RTD**: resistance temperature detector, here a platinum PT100 (R0 = 100 Ω) or PT1000 (R0 = 1000 Ω).
//! - **R0**: the RTD's resistance at 0 °C.
//! - **Reference resistor** (`r_ref_ohm`): the precision resistor on the board the RTD is ratioed against
//!   (typically 430 Ω for PT100, 4300 Ω for PT1000). The ADC code is `R_rtd / R_ref · 2^15`.
//! - **Callendar–Van Dusen (CVD)**: the IEC 60751 resistance–temperature relation of platinum RTDs,
//!   `R(T) = R0·(1 + A·T + B·T²)` for T ≥ 0 °C, plus `C·(T − 100)·T³` inside the bracket for T < 0 °C.
//! - **Fault status**: the chip's register 0x07; a set fault bit in the RTD LSB register says one is latched.
//!
//! Register transactions (datasheet, "Serial Interface"): a read sends the register address (bit 7 clear) and
//! clocks out the data with auto-increment; a write sends `address | 0x80` followed by the data. SPI mode 1 or 3.

use embedded_hal::spi::{Operation, SpiDevice};

/// Callendar–Van Dusen coefficients of IEC 60751 (α = 0.00385).
pub const CVD_A: f32 = 3.9083e-3;
/// See [`CVD_A`].
pub const CVD_B: f32 = -5.775e-7;
/// See [`CVD_A`]; used below 0 °C only.
pub const CVD_C: f32 = -4.183e-12;

/// Register addresses (read address; the write address is `| 0x80`).
pub mod reg {
    pub const CONFIG: u8 = 0x00;
    pub const RTD_MSB: u8 = 0x01;
    pub const HIGH_FAULT_MSB: u8 = 0x03;
    pub const FAULT_STATUS: u8 = 0x07;
    pub const WRITE: u8 = 0x80;
}

/// Configuration register bits.
pub mod config {
    pub const VBIAS: u8 = 0x80;
    pub const AUTO_CONVERSION: u8 = 0x40;
    pub const ONE_SHOT: u8 = 0x20;
    pub const THREE_WIRE: u8 = 0x10;
    /// D3:D2 = 01: start the automatic fault-detection cycle (reads back 00 when finished).
    pub const FAULT_DETECT_AUTO: u8 = 0x04;
    /// D3:D2 mask of the fault-detection cycle control.
    pub const FAULT_DETECT_MASK: u8 = 0x0C;
    pub const FAULT_CLEAR: u8 = 0x02;
    pub const FILTER_50HZ: u8 = 0x01;
}

/// RTD wiring.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Wiring {
    TwoWire,
    ThreeWire,
    FourWire,
}

/// Mains rejection filter of the converter's ADC.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MainsFilter {
    Hz50,
    Hz60,
}

/// Unvalidated settings; turn them into [`Settings`] with [`SettingsBuilder::build`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SettingsBuilder {
    pub wiring: Wiring,
    pub filter: MainsFilter,
    /// RTD resistance at 0 °C (100 for PT100, 1000 for PT1000).
    pub r0_ohm: f32,
    /// Reference resistor on the board.
    pub r_ref_ohm: f32,
}

impl SettingsBuilder {
    /// PT100 with a 430 Ω reference (the common breakout board), 50 Hz filter.
    pub const PT100: SettingsBuilder = SettingsBuilder {
        wiring: Wiring::FourWire,
        filter: MainsFilter::Hz50,
        r0_ohm: 100.0,
        r_ref_ohm: 430.0,
    };
    /// PT1000 with a 4300 Ω reference, 50 Hz filter.
    pub const PT1000: SettingsBuilder = SettingsBuilder {
        wiring: Wiring::FourWire,
        filter: MainsFilter::Hz50,
        r0_ohm: 1000.0,
        r_ref_ohm: 4300.0,
    };

    /// Validates: R0 is finite and positive, and the reference is finite and exceeds R0 (the ADC's full
    /// scale is R_ref; boards use R_ref ≈ 4.3·R0 so that 850 °C stays in range).
    pub fn build(self) -> Result<Settings, SettingsError> {
        if !(self.r0_ohm.is_finite() && self.r0_ohm > 0.0) {
            return Err(SettingsError::BadR0);
        }
        if !(self.r_ref_ohm.is_finite() && self.r_ref_ohm > self.r0_ohm) {
            return Err(SettingsError::BadReference);
        }
        let mut cfg = config::VBIAS | config::AUTO_CONVERSION;
        if self.wiring == Wiring::ThreeWire {
            cfg |= config::THREE_WIRE;
        }
        if self.filter == MainsFilter::Hz50 {
            cfg |= config::FILTER_50HZ;
        }
        Ok(Settings {
            config_byte: cfg,
            ohm_per_code: self.r_ref_ohm / 32768.0,
            r0_ohm: self.r0_ohm,
        })
    }
}

/// Invalid [`SettingsBuilder`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SettingsError {
    /// R0 not finite or not positive.
    BadR0,
    /// Reference resistor not finite or not above R0.
    BadReference,
}

impl core::fmt::Display for SettingsError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            SettingsError::BadR0 => f.write_str("RTD R0 must be finite and > 0 ohm"),
            SettingsError::BadReference => {
                f.write_str("reference resistor must be finite and greater than the RTD's R0")
            }
        }
    }
}

impl core::error::Error for SettingsError {}

/// Validated settings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Settings {
    config_byte: u8,
    ohm_per_code: f32,
    r0_ohm: f32,
}

impl Settings {
    /// The configuration register value written by [`Max31865::init`].
    pub fn config_byte(&self) -> u8 {
        self.config_byte
    }

    /// RTD resistance of a 15-bit ADC code.
    pub fn resistance_ohm(&self, code: u16) -> f32 {
        code as f32 * self.ohm_per_code
    }

    /// Temperature of an RTD resistance (Callendar–Van Dusen, see [`rtd_temperature_degc`]).
    pub fn temperature_degc(&self, resistance_ohm: f32) -> f32 {
        rtd_temperature_degc(resistance_ohm, self.r0_ohm)
    }
}

/// Latched fault bits of the fault status register (0x07).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct FaultStatus(pub u8);

impl FaultStatus {
    /// RTD code above the high fault threshold.
    pub const RTD_HIGH: u8 = 0x80;
    /// RTD code below the low fault threshold.
    pub const RTD_LOW: u8 = 0x40;
    /// REFIN− > 0.85·VBIAS.
    pub const REFIN_HIGH: u8 = 0x20;
    /// REFIN− < 0.85·VBIAS, FORCE− open.
    pub const REFIN_LOW_FORCE_OPEN: u8 = 0x10;
    /// RTDIN− < 0.85·VBIAS, FORCE− open.
    pub const RTDIN_LOW_FORCE_OPEN: u8 = 0x08;
    /// Over- or under-voltage on an input.
    pub const OVER_UNDER_VOLTAGE: u8 = 0x04;

    /// True when `bit` (one of the constants above) is set.
    pub fn has(self, bit: u8) -> bool {
        self.0 & bit != 0
    }

    /// An open RTD reads as high threshold plus open FORCE−; a short as low threshold.
    pub fn is_open_circuit(self) -> bool {
        self.has(Self::RTD_HIGH)
            && (self.has(Self::REFIN_LOW_FORCE_OPEN) || self.has(Self::RTDIN_LOW_FORCE_OPEN))
    }
}

/// Driver error.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Error<E> {
    /// The SPI transaction failed.
    Spi(E),
    /// The converter reported a fault; the status was read and the latch cleared.
    Fault(FaultStatus),
    /// The automatic fault-detection cycle did not finish within its time limit.
    FaultDetectionTimeout,
}

impl<E: core::fmt::Debug> core::fmt::Display for Error<E> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Error::Spi(e) => write!(f, "MAX31865 SPI error: {e:?}"),
            Error::Fault(s) => write!(f, "MAX31865 fault, status 0x{:02x}", s.0),
            Error::FaultDetectionTimeout => {
                f.write_str("MAX31865 fault-detection cycle did not finish within 1 ms")
            }
        }
    }
}

impl<E: core::fmt::Debug> core::error::Error for Error<E> {}

/// One MAX31865 on an SPI device (the device owns chip select).
pub struct Max31865<SPI> {
    spi: SPI,
    settings: Settings,
}

impl<SPI: SpiDevice> Max31865<SPI> {
    pub fn new(spi: SPI, settings: Settings) -> Self {
        Max31865 { spi, settings }
    }

    /// Releases the SPI device.
    pub fn release(self) -> SPI {
        self.spi
    }

    pub fn settings(&self) -> &Settings {
        &self.settings
    }

    /// Opens the fault window fully (high threshold 0xFFFF, low 0x0000) and starts automatic conversion
    /// with bias on, the configured wiring and filter, clearing any latched fault.
    pub fn init(&mut self) -> Result<(), Error<SPI::Error>> {
        self.spi
            .write(&[reg::HIGH_FAULT_MSB | reg::WRITE, 0xFF, 0xFF, 0x00, 0x00])
            .map_err(Error::Spi)?;
        self.write_config(self.settings.config_byte | config::FAULT_CLEAR)
    }

    /// Reads the configuration register.
    pub fn read_config(&mut self) -> Result<u8, Error<SPI::Error>> {
        let mut b = [0u8; 1];
        self.read_registers(reg::CONFIG, &mut b)?;
        Ok(b[0])
    }

    /// Reads the fault status register.
    pub fn read_fault_status(&mut self) -> Result<FaultStatus, Error<SPI::Error>> {
        let mut b = [0u8; 1];
        self.read_registers(reg::FAULT_STATUS, &mut b)?;
        Ok(FaultStatus(b[0]))
    }

    /// Clears latched faults (the clear bit self-resets).
    pub fn clear_faults(&mut self) -> Result<(), Error<SPI::Error>> {
        self.write_config(self.settings.config_byte | config::FAULT_CLEAR)
    }

    /// Reads the 15-bit RTD code. When the fault bit is set, reads the fault status, clears the latch and
    /// returns [`Error::Fault`].
    pub fn read_code(&mut self) -> Result<u16, Error<SPI::Error>> {
        let mut b = [0u8; 2];
        self.read_registers(reg::RTD_MSB, &mut b)?;
        let word = u16::from_be_bytes(b);
        if word & 1 != 0 {
            let status = self.read_fault_status()?;
            self.clear_faults()?;
            return Err(Error::Fault(status));
        }
        Ok(word >> 1)
    }

    /// RTD resistance in ohm.
    pub fn read_resistance_ohm(&mut self) -> Result<f32, Error<SPI::Error>> {
        let code = self.read_code()?;
        Ok(self.settings.resistance_ohm(code))
    }

    /// RTD temperature in °C (Callendar–Van Dusen).
    pub fn read_temperature_degc(&mut self) -> Result<f32, Error<SPI::Error>> {
        let r = self.read_resistance_ohm()?;
        Ok(self.settings.temperature_degc(r))
    }

    /// Runs the chip's automatic fault-detection cycle (datasheet "Fault Detection": conversion off, bias on,
    /// D3:D2 = 01; the chip clears D3:D2 when done, within about 600 µs), returns the fault status it latched
    /// and restores automatic conversion with the latch cleared. Polls every 100 µs for at most 1 ms.
    pub fn run_fault_detection<D: embedded_hal::delay::DelayNs>(
        &mut self,
        delay: &mut D,
    ) -> Result<FaultStatus, Error<SPI::Error>> {
        let base = self.settings.config_byte & !config::AUTO_CONVERSION;
        self.write_config(base | config::FAULT_DETECT_AUTO)?;
        let mut done = false;
        for _ in 0..10 {
            delay.delay_us(100);
            if self.read_config()? & config::FAULT_DETECT_MASK == 0 {
                done = true;
                break;
            }
        }
        let status = self.read_fault_status()?;
        self.write_config(self.settings.config_byte | config::FAULT_CLEAR)?;
        if !done {
            return Err(Error::FaultDetectionTimeout);
        }
        Ok(status)
    }

    fn write_config(&mut self, value: u8) -> Result<(), Error<SPI::Error>> {
        self.spi
            .write(&[reg::CONFIG | reg::WRITE, value])
            .map_err(Error::Spi)
    }

    fn read_registers(&mut self, first: u8, out: &mut [u8]) -> Result<(), Error<SPI::Error>> {
        self.spi
            .transaction(&mut [Operation::Write(&[first & 0x7F]), Operation::Read(out)])
            .map_err(Error::Spi)
    }
}

/// Temperature in °C of a platinum RTD of resistance `r_ohm` with `R0 = r0_ohm` (IEC 60751 Callendar–Van
/// Dusen). T ≥ 0 °C: closed-form root of the quadratic in the numerically stable form
/// `T = 2(r − 1) / (A + sqrt(A² − 4B(1 − r)))`, `r = R/R0`. T < 0 °C: Newton iterations on the full CVD
/// equation starting from the quadratic root (converges to < 1e-4 °C in three steps over −200..0 °C).
/// Returns NaN for a non-finite or non-positive resistance.
pub fn rtd_temperature_degc(r_ohm: f32, r0_ohm: f32) -> f32 {
    if !(r_ohm.is_finite() && r_ohm > 0.0) {
        return f32::NAN;
    }
    let r = r_ohm / r0_ohm;
    let disc = CVD_A * CVD_A - 4.0 * CVD_B * (1.0 - r);
    let mut t = 2.0 * (r - 1.0) / (CVD_A + libm::sqrtf(disc));
    if r < 1.0 {
        for _ in 0..3 {
            let t2 = t * t;
            let f = 1.0 + CVD_A * t + CVD_B * t2 + CVD_C * (t - 100.0) * t2 * t - r;
            let df = CVD_A + 2.0 * CVD_B * t + CVD_C * (4.0 * t2 * t - 300.0 * t2);
            t -= f / df;
        }
    }
    t
}

/// Resistance of a platinum RTD at `t_degc` (forward CVD), for tests and simulation.
pub fn rtd_resistance_ohm(t_degc: f32, r0_ohm: f32) -> f32 {
    let t2 = t_degc * t_degc;
    let mut x = 1.0 + CVD_A * t_degc + CVD_B * t2;
    if t_degc < 0.0 {
        x += CVD_C * (t_degc - 100.0) * t2 * t_degc;
    }
    r0_ohm * x
}

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use embedded_hal_mock::eh1::spi::{Mock, Transaction as T};
    use std::vec;

    /// The driver's fault handling: read the fault status register (0x07), then write the configuration back
    /// (0x80 ← 0xC3: bias on, auto conversion, fault-status clear).
    fn status_then_restore_config(status: u8) -> [T<u8>; 7] {
        [
            T::transaction_start(),
            T::write(0x07),
            T::read_vec(vec![status]),
            T::transaction_end(),
            T::transaction_start(),
            T::write_vec(vec![0x80, 0xC3]),
            T::transaction_end(),
        ]
    }

    /// IEC 60751 table values (PT100, resistance rounded to 0.01 Ω in the standard).
    const IEC60751_PT100: &[(f32, f32)] = &[
        (-200.0, 18.52),
        (-100.0, 60.26),
        (-50.0, 80.31),
        (0.0, 100.00),
        (50.0, 119.40),
        (100.0, 138.51),
        (200.0, 175.86),
        (400.0, 247.09),
        (850.0, 390.48),
    ];

    #[test]
    fn cvd_inverse_matches_iec60751_table() {
        // Reference: IEC 60751 PT100 table. Tolerance 0.03 °C: the table's resistances are rounded to 0.01 Ω,
        // which is 0.026 °C at the lowest sensitivity (0.39 Ω/K near 850 °C... 0.43 Ω/K at −200 °C).
        for &(t, r) in IEC60751_PT100 {
            let got = rtd_temperature_degc(r, 100.0);
            assert!(
                (got - t).abs() < 0.03,
                "R = {r} Ω: expected {t} °C, got {got} °C"
            );
            // PT1000: ten times the resistance, same temperature.
            let got1000 = rtd_temperature_degc(10.0 * r, 1000.0);
            assert!(
                (got1000 - t).abs() < 0.03,
                "PT1000 R = {} Ω: expected {t} °C, got {got1000}",
                10.0 * r
            );
        }
        assert_eq!(
            rtd_temperature_degc(100.0, 100.0),
            0.0,
            "R0 is exactly 0 °C"
        );
    }

    #[test]
    fn cvd_forward_matches_iec60751_table_and_roundtrips() {
        // Reference: IEC 60751 table; tolerance 0.006 Ω (half the table's 0.01 Ω rounding plus f32 error).
        for &(t, r) in IEC60751_PT100 {
            let got = rtd_resistance_ohm(t, 100.0);
            assert!(
                (got - r).abs() < 0.006,
                "T = {t} °C: expected {r} Ω, got {got} Ω"
            );
        }
        // Round trip forward → inverse over −200..850 °C every 0.5 °C, tolerance 2e-3 °C (f32 arithmetic).
        let mut t = -200.0f32;
        while t <= 850.0 {
            let back = rtd_temperature_degc(rtd_resistance_ohm(t, 100.0), 100.0);
            assert!(
                (back - t).abs() < 2e-3,
                "round trip at {t} °C gave {back} °C"
            );
            t += 0.5;
        }
    }

    #[test]
    fn bad_resistance_is_nan() {
        assert!(rtd_temperature_degc(f32::NAN, 100.0).is_nan());
        assert!(rtd_temperature_degc(0.0, 100.0).is_nan());
        assert!(rtd_temperature_degc(-1.0, 100.0).is_nan());
    }

    #[test]
    fn settings_are_validated() {
        let mut s = SettingsBuilder::PT100;
        s.r_ref_ohm = 50.0;
        assert_eq!(s.build(), Err(SettingsError::BadReference));
        s.r0_ohm = f32::NAN;
        assert_eq!(s.build(), Err(SettingsError::BadR0));
        let s = SettingsBuilder {
            wiring: Wiring::ThreeWire,
            filter: MainsFilter::Hz60,
            ..SettingsBuilder::PT100
        }
        .build()
        .unwrap();
        assert_eq!(s.config_byte(), 0x80 | 0x40 | 0x10);
        assert_eq!(SettingsBuilder::PT1000.build().unwrap().config_byte(), 0xC1);
    }

    #[test]
    fn init_writes_thresholds_then_config() {
        let expectations = [
            T::transaction_start(),
            T::write_vec(vec![0x83, 0xFF, 0xFF, 0x00, 0x00]),
            T::transaction_end(),
            T::transaction_start(),
            T::write_vec(vec![0x80, 0xC1 | 0x02]),
            T::transaction_end(),
            T::transaction_start(),
            T::write(0x00),
            T::read_vec(vec![0xC1]),
            T::transaction_end(),
        ];
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        dev.init().unwrap();
        assert_eq!(dev.read_config().unwrap(), 0xC1);
        spi.done();
    }

    #[test]
    fn reads_temperature_from_rtd_registers() {
        // 138.51 Ω with R_ref = 430 Ω → code round(138.51/430·32768) = 10555 → word 21110 = 0x5276.
        // Expected 100 °C (IEC 60751); tolerance 0.04 °C = one ADC step (430/32768 Ω = 0.0131 Ω ≈ 0.034 °C).
        let code: u16 = 10555;
        let word = (code << 1).to_be_bytes();
        let expectations = [
            T::transaction_start(),
            T::write(0x01),
            T::read_vec(vec![word[0], word[1]]),
            T::transaction_end(),
        ];
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        let t = dev.read_temperature_degc().unwrap();
        assert!((t - 100.0).abs() < 0.04, "expected 100 °C, got {t}");
        spi.done();

        // 100 Ω → code 7620.47 → 7620 → 0 °C within one ADC step (0.034 °C).
        let word = (7620u16 << 1).to_be_bytes();
        let expectations = [
            T::transaction_start(),
            T::write(0x01),
            T::read_vec(vec![word[0], word[1]]),
            T::transaction_end(),
        ];
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        let t = dev.read_temperature_degc().unwrap();
        assert!(t.abs() < 0.04, "expected 0 °C, got {t}");
        spi.done();
    }

    #[test]
    fn fault_bit_reads_status_and_clears_latch() {
        // Open RTD: code saturates with the fault bit set; status = RTD high + FORCE− open (0x80 | 0x08).
        let mut expectations = vec![
            T::transaction_start(),
            T::write(0x01),
            T::read_vec(vec![0xFF, 0xFF]),
            T::transaction_end(),
        ];
        expectations.extend(status_then_restore_config(0x88));
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        let err = dev.read_temperature_degc().unwrap_err();
        assert_eq!(err, Error::Fault(FaultStatus(0x88)));
        match err {
            Error::Fault(s) => {
                assert!(s.is_open_circuit());
                assert!(s.has(FaultStatus::RTD_HIGH));
                assert!(!s.has(FaultStatus::OVER_UNDER_VOLTAGE));
            }
            _ => unreachable!(),
        }
        spi.done();
    }

    #[test]
    fn fault_detection_cycle_polls_until_done_and_restores_conversion() {
        use embedded_hal_mock::eh1::delay::NoopDelay;
        // PT100 defaults: normal config 0xC1. Detection: 0x81 & !0x40 | 0x04 = 0x85; busy reads 0x85,
        // done reads 0x81; status 0x04 (over/under-voltage); restore 0xC1 | clear 0x02 = 0xC3.
        let read_config = |v: u8| {
            [
                T::transaction_start(),
                T::write(0x00),
                T::read_vec(vec![v]),
                T::transaction_end(),
            ]
        };
        let mut expectations = vec![
            T::transaction_start(),
            T::write_vec(vec![0x80, 0x85]),
            T::transaction_end(),
        ];
        expectations.extend(read_config(0x85));
        expectations.extend(read_config(0x81));
        expectations.extend(status_then_restore_config(0x04));
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        let st = dev.run_fault_detection(&mut NoopDelay).unwrap();
        assert!(st.has(FaultStatus::OVER_UNDER_VOLTAGE));
        spi.done();

        // Never finishing: ten polls, then the status is still read, conversion restored, and a timeout.
        let mut expectations = vec![
            T::transaction_start(),
            T::write_vec(vec![0x80, 0x85]),
            T::transaction_end(),
        ];
        for _ in 0..10 {
            expectations.extend(read_config(0x85));
        }
        expectations.extend(status_then_restore_config(0x00));
        let mut spi = Mock::new(&expectations);
        let mut dev = Max31865::new(spi.clone(), SettingsBuilder::PT100.build().unwrap());
        assert_eq!(
            dev.run_fault_detection(&mut NoopDelay),
            Err(Error::FaultDetectionTimeout)
        );
        spi.done();
    }
}
