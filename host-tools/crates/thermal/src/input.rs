//! What a thermal fit reads and how it is set ([`ThermalInput`], [`ThermalOptions`]) and why it fails
//! ([`ThermalError`]): a leaf below the fit and its data preparation, which both name these.

use axcomp_effects::thermal_model::Series;

/// What the fit reads (already filtered, renamed and scaled).
#[derive(Debug, Clone)]
pub struct ThermalInput {
    pub time_s: Vec<f64>,
    /// Temperature sensors (name without the `_degC` suffix).
    pub sensors: Vec<Series>,
    /// Force columns (`*_N`), used as linear terms.
    pub forces: Vec<Series>,
    /// The error channel to model (µm).
    pub target: Vec<f64>,
    /// Operating condition of each row (`--cv` column), if any.
    pub conditions: Option<Vec<String>>,
    /// Held-out rows (true = judge only).
    pub holdout: Option<Vec<bool>>,
    /// Run of each row (`--runs`): per-run references, lag restarts, validation over runs.
    pub runs: Option<Vec<String>>,
}

/// Ridge setting.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Ridge {
    Off,
    Fixed(f64),
    /// λ chosen by inner CV from {0, 1e-6, …, 10}.
    Auto,
}

/// Which sensor selection to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Selection {
    /// The method with the lower nested CV RMS (FCM + GRA or forward selection).
    Auto,
    /// The reference method, fuzzy c-means + grey relational analysis.
    FcmGra,
    /// Forward selection scored by inner CV.
    Forward,
    /// Every usable sensor (no selection; a baseline).
    All,
    /// Greedy selection of up to 4 sensors, each with its lag (the plain reference with lags).
    Greedy,
}

/// Fit settings (validated by [`ThermalOptions::build`]).
#[derive(Debug, Clone, Copy)]
pub struct ThermalOptions {
    pub lags: bool,
    pub ridge: Ridge,
    /// Most sensors in the model (≤ `axcomp_core::MAX_SENSORS` = 16).
    pub max_sensors: usize,
    /// Time blocks for the inner CV when there are fewer than 3 conditions.
    pub time_blocks: usize,
    /// Lag grid size (besides τ = 0).
    pub lag_grid: usize,
    pub selection: Selection,
    /// The target's reference value is the mean of its first `reference_rows` rows (file order): the raw
    /// figures are the target minus it (the sensors' reference readings are their first row).
    pub reference_rows: usize,
}

impl Default for ThermalOptions {
    fn default() -> Self {
        ThermalOptions {
            lags: false,
            ridge: Ridge::Off,
            max_sensors: 6,
            time_blocks: 5,
            lag_grid: 8,
            selection: Selection::Auto,
            reference_rows: 1,
        }
    }
}

impl ThermalOptions {
    /// Checks the settings.
    pub fn build(self) -> Result<Self, ThermalError> {
        if self.max_sensors == 0 || self.max_sensors > 16 {
            return Err(ThermalError::Option("max_sensors must be 1..=16"));
        }
        if self.time_blocks < 3 {
            return Err(ThermalError::Option("time_blocks must be >= 3"));
        }
        if let Ridge::Fixed(l) = self.ridge
            && !(l >= 0.0 && l.is_finite())
        {
            return Err(ThermalError::Option("ridge must be a finite number >= 0"));
        }
        Ok(self)
    }
}

/// Why a thermal fit failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ThermalError {
    #[error("invalid option: {0}")]
    Option(&'static str),
    #[error("column `{column}` has {got} rows, expected {want}")]
    Length {
        column: String,
        got: usize,
        want: usize,
    },
    #[error("column `{column}`, data row {row}: value is not finite")]
    NonFinite { column: String, row: usize },
    #[error("no usable temperature sensor (`*_degC` column that varies on the training rows)")]
    NoSensors,
    #[error("too few training rows ({0}); need at least 10")]
    TooFewRows(usize),
    #[error("the holdout selects no rows")]
    EmptyHoldout,
    #[error("least squares failed: {0}")]
    Ls(#[from] axcomp_numeric::lsq::LsError),
}

/// With one episode of change in the training rows (a step, a single rise), a sensor's lag is tried only up
/// to this fraction of that episode's duration: a longer lag of it is, on these rows, only a function of the
/// time since the start.
pub const LAG_CAP_FRACTION: f64 = 1.0 / 3.0;
