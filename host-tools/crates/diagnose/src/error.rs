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
    /// Observations, options or a campaign the verdict rule cannot work on (the message says why).
    #[error("{0}")]
    Invalid(String),
    /// A report file or folder that cannot be written.
    #[error("cannot {action} {path}: {cause}")]
    Io {
        action: &'static str,
        path: String,
        cause: std::io::Error,
    },
}

impl From<String> for DiagnoseError {
    fn from(s: String) -> Self {
        DiagnoseError::Invalid(s)
    }
}

/// Results of this crate.
pub type Result<T, E = DiagnoseError> = std::result::Result<T, E>;
