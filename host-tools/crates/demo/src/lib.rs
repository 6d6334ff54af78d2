//! The whole compensation loop on the digital twin, with no input files: what `axcomp demo` and
//! `axcomp demo --all` compute. The command parses its options, calls [`axis::run`] or [`all::run`]
//! and writes the returned files and console text; nothing here writes a file or prints.
//!
//! Glossary:
//! - *twin*: the simulated machine (`axcomp_twin`): a linear axis, a three-axis machine, a five-axis
//!   trunnion, a touch probe, each with known error effects and measurement noise.
//! - *campaign*: a measurement on the twin (ISO 230-2 on one axis, a warm-up/cool-down, laser lines,
//!   R-test circles, probe touches).
//! - *chain*: measure → fit (the library the `fit` command calls) → image (the core's image writers)
//!   → the firmware library applies the image (`axcomp_core::Compensator` / `group::Group`, loaded
//!   from the image bytes) → before / after on data the fit never saw.
//! - *output file*: a file name in the report folder and its bytes ([`OutputFile`]); the command
//!   writes them all together or none.

pub mod all;
pub mod axis;
mod chains;
mod probe;
mod rotary;
mod row;
mod trace;

/// A file of the report folder: its name and its bytes.
pub type OutputFile = (String, Vec<u8>);

/// Why a demo could not run to its end.
#[derive(Debug, thiserror::Error)]
pub enum DemoError {
    /// The do-no-harm guard refused the fitted table (the reasons, joined).
    #[error("the do-no-harm guard refused the fitted table: {0}")]
    GuardRefused(String),
    /// A step failed: what was being done, and the cause as its source.
    #[error("{what}")]
    Step {
        what: String,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
    /// A library the demo calls refused, in its own words.
    #[error(transparent)]
    Library(Box<dyn std::error::Error + Send + Sync>),
    /// The firmware core refused (its errors carry no context: the message says what was done).
    #[error("{0}")]
    Firmware(String),
    /// A value a step needs is missing or implausible; the message names it.
    #[error("{0}")]
    Invalid(String),
}

/// Result of this crate.
pub type Result<T> = std::result::Result<T, DemoError>;

/// The errors of the libraries a chain calls, passed on unchanged.
macro_rules! library_errors {
    ($($t:ty),* $(,)?) => {
        $(impl From<$t> for DemoError {
            fn from(e: $t) -> Self {
                DemoError::Library(Box::new(e))
            }
        })*
    };
}

library_errors!(
    axcomp_data::DataError,
    axcomp_core::ImageError,
    axcomp_image::Error,
    axcomp_image::replay::ReplayError,
    axcomp_positioning::iso230::Iso230Error,
    axcomp_positioning::fit::FitError,
    axcomp_positioning::table_file::TableError,
    axcomp_twin::sim::SimError,
    axcomp_thermal::ThermalError,
    axcomp_probe::ProbeError,
    axcomp_geometry::GeometryError,
    axcomp_rtest::RtestError,
    serde_json::Error,
    std::fmt::Error,
);

/// `what` as the context of a failed step.
trait StepContext<T> {
    fn step(self, what: impl FnOnce() -> String) -> Result<T>;
}

impl<T, E: Into<Box<dyn std::error::Error + Send + Sync>>> StepContext<T>
    for std::result::Result<T, E>
{
    fn step(self, what: impl FnOnce() -> String) -> Result<T> {
        self.map_err(|e| DemoError::Step {
            what: what(),
            source: e.into(),
        })
    }
}

impl<T> StepContext<T> for Option<T> {
    fn step(self, what: impl FnOnce() -> String) -> Result<T> {
        self.ok_or_else(|| DemoError::Invalid(what()))
    }
}

/// The image `spec` as bytes, by the core's writer.
fn image_bytes(spec: &axcomp_core::ImageSpec) -> Result<Vec<u8>> {
    let mut buf = vec![0u8; axcomp_core::image_len(spec)];
    let n = axcomp_core::write_image(spec, &mut buf)?;
    buf.truncate(n);
    Ok(buf)
}

/// Positioning observations of an ISO 230-2 campaign (`target_mm`, `direction`, `run`,
/// `deviation_um`), as `fit positioning` reads them.
fn positioning_observations(
    ds: &axcomp_data::Dataset,
) -> Result<Vec<axcomp_positioning::fit::Observation>> {
    let x = ds.numeric("target_mm")?;
    let d = ds.numeric("deviation_um")?;
    let r = ds.numeric("run")?;
    let dir = ds
        .direction()?
        .step(|| "the campaign has no direction column".into())?;
    Ok((0..ds.n_rows())
        .map(|i| axcomp_positioning::fit::Observation {
            target_mm: x[i],
            direction: dir[i],
            run: r[i] as i64,
            deviation_um: d[i],
        })
        .collect())
}
