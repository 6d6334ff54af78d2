//! Errors of this crate: each names what is wrong and where (file, line, column, option or row).

/// What can go wrong reading, diagnosing or reporting a campaign.
#[derive(Debug, thiserror::Error)]
pub enum DiagnoseError {
    /// A file, column or option read by `axcomp-data` (names file, line, column).
    #[error(transparent)]
    Data(#[from] axcomp_data::DataError),
    /// R-test rows read by `axcomp-rtest` (names file, line, column).
    #[error(transparent)]
    Rtest(#[from] axcomp_rtest::RtestError),
    /// A value the diagnosis cannot use, with where it is (`file:line:column: …`).
    #[error("{at}: {what}")]
    BadValue { at: String, what: String },
    /// Observations or a campaign the diagnosis cannot work on: columns of different lengths, no training
    /// or no held-out rows, non-finite values, a fit that fails on them (the message says which and why).
    #[error("{0}")]
    Invalid(String),
    /// A told model that cannot be read (`--model`: an unknown or unsupported effect kind).
    #[error("{0}")]
    Model(String),
    /// Diagnosis settings out of range ([`crate::DiagnoseOptions`]).
    #[error("{0}")]
    Options(String),
    /// A report file or folder that cannot be written.
    #[error("cannot {action} {path}: {cause}")]
    Io {
        action: &'static str,
        path: String,
        cause: std::io::Error,
    },
}

/// Results of this crate.
pub type Result<T, E = DiagnoseError> = std::result::Result<T, E>;
